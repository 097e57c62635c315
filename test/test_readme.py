"""The README shows what runs: its client example is examples/execute_move.py (which a ROS test runs),
and its interface definitions are the package's files."""
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def code_blocks(text: str) -> list[str]:
    parts = text.split('```')
    return [block.split('\n', 1)[1] for block in parts[1::2]]


def test_the_readme_client_example_is_the_file_the_tests_run():
    readme = (ROOT / 'README.md').read_text()
    section = readme.split('### Calling the planner from another node', 1)[1]
    assert code_blocks(section)[0] == (ROOT / 'examples' / 'execute_move.py').read_text()


def test_the_readme_shows_every_interface_file_as_it_is():
    readme = (ROOT / 'README.md').read_text()
    base = ROOT / 'src' / 'crane_interfaces'
    files = [p for d in ('msg', 'srv', 'action') for p in sorted((base / d).glob('*'))]
    assert len(files) == 5
    for path in files:
        assert path.read_text() in readme, path.name

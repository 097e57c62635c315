"""The documentation shows what runs and stays a user's: the client example in docs/ros.md is
examples/execute_move.py (which a ROS test runs), its interface definitions are the package's
files, the README stays short, every relative link resolves, and no page cites internal issues."""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / 'README.md'
ROS_DOC = ROOT / 'docs' / 'ros.md'
PAGES = [README, *sorted((ROOT / 'docs').glob('*.md'))]
MAX_README_LINES = 400


def code_blocks(text: str) -> list[str]:
    parts = text.split('```')
    return [block.split('\n', 1)[1] for block in parts[1::2]]


def prose(text: str) -> str:
    """The text outside fenced code blocks and inline code spans."""
    outside = ''.join(text.split('```')[0::2])
    return re.sub(r'`[^`\n]*`', '', outside)


def slug(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r'\[([^\]]*)\]\([^)]*\)', r'\1', heading).replace('`', '').strip().lower()
    return re.sub(r'[^\w\- ]', '', text).replace(' ', '-')


def anchors(path: Path) -> set[str]:
    found, seen = set(), {}
    for line in ''.join(path.read_text().split('```')[0::2]).splitlines():
        match = re.match(r'#{1,6}\s+(.*?)\s*#*\s*$', line)
        if match:
            base = slug(match.group(1))
            count = seen.get(base, 0)
            seen[base] = count + 1
            found.add(base if count == 0 else f'{base}-{count}')
    return found


def relative_links(path: Path) -> list[str]:
    targets = re.findall(r'!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)', prose(path.read_text()))
    return [t for t in targets if not re.match(r'[a-z][a-z0-9+.-]*:', t, re.IGNORECASE)]


def test_the_client_example_is_the_file_the_tests_run():
    section = ROS_DOC.read_text().split('## Calling the planner from another node\n', 1)[1]
    assert code_blocks(section)[0] == (ROOT / 'examples' / 'execute_move.py').read_text()


def test_the_docs_show_every_interface_file_as_it_is():
    text = ROS_DOC.read_text()
    base = ROOT / 'src' / 'crane_interfaces'
    files = [p for d in ('msg', 'srv', 'action') for p in sorted((base / d).glob('*'))]
    assert len(files) == 8
    blocks = code_blocks(text)
    for path in files:
        assert path.read_text() in blocks, path.name


def test_the_readme_is_short():
    lines = len(README.read_text().splitlines())
    assert lines <= MAX_README_LINES, f'README.md has {lines} lines; move details into docs/'


def test_the_readme_links_every_docs_page():
    readme = README.read_text()
    for page in PAGES[1:]:
        assert f'(docs/{page.name}' in readme, f'README.md does not link docs/{page.name}'


@pytest.mark.parametrize('page', PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_page_cites_internal_issue_numbers(page):
    cited = re.findall(r'\bissues?\s+#?\d+', page.read_text(), re.IGNORECASE)
    assert not cited, f'{page.name} cites {cited}: say what the behaviour is instead'


@pytest.mark.parametrize('page', PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves(page):
    links = relative_links(page)
    if page == README:
        assert links  # the parser finds the README's links at all
    broken = []
    for link in links:
        target, _, anchor = link.partition('#')
        path = (page.parent / target).resolve() if target else page
        if not path.exists():
            broken.append(f'{link}: no file {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}')
        elif anchor and path.suffix == '.md' and anchor not in anchors(path):
            broken.append(f'{link}: no heading #{anchor} in {path.relative_to(ROOT)}')
    assert not broken, f'{page.name}: ' + '; '.join(broken)


def test_the_link_checks_see_a_broken_link(tmp_path):
    page = tmp_path / 'page.md'
    page.write_text('# Title\n\n[ok](#title) [gone](missing.md) [bad anchor](#nowhere) `[code](x.md)`\n'
                    '```\n[in a block](y.md)\n```\n[web](https://example.com)\n')
    assert relative_links(page) == ['#title', 'missing.md', '#nowhere']
    assert anchors(page) == {'title'}
    assert slug('`~/plan_move`: a preview') == 'plan_move-a-preview'

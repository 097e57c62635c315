"""The workspace builds with colcon (from the venv) and installs executables where `ros2 run` looks."""
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ('crane_msgs_py', 'crane_sim', 'crane_planner')
EXECUTABLES = {'crane_planner': ('planner', 'streamer', 'crane-plan'), 'crane_sim': ('sim',)}


@pytest.mark.parametrize('pkg', PACKAGES)
def test_package_xml_format_3(pkg):
    root = ET.parse(ROOT / 'src' / pkg / 'package.xml').getroot()
    assert root.get('format') == '3'
    assert root.findtext('name') == pkg
    assert root.find('export/build_type').text == 'ament_python'
    assert (ROOT / 'src' / pkg / 'resource' / pkg).exists()


@pytest.fixture(scope='module')
def colcon_install(tmp_path_factory):
    base = tmp_path_factory.mktemp('colcon')
    colcon = Path(sys.executable).parent / 'colcon'
    r = subprocess.run([str(colcon), '--log-base', str(base / 'log'), 'build', '--base-paths', str(ROOT / 'src'),
                        '--build-base', str(base / 'build'), '--install-base', str(base / 'install')],
                       cwd=base, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    return base / 'install'


def test_colcon_build_installs_packages(colcon_install):
    for pkg in PACKAGES:
        assert (colcon_install / pkg / 'share' / 'ament_index' / 'resource_index' / 'packages' / pkg).exists()
        assert (colcon_install / pkg / 'share' / pkg / 'package.xml').exists()
    for pkg, exes in EXECUTABLES.items():
        for exe in exes:
            path = colcon_install / pkg / 'lib' / pkg / exe
            assert path.exists(), f'{path} missing'
            assert path.stat().st_mode & 0o111

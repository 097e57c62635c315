"""The workspace builds with colcon (from the venv) and installs executables where `ros2 run` looks."""
import os
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
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


#: The parameters files each package installs into share/<package>/config (ROS packages' layout).
CONFIG_FILES = {'crane_planner': ('planner.yaml', 'streamer.yaml'), 'crane_sim': ('sim.yaml',)}


def test_colcon_build_installs_each_packages_parameters_files(colcon_install):
    for pkg, names in CONFIG_FILES.items():
        for name in names:
            installed = colcon_install / pkg / 'share' / pkg / 'config' / name
            assert installed.exists(), f'{installed} missing'
            assert installed.read_text() == (ROOT / 'src' / pkg / 'config' / name).read_text()


ANSWERING_SERVICE = {'planner': 'crane_planner/plan/zv', 'streamer': 'crane_streamer/start', 'sim': 'crane_sim/reset'}


@pytest.mark.parametrize('pkg, exe', [('crane_planner', 'planner'), ('crane_planner', 'streamer'),
                                      ('crane_sim', 'sim')])
def test_colcon_installed_node_starts_and_answers(colcon_install, ros_domain, tmp_path, pkg, exe):
    """The colcon-installed lib/<pkg>/<exe> runs the installed code and offers its services."""
    import rclpy
    from nav_msgs.srv import GetPlan
    from std_srvs.srv import Trigger

    from crane_planner.tools.processes import ros_args

    site = [str(p) for p in colcon_install.glob('*/lib/python3*/site-packages')]
    env = dict(ros_domain, PYTHONPATH=os.pathsep.join(site + [ros_domain.get('PYTHONPATH', '')]))
    namespace = f'/colcon_{exe}'
    log = open(tmp_path / f'{exe}.log', 'w')
    proc = subprocess.Popen([str(colcon_install / pkg / 'lib' / pkg / exe), *ros_args(namespace)],
                            env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    rclpy.init()
    node = rclpy.create_node('colcon_probe', namespace=namespace)
    try:
        srv_type = GetPlan if exe == 'planner' else Trigger
        client = node.create_client(srv_type, ANSWERING_SERVICE[exe])
        assert client.wait_for_service(timeout_sec=30.0), (tmp_path / f'{exe}.log').read_text()
        if exe == 'sim':  # a real answer, not just an advertisement
            future = client.call_async(Trigger.Request())
            rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
            assert future.done() and future.result().success
        assert proc.poll() is None
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        os.killpg(proc.pid, signal.SIGINT)
        try:
            assert proc.wait(10) == 0, (tmp_path / f'{exe}.log').read_text()
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
            log.close()
    # It ran the colcon-installed package, not the editable sources.
    assert 'Traceback' not in (tmp_path / f'{exe}.log').read_text()

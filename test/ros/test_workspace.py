"""The workspace builds with colcon (from the venv) and installs executables where `ros2 run` looks.

``make install`` builds the interface package with colcon into the venv's ``ros/install`` (the underlay);
these tests check that install and build the Python packages with colcon as an overlay on it, as a ROS
user's workspace on top of an installed one.
"""
import os
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PYTHON_PACKAGES = ('crane_msgs_py', 'crane_sim', 'crane_planner')
INTERFACE_PACKAGES = ('crane_interfaces',)
PACKAGES = PYTHON_PACKAGES + INTERFACE_PACKAGES
EXECUTABLES = {'crane_planner': ('planner', 'streamer', 'crane-plan'), 'crane_sim': ('sim',)}
#: What rosidl_generate_interfaces installs into lib/ per package: the C/C++ code and every type support.
TYPESUPPORT_LIBRARIES = ('rosidl_generator_c', 'rosidl_generator_py', 'rosidl_typesupport_c',
                         'rosidl_typesupport_cpp', 'rosidl_typesupport_fastrtps_c', 'rosidl_typesupport_fastrtps_cpp',
                         'rosidl_typesupport_introspection_c', 'rosidl_typesupport_introspection_cpp')
INTERFACE_FILES = ('msg/AxisStatus.msg', 'msg/CraneState.msg', 'msg/Move.msg', 'msg/Occupancy.msg',
                   'msg/PlanInfo.msg', 'msg/StreamState.msg', 'srv/PlanMove.srv', 'action/ExecuteMove.action')


@pytest.mark.parametrize('pkg', PACKAGES)
def test_package_xml_format_3(pkg):
    root = ET.parse(ROOT / 'src' / pkg / 'package.xml').getroot()
    assert root.get('format') == '3'
    assert root.findtext('name') == pkg
    if pkg in PYTHON_PACKAGES:
        assert root.find('export/build_type').text == 'ament_python'
        assert (ROOT / 'src' / pkg / 'resource' / pkg).exists()
    else:  # an interface package: ament_cmake + rosidl
        assert root.find('export/build_type').text == 'ament_cmake'
        assert {e.text for e in root.findall('buildtool_depend')} >= {'ament_cmake', 'rosidl_default_generators'}
        assert root.findtext('member_of_group') == 'rosidl_interface_packages'
        assert (ROOT / 'src' / pkg / 'CMakeLists.txt').exists()


def test_interface_package_generates_every_interface_file():
    """CMakeLists.txt names each .msg/.srv/.action of the package (a forgotten one would not be built)."""
    for pkg in INTERFACE_PACKAGES:
        base = ROOT / 'src' / pkg
        on_disk = {p.relative_to(base).as_posix() for d in ('msg', 'srv', 'action') for p in (base / d).glob('*.*')}
        cmake = (base / 'CMakeLists.txt').read_text()
        assert on_disk == set(INTERFACE_FILES) and all(f'"{f}"' in cmake for f in on_disk)


#: Where ``make install`` put the colcon-built interface package: the overlay's underlay.
UNDERLAY = Path(sys.prefix) / 'ros' / 'install'


@pytest.fixture(scope='module')
def colcon_install(tmp_path_factory):
    """The Python packages built with colcon on top of the underlay; the install base."""
    base = tmp_path_factory.mktemp('colcon')
    colcon = Path(sys.executable).parent / 'colcon'
    # The PyPI wheels' ROS prefix is the venv, and the interface package is in the underlay (what sourcing
    # a ROS install and the underlay's setup does): colcon finds crane_interfaces, a dependency, there.
    prefixes = os.pathsep.join([str(UNDERLAY / pkg) for pkg in INTERFACE_PACKAGES] + [str(Path(sys.prefix))])
    env = dict(os.environ, AMENT_PREFIX_PATH=prefixes, CMAKE_PREFIX_PATH=prefixes)
    r = subprocess.run([str(colcon), '--log-base', str(base / 'log'), 'build', '--base-paths', str(ROOT / 'src'),
                        '--packages-skip', *INTERFACE_PACKAGES,
                        '--build-base', str(base / 'build'), '--install-base', str(base / 'install')],
                       cwd=base, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    return base / 'install'


def prefix_of(colcon_install, pkg: str) -> Path:
    """The install prefix of ``pkg``: the underlay's for the interface package, the overlay's for the others."""
    return (UNDERLAY if pkg in INTERFACE_PACKAGES else colcon_install) / pkg


def colcon_env(colcon_install, env):
    """``env`` with the overlay's and the underlay's Python packages and libraries first (what `source
    install/setup.bash` does): the generated interface packages need their lib/ on LD_LIBRARY_PATH for their
    type supports."""
    bases = (colcon_install, UNDERLAY)
    site = [str(p) for base in bases for p in base.glob('*/lib/python3*/site-packages')]
    libs = [str(p.parent) for base in bases for p in base.glob('*/lib/lib*.so')]
    return dict(env, PYTHONPATH=os.pathsep.join(site + [env.get('PYTHONPATH', '')]),
                LD_LIBRARY_PATH=os.pathsep.join(sorted(set(libs)) + [env.get('LD_LIBRARY_PATH', '')]))


def test_colcon_build_installs_packages(colcon_install):
    for pkg in PACKAGES:
        assert (prefix_of(colcon_install, pkg) / 'share' / 'ament_index' / 'resource_index' / 'packages' / pkg).exists()
        assert (prefix_of(colcon_install, pkg) / 'share' / pkg / 'package.xml').exists()
    for pkg, exes in EXECUTABLES.items():
        for exe in exes:
            path = colcon_install / pkg / 'lib' / pkg / exe
            assert path.exists(), f'{path} missing'
            assert path.stat().st_mode & 0o111


def test_colcon_build_installs_interface_packages():
    """crane_interfaces (make install's colcon build): its definitions, its Python package and every type
    support library."""
    for pkg in INTERFACE_PACKAGES:
        prefix = UNDERLAY / pkg
        assert (prefix / 'share' / 'ament_index' / 'resource_index' / 'rosidl_interfaces' / pkg).exists()
        for name in INTERFACE_FILES:
            installed = prefix / 'share' / pkg / name
            assert installed.read_text() == (ROOT / 'src' / pkg / name).read_text()
        for lib in TYPESUPPORT_LIBRARIES:
            assert (prefix / 'lib' / f'lib{pkg}__{lib}.so').exists(), f'lib{pkg}__{lib}.so missing'
        [site] = prefix.glob('lib/python3*/site-packages')
        for sub in ('msg', 'srv', 'action'):
            assert (site / pkg / sub / '__init__.py').exists()
        for ts in ('rosidl_typesupport_c', 'rosidl_typesupport_fastrtps_c', 'rosidl_typesupport_introspection_c'):
            assert list((site / pkg).glob(f'{pkg}_s__{ts}*.so')), f'{pkg} Python extension for {ts} missing'


#: Run by the venv's Python against the colcon installs: the types load, serialize through Fast DDS's
#: type support, and come from the colcon-built interface package (its Python package and its libraries).
IMPORT_CHECK = """
import crane_interfaces
from crane_interfaces.action import ExecuteMove
from crane_interfaces.msg import Move
from crane_interfaces.srv import PlanMove
from rclpy.serialization import deserialize_message, serialize_message
move = Move(method='zv', joint_names=['cart'], goal=[0.3], duration=3.0)
assert deserialize_message(serialize_message(move), Move) == move
for t in (PlanMove.Request, PlanMove.Response, ExecuteMove.Goal, ExecuteMove.Result, ExecuteMove.Feedback):
    assert deserialize_message(serialize_message(t()), t) == t()
maps = open('/proc/self/maps').read()
print(crane_interfaces.__file__)
print(sorted({line.split()[-1] for line in maps.splitlines() if 'libcrane_interfaces__' in line}))
"""


def test_colcon_installed_interfaces_import_with_type_supports(colcon_install):
    env = colcon_env(colcon_install, dict(os.environ))
    r = subprocess.run([sys.executable, '-c', IMPORT_CHECK], env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    module_file, libraries = r.stdout.splitlines()[-2:]
    prefix = str(UNDERLAY / 'crane_interfaces')
    assert module_file.startswith(prefix)
    assert 'rosidl_typesupport_fastrtps_c.so' in libraries and prefix + '/lib/' in libraries


#: The parameters files each package installs into share/<package>/config (ROS packages' layout).
CONFIG_FILES = {'crane_planner': ('planner.yaml', 'streamer.yaml'), 'crane_sim': ('sim.yaml',)}


def test_colcon_build_installs_each_packages_parameters_files(colcon_install):
    for pkg, names in CONFIG_FILES.items():
        for name in names:
            installed = colcon_install / pkg / 'share' / pkg / 'config' / name
            assert installed.exists(), f'{installed} missing'
            assert installed.read_text() == (ROOT / 'src' / pkg / 'config' / name).read_text()


ANSWERING_SERVICE = {'planner': 'crane_planner/plan_move', 'streamer': 'crane_streamer/start', 'sim': 'crane_sim/reset'}


@pytest.mark.parametrize('pkg, exe', [('crane_planner', 'planner'), ('crane_planner', 'streamer'),
                                      ('crane_sim', 'sim')])
def test_colcon_installed_node_starts_and_answers(colcon_install, ros_domain, tmp_path, pkg, exe):
    """The colcon-installed lib/<pkg>/<exe> runs the installed code and offers its services."""
    import rclpy
    from crane_interfaces.srv import PlanMove
    from std_srvs.srv import Trigger

    from crane_msgs_py.messages.conversions import move_message
    from crane_planner.tools.processes import ros_args

    env = colcon_env(colcon_install, ros_domain)
    namespace = f'/colcon_{exe}'
    log = open(tmp_path / f'{exe}.log', 'w')
    # (one solver process, not the default three: starting them is not what this checks, and each builds)
    params = {'solver_processes': 1} if exe == 'planner' else None
    proc = subprocess.Popen([str(colcon_install / pkg / 'lib' / pkg / exe), *ros_args(namespace, params)],
                            env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    rclpy.init()
    node = rclpy.create_node('colcon_probe', namespace=namespace)
    try:
        srv_type = PlanMove if exe == 'planner' else Trigger
        client = node.create_client(srv_type, ANSWERING_SERVICE[exe])
        assert client.wait_for_service(timeout_sec=180.0), (tmp_path / f'{exe}.log').read_text()
        if exe in ('sim', 'planner'):  # a real answer, not just an advertisement
            preview = PlanMove.Request(move=move_message([0.3], 3.0, [0.0], 'zv'))
            future = client.call_async(Trigger.Request() if exe == 'sim' else preview)
            rclpy.spin_until_future_complete(node, future, timeout_sec=180.0)
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

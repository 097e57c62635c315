"""Shared fixtures, and the ``ros`` marker (pytest.ini) on every test that joins a ROS graph."""
import os
from pathlib import Path

import pytest
from shared_crane import CART_CRANE_MODULES, CART_NAMESPACE, CART_STREAMER_PARAMS

ROS_TESTS = Path(__file__).resolve().parent / 'ros'
#: Modules of test/ros/ that start ROS processes but time nothing real-time: they check files, parameters,
#: messages and exit statuses, with hang guards only, long enough for a start-up at that niceness beside a
#: CPU-bound process (none runs the 1 kHz streamer and sim with a motion to judge: a planner alone whose solver
#: processes are killed, a made-up server of the interfaces). ``make test`` runs them beside the real-time ROS
#: tests, at the pure tests' niceness, instead of after them (``pytest_xdist_make_scheduler``).
UNTIMED_ROS_MODULES = ('test_workspace.py', 'test_params_files.py', 'test_demo_failures.py', 'test_without_sim.py',
                       'test_faults_solver.py', 'test_interfaces.py')


def untimed(path: str) -> bool:
    """Whether a test's file path (a nodeid or an item's path) is one of ``UNTIMED_ROS_MODULES``."""
    return Path(str(path).split('::', 1)[0]).name in UNTIMED_ROS_MODULES

# The NLPs' derivatives are not compiled in the background (``planning.compiled``) in the tests or the nodes
# they start: a solver that swaps them in mid-test would give plans that differ in the last bits from an
# interpreted one's, which tests comparing two solvers' plans exactly would see. test_compiled.py compiles
# into a directory of its own.
os.environ['CRANE_PLANNER_CACHE'] = 'off'


@pytest.fixture(scope='session')
def ros_domain():
    """A private ROS graph for the session: random ROS_DOMAIN_ID, localhost-only discovery.

    Set in this process's environment before rclpy.init, and inherited by the
    node subprocesses, so parallel sessions and other projects never meet.
    Yields the environment.
    """
    from crane_planner.tools.processes import isolated_graph
    with isolated_graph() as env:
        yield env


def crane_up(ros_domain, tmp_path_factory, namespace: str, startup: float = 90.0, **kwargs):
    """The planner, streamer and sim executables started in a namespace of the private graph
    (``start_crane_nodes``' keywords): a ``CraneHarness`` once every node is up (its ``nodes``); all stopped
    again if that fails."""
    from crane_planner.tools.harness import CraneHarness, start_crane_nodes
    from crane_planner.tools.processes import NodeGroup
    nodes = NodeGroup(ros_domain, tmp_path_factory.mktemp(namespace.strip('/') + '-node-logs'))
    driver = None
    try:
        start_crane_nodes(nodes, namespace, **kwargs)
        driver = CraneHarness(namespace, nodes)
        driver.wait_until_up(startup)
        return driver
    except BaseException:
        crane_down(driver, nodes)
        raise


def crane_down(driver, nodes):
    """Stop what ``crane_up`` started."""
    if driver is not None:
        driver.close()
    nodes.stop(timeout=10.0)


@pytest.fixture(scope='module')
def start_crane(ros_domain, tmp_path_factory):
    """Start the planner, streamer and sim executables in a namespace of the private graph:
    ``with start_crane(namespace, **start_crane_nodes_keywords) as driver:`` a ``CraneHarness`` once every
    node is up; at the end every node is checked alive, and whatever happened all are stopped."""
    from contextlib import contextmanager

    @contextmanager
    def start(namespace: str, startup: float = 90.0, **kwargs):
        driver = crane_up(ros_domain, tmp_path_factory, namespace, startup, **kwargs)
        try:
            yield driver
            driver.nodes.check_alive()  # every node survived the whole module
        finally:
            crane_down(driver, driver.nodes)

    return start


#: The shared node set while it runs (``cart_crane``): {'driver': its CraneHarness}.
_CART_CRANE = {}


def stop_cart_crane():
    """Stop the shared node set, if it runs."""
    driver = _CART_CRANE.pop('driver', None)
    if driver is not None:
        crane_down(driver, driver.nodes)


@pytest.fixture(scope='module')
def cart_crane(request, ros_domain, tmp_path_factory):
    """The node set with the joint [cart] that ``shared_crane.CART_CRANE_MODULES`` share, in
    ``CART_NAMESPACE``, every node at its defaults (but ``CART_STREAMER_PARAMS``): its ``CraneHarness`` for one
    module, the streamer holding and the plant at rest where the cart is, the nodes' worker processes idle
    (``wait_until_idle``; but for the first module, right after the start-up, as a set of its own would be).
    Started by the first module that asks for it, kept for the next (every node checked alive at the end of
    each), stopped once the next test needs it no more (``pytest_runtest_teardown``), or at once if a node
    died."""
    driver = _CART_CRANE.get('driver')
    fresh = driver is None
    if fresh:
        driver = _CART_CRANE['driver'] = crane_up(ros_domain, tmp_path_factory, CART_NAMESPACE, startup=120.0,
                                                  streamer_params=CART_STREAMER_PARAMS)
    try:
        if not fresh or Path(str(request.path)).name != CART_CRANE_MODULES[0]:
            wait_until_idle(driver)
        driver.wait_until_holding()  # (a motion the module before left running has ended)
        driver.reset_sim()
        yield driver
        driver.nodes.check_alive()  # every node survived the whole module
    except BaseException:
        stop_cart_crane()  # the next module starts a set of its own
        raise


def wait_until_idle(driver, timeout: float = 180.0):
    """Wait until the nodes' worker processes (the planner's solver processes, the streamer's stop planner: the
    children of their fork servers) spend no CPU over half a second: no build in the background (the start-up's,
    or one a parameter changed) takes the cores the 1 kHz nodes and the next goals need."""
    import time

    from crane_planner.tools.harness import HarnessError
    from crane_planner.tools.processes import cpu_ticks, fork_servers, process_children
    deadline = time.monotonic() + timeout
    while True:
        tree = process_children()
        workers = [w for p in driver.nodes.processes for server in fork_servers(p.popen.pid)
                   for w in tree.get(server, [])]
        before = {w: cpu_ticks(w) for w in workers}
        driver.sleep(0.5)
        if all(cpu_ticks(w) - ticks <= 1 for w, ticks in before.items()):
            return
        if time.monotonic() > deadline:
            raise HarnessError(f'the nodes\' worker processes still busy {timeout:g} s on')


@pytest.hookimpl(wrapper=True)
def pytest_runtest_teardown(item, nextitem):
    """After a test's teardown: the shared node set stopped once the next test does not use it (no node set runs
    idle beside the next, nor beside the pure tests that may follow on this worker)."""
    try:
        return (yield)
    finally:
        if nextitem is None or 'cart_crane' not in nextitem.fixturenames:
            stop_cart_crane()


def pytest_sessionfinish(session):
    stop_cart_crane()  # (a session interrupted while it ran)


def pytest_collection_modifyitems(config, items):
    """Mark ``ros`` every test under test/ros/ and every test that needs ``ros_domain`` (directly or
    through another fixture), so ``-m "not ros"`` leaves exactly the tests that run without DDS; and run
    them first (each kind keeps its order): with two workers the longest-running unit starts at once. The
    modules sharing a node set (``cart_crane``) run after the other real-time ones, one after the other in
    ``CART_CRANE_MODULES``' order."""
    for item in items:
        if 'ros_domain' in item.fixturenames or ROS_TESTS in Path(item.fspath).parents:
            item.add_marker(pytest.mark.ros)

    def shared(item) -> int:
        if 'cart_crane' not in item.fixturenames:
            return 0
        name = Path(str(item.fspath)).name  # (a module not listed: after those listed)
        return 1 + (CART_CRANE_MODULES.index(name) if name in CART_CRANE_MODULES else len(CART_CRANE_MODULES))

    # (the untimed ROS modules after the real-time ones: a process that has raised its niceness for them may not
    # be allowed to lower it again)
    items.sort(key=lambda item: (item.get_closest_marker('ros') is None, untimed(item.nodeid), shared(item)))


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``make test`` runs ``pytest -n 2 --dist loadgroup``: every real-time test under test/ros/ in one unit, in
    order on one worker (one node set at a time: two on 2 cores starve each other's 1 kHz threads), the pure
    tests and the ``UNTIMED_ROS_MODULES`` on the other meanwhile, a module at a time (split between the workers,
    a module-scoped fixture would be computed on both). (xdist's own ``xdist_group`` marks do nothing under
    pytest 9: the group it appends to a test's nodeid no longer reaches the scheduler.)"""
    if config.getvalue('dist') != 'loadgroup':
        return None
    from xdist.scheduler import LoadScopeScheduling

    class RosTestsTogether(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            module = nodeid.split('::', 1)[0]
            return 'ros' if module.startswith('test/ros/') and not untimed(module) else module

    return RosTestsTogether(config, log)


#: Niceness of the pure tests: beside the ROS tests (``make test`` runs both at once) they take the CPU the
#: real-time nodes leave, so the nodes' timing is what it would be beside one ordinary busy process.
PURE_NICENESS = 10


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    """Pure and untimed ROS tests at ``PURE_NICENESS``, real-time ROS tests at the usual priority (of this
    thread, which the node subprocesses and solver processes a test starts inherit)."""
    import os
    realtime = item.get_closest_marker('ros') and not untimed(item.nodeid)
    try:
        os.setpriority(os.PRIO_PROCESS, 0, 0 if realtime else PURE_NICENESS)
    except OSError:  # lowering it again needs CAP_SYS_NICE: an unprivileged run keeps the pure tests' value
        pass

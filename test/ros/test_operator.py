"""ROS: the streamer's operator mode through the real executables and crane-teleop, and the
streamer's ~/stop during a planned motion. The swing is measured by the test from ``joint_states``."""
import signal

import numpy as np
import pytest
from shared_crane import CART_NAMESPACE

from crane_msgs_py.crane.params import CraneParams

NS = CART_NAMESPACE
NOMINAL = CraneParams()
PLAYOUT = 0.2  # s: the sim's joint_states are stamped with plant time, this far behind the clock


@pytest.fixture
def crane(operator_crane):
    """The nodes, back in operator mode at rest after the test (whatever its outcome)."""
    yield operator_crane
    driver = operator_crane
    driver.call_streamer('start')
    driver.wait_until_still()  # a stick a failed test left moving: cmd_timeout, braking and the shaper, 2.3 s
    driver.set_parameters('streamer', {'mode': 'operator', 'operator_shaper': 'zv'})
    driver.reset_sim()


@pytest.fixture(scope='module')
def operator_crane(cart_crane):
    """The nodes (conftest's ``cart_crane``), the streamer in operator mode for the module (set at rest)."""
    cart_crane.set_parameters('streamer', {'mode': 'operator', 'operator_shaper': 'zv'})
    yield cart_crane
    cart_crane.set_parameters('streamer', {'mode': 'trajectory'})  # (the tests leave it at rest)


def teleop(driver, script: str):
    """crane-teleop playing ``script`` in the test's namespace (a process, running)."""
    return driver.run_tool('crane-teleop', '--namespace', NS, f'--script={script}')  # (= : it may start with -)


def record(driver, seconds: float) -> np.ndarray:
    """joint_states (stamp, theta1, theta2, cart, hoist) over the next ``seconds`` of plant time."""
    begin = driver.now_ns()  # plant time: the reference stamped now acts at plant time now
    end = begin + round(seconds * 1e9)
    driver.sleep(max(0.0, (end - driver.now_ns()) * 1e-9 + PLAYOUT))
    return driver.states_between(begin, end, timeout=10.0)


def residual_mm(rec: np.ndarray, after: float) -> float:
    from crane_sim.metrics import residual_load_mm
    t = (rec[:, 0] - rec[0, 0]) * 1e-9
    return float(residual_load_mm(t, rec[:, 1], rec[:, 2], NOMINAL.L1, NOMINAL.L2, after=after))


def stick_run(driver, speed: float) -> tuple[float, np.ndarray]:
    """The stick at ``speed`` for 3 s, released: the residual (mm) over a second from 2.5 s after the release on
    (braking 0.5 s and the shaper 1.2 s before; a second is over half the slow mode's period, so its peak
    shows), and the record from the start."""
    begin = driver.now_ns()
    tool = teleop(driver, f'{speed}:3')
    assert tool.wait(timeout=20.0) == 0, tool.stderr.read()
    released = driver.now_ns()
    end = released + round(3.5e9)
    driver.sleep(max(0.0, (end - driver.now_ns()) * 1e-9 + PLAYOUT))
    rec = driver.states_between(begin, end, timeout=10.0)
    return residual_mm(rec, (released - begin) * 1e-9 + 2.5), rec


def test_a_stick_shaped_online_leaves_under_5_percent_of_the_rate_limited_swing(crane):
    driver = crane
    shaped, rec = stick_run(driver, 0.2)
    moved = rec[-1, 3] - rec[0, 3]
    assert moved == pytest.approx(0.6, abs=0.03)  # 0.2 m/s for 3 s (the tool's timing is the host's)
    driver.set_parameters('streamer', {'operator_shaper': 'none'})  # at rest: allowed
    driver.reset_sim()
    unshaped, _ = stick_run(driver, -0.2)
    driver.set_parameters('streamer', {'operator_shaper': 'zv'})
    driver.reset_sim()
    assert unshaped > 10.0, unshaped
    assert shaped <= 0.05 * unshaped, (shaped, unshaped)


def test_a_lost_stick_stops_the_crane_within_the_timeout_and_the_stop(crane):
    from crane_planner.tools.harness import HarnessError
    driver = crane
    tool = teleop(driver, '0.2:30')
    before = driver.last_state()[3]
    driver.wait_until(lambda: abs(driver.last_state()[3] - before) > 0.05, 10.0, 'the stick never moved the cart')
    # mid-travel the mode cannot change
    with pytest.raises(HarnessError, match='only with the crane at rest'):
        driver.set_parameters('streamer', {'mode': 'trajectory'})
    lost = driver.now_ns()
    tool.send_signal(signal.SIGKILL)  # the joystick's messages stop, no zero command sent
    tool.wait(timeout=5.0)
    rec = record(driver, 4.5)  # at rest within 2.31 s (below), then over a second of it
    t = (rec[:, 0] - lost) * 1e-9  # plant time since the messages stopped
    away = np.nonzero(np.abs(rec[:, 3] - rec[-1, 3]) > 1e-5)[0]  # farther than 10 um from where it stops
    stopped = t[away[-1] + 1]
    # cmd_timeout 0.5 s + braking 0.2/0.5 + 0.5/5 s + the ZV shaper's 1.21 s, and the servo's and a sample's slack
    assert stopped <= 0.5 + 0.5 + 1.21 + 0.1, stopped
    assert residual_mm(rec, stopped - t[0] + 1.0) < 1.0  # a centimetre-scale swing without shaping
    driver.reset_sim()


def test_operator_mode_refuses_trajectories_and_its_stop_brakes_without_swing(crane):
    from crane_msgs_py.crane.errors import PlanError
    driver = crane
    with pytest.raises(PlanError, match='the streamer is in operator mode'):
        driver.move('zv', None, 0.3, 3.0)
    tool = teleop(driver, '-0.2:30')
    before = driver.last_state()[3]
    driver.wait_until(lambda: abs(driver.last_state()[3] - before) > 0.05, 10.0, 'the stick never moved the cart')
    response = driver.call_streamer('stop')
    assert response.success and 'stopping' in response.message, response.message
    rec = record(driver, 4.0)
    tool.kill()
    assert residual_mm(rec, 3.0) < 1.0
    assert np.ptp(rec[-20:, 3]) < 1e-6  # at rest
    response = driver.call_streamer('start')
    assert response.success, response.message
    driver.reset_sim()


def test_the_streamers_stop_during_a_planned_motion_brakes_without_swing(crane):
    driver = crane
    driver.set_parameters('streamer', {'mode': 'trajectory'})  # (returns once the planner can hear it)
    start, _, _ = driver.move('rvf', None, driver.last_state()[3] + 0.3, 3.0, settle=0.5)
    driver.sleep(max(0.0, (start + round(1.5e9) - driver.now_ns()) * 1e-9))
    response = driver.call_streamer('stop')
    assert response.success and 'stopping without swing' in response.message, response.message
    rec = record(driver, 4.0)
    assert residual_mm(rec, 2.5) < 0.5
    assert np.ptp(rec[-20:, 3]) < 1e-6
    assert driver.call_streamer('start').success
    driver.set_parameters('streamer', {'mode': 'operator'})

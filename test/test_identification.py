"""Commissioning: identify the crane from a recorded move (crane_planner.identification, ``crane-plan identify``).

Data come from crane_sim's independent numpy simulator with seeded sensor noise
(crane_sim.measurement); the truth is the simulated plant. Damping ratios are
checked against the eigenvalues of a finite-difference linearization of that
simulator, not against the planner's model.
"""
import json
import math
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from crane_msgs_py.params import CraneParams
from crane_planner.identification import IdentificationError, Recording, identify, read_csv
from crane_planner.identification.recording import RecordingError
from crane_planner.planning.profiles import quintic
from crane_sim.measurement import measured_angles
from crane_sim.simulator import simulate
from references import linearized_modes

CRANE_PLAN = str(Path(__file__).resolve().parents[1] / '.venv' / 'bin' / 'crane-plan')
TABLE1 = CraneParams()


def record(plant, after=8.0, noise=1e-3, seed=0, D=0.3, move=1.0, rate=50.0, reference=False) -> Recording:
    """A 0.3 m quintic move in ``move`` s, then ``after`` s of free swing, sampled at ``rate`` with sensor noise."""
    t = np.arange(0.0, move + after + 1e-9, 1e-3)
    position, _, acceleration, _ = quintic(t, D, move)
    every = round(1.0 / (rate * 1e-3))
    r = simulate(t, acceleration, plant, dt=1e-3, record_every=every)
    theta1, theta2 = measured_angles(r, noise, seed)
    return Recording(r.t, r.y[0], theta1[0], theta2[0], position[::every] if reference else None)


def random_plant(rng, spread=0.3) -> CraneParams:
    f = rng.uniform(1 - spread, 1 + spread, 4)
    return TABLE1.replace(L1=TABLE1.L1 * f[0], L2=TABLE1.L2 * f[1], m1=TABLE1.m1 * f[2], m2=TABLE1.m2 * f[3])


@pytest.mark.parametrize('seed', range(6))
def test_a_random_crane_within_30_percent_is_identified_from_one_noisy_move(seed):
    rng = np.random.default_rng(100 + seed)
    truth = random_plant(rng)
    result = identify(record(truth, seed=seed), TABLE1)
    v = result.values
    omega, _ = linearized_modes(truth)
    assert v['L1'] == pytest.approx(truth.L1, rel=0.01)
    assert v['L2'] == pytest.approx(truth.L2, rel=0.01)
    assert v['mass_ratio'] == pytest.approx(truth.m2 / (truth.m1 + truth.m2), rel=0.03)
    assert v['omega1'] == pytest.approx(omega[0], rel=0.003)
    assert v['omega2'] == pytest.approx(omega[1], rel=0.003)
    assert result.rms_residual_rad == pytest.approx(1e-3, rel=0.15)  # down to the sensor noise
    assert not result.warnings


def test_without_noise_the_estimates_are_far_tighter():
    truth = random_plant(np.random.default_rng(7))
    v = identify(record(truth, noise=0.0), TABLE1).values
    assert v['L1'] == pytest.approx(truth.L1, rel=2e-4)
    assert v['L2'] == pytest.approx(truth.L2, rel=2e-4)
    assert v['mass_ratio'] == pytest.approx(truth.m2 / (truth.m1 + truth.m2), rel=5e-4)
    omega, _ = linearized_modes(truth)
    assert v['omega1'] == pytest.approx(omega[0], rel=2e-5) and v['omega2'] == pytest.approx(omega[1], rel=2e-5)


@pytest.mark.parametrize('c1, c2', [(0.004, 0.001), (0.01, 0.0005)])
def test_joint_damping_gives_the_damping_ratios_of_the_linearized_damped_crane(c1, c2):
    truth = TABLE1.replace(L1=0.52, L2=0.33, c1=c1, c2=c2)
    result = identify(record(truth, seed=3), TABLE1)
    _, zeta = linearized_modes(truth)
    assert min(zeta) > 0.001  # really damped
    assert result.values['zeta1'] == pytest.approx(zeta[0], rel=0.10)
    assert result.values['zeta2'] == pytest.approx(zeta[1], rel=0.10)
    # the nominal total mass is the true one here, so the dampings themselves come out
    assert result.values['c1'] == pytest.approx(c1, rel=0.1)
    assert result.values['c2'] == pytest.approx(c2, rel=0.1)


def test_tau_comes_from_the_reference_recorded_beside_the_cart():
    truth = TABLE1.replace(tau=0.025)
    result = identify(record(truth, reference=True), TABLE1)
    assert result.values['tau'] == pytest.approx(0.025, rel=0.01)
    assert result.params.tau == pytest.approx(0.025, rel=0.01)
    assert identify(record(truth), TABLE1).values['tau'] is None


def test_a_recording_too_short_for_one_slow_period_is_refused():
    slow_period = 2 * math.pi / linearized_modes(TABLE1)[0][0]
    with pytest.raises(IdentificationError, match='less than one period of the slow mode'):
        identify(record(TABLE1, after=0.8 * slow_period), TABLE1)


def test_a_move_that_leaves_no_swing_is_refused():
    rec = record(TABLE1, noise=0.0)
    still = Recording(rec.t, np.zeros_like(rec.t), 0.0 * rec.theta1, 0.0 * rec.theta2)
    with pytest.raises(IdentificationError, match='too little excitation'):
        identify(still, TABLE1)


def write_csv(path, rec: Recording):
    rec.write_csv(path)


def run(*args):
    return subprocess.run([CRANE_PLAN, 'identify', *args], capture_output=True, text=True, timeout=120)


def test_cli_prints_json_writes_a_params_file_and_a_plot(tmp_path):
    truth = TABLE1.replace(L1=0.55, L2=0.3, tau=0.02, c1=0.003)
    write_csv(tmp_path / 'move.csv', record(truth, reference=True))
    out = run('--csv', str(tmp_path / 'move.csv'), '--json', '--params-out', str(tmp_path / 'crane.yaml'),
              '--plot', str(tmp_path / 'fit.png'))
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    for key in ('L1', 'L2', 'mass_ratio', 'c1', 'c2', 'tau', 'omega1', 'omega2', 'zeta1', 'zeta2'):
        assert isinstance(data[key], float) and isinstance(data[f'{key}_std'], float) and data[f'{key}_std'] >= 0
    assert data['L1'] == pytest.approx(0.55, rel=0.01) and data['tau'] == pytest.approx(0.02, rel=0.02)
    assert 0 < data['rms_residual_rad'] < 2e-3
    text = (tmp_path / 'crane.yaml').read_text()
    assert 'ros__parameters:' in text and f'L1: {data["L1"]!r}' in text and 'tau:' in text
    assert (tmp_path / 'fit.png').stat().st_size > 10_000
    human = run('--csv', str(tmp_path / 'move.csv'))
    assert human.returncode == 0 and 'mode 1: omega' in human.stdout and 'L1 (m)' in human.stdout


@pytest.mark.parametrize('content, needle', [
    ('t,cart,theta1\n0,0,0\n', 'lacks column(s) theta2'),
    ('t,cart,theta1,theta2\n' + ''.join(f'{k * 0.02},0,0,0\n' for k in range(30)) + '0.3,0,x,0\n', 'not a number'),
    ('t,cart,theta1,theta2\n' + ''.join(f'{k * 0.02},0,0,{k}\n' for k in range(30)) + '0.1,0,0,0\n',
     't must increase strictly'),
    ('t,cart,theta1,theta2\n' + ''.join(f'{k * 0.02},0,nan,0\n' for k in range(30)), 'theta1 is not finite'),
    ('', 'is empty'),
])
def test_cli_refuses_bad_recordings_in_one_line(tmp_path, content, needle):
    path = tmp_path / 'bad.csv'
    path.write_text(content)
    out = run('--csv', str(path))
    assert out.returncode == 2 and needle in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert 'Traceback' not in out.stderr


def test_cli_refuses_a_too_short_recording_and_a_missing_file(tmp_path):
    write_csv(tmp_path / 'short.csv', record(TABLE1, after=1.0))
    out = run('--csv', str(tmp_path / 'short.csv'))
    assert out.returncode == 2 and 'less than one period of the slow mode' in out.stderr
    out = run('--csv', str(tmp_path / 'missing.csv'))
    assert out.returncode == 2 and 'cannot read' in out.stderr and 'Traceback' not in out.stderr


def test_read_csv_round_trips_a_recording(tmp_path):
    rec = record(TABLE1, reference=True)
    write_csv(tmp_path / 'r.csv', rec)
    back = read_csv(tmp_path / 'r.csv')
    for name in ('t', 'cart', 'theta1', 'theta2', 'reference'):
        assert np.array_equal(getattr(back, name), getattr(rec, name))  # repr round-trips floats
    keep = np.r_[0:30, 31:60]  # one lost sample is fine (each interval has its own length) ...
    Recording(*(x[keep] for x in (rec.t, rec.cart, rec.theta1, rec.theta2)))
    keep = np.r_[0:30, 36:60]  # ... a gap of six is not
    with pytest.raises(RecordingError, match='evenly spaced'):
        Recording(*(x[keep] for x in (rec.t, rec.cart, rec.theta1, rec.theta2)))


def write_bag(path, rec: Recording, namespace='/crane'):
    """A rosbag2 recording in MCAP storage of joint_states (+ the reference at 1 kHz), as a recorder writes it."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    js_type, traj_type = 'sensor_msgs/msg/JointState', 'trajectory_msgs/msg/JointTrajectory'
    t0 = 1_700_000_000 * 10**9

    def header(ns):
        return T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9),
                                        frame_id='crane_base')
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        js = w.add_connection(f'{namespace}/joint_states', js_type, typestore=ts)
        for k in range(rec.t.size):
            ns = t0 + round(rec.t[k] * 1e9)
            msg = T[js_type](header=header(ns), name=['cart', 'theta1', 'theta2'],
                             position=np.array([rec.cart[k], rec.theta1[k], rec.theta2[k]]),
                             velocity=np.zeros(3), effort=np.zeros(0))
            w.write(js, ns, ts.serialize_cdr(msg, js_type))
        if rec.reference is not None:
            ref = w.add_connection(f'{namespace}/reference', traj_type, typestore=ts)
            t = np.arange(rec.t[0], rec.t[-1], 1e-3)
            for tk, p in zip(t, np.interp(t, rec.t, rec.reference)):
                ns = t0 + round(tk * 1e9)
                point = T['trajectory_msgs/msg/JointTrajectoryPoint'](
                    positions=np.array([p]), velocities=np.zeros(1), accelerations=np.zeros(1), effort=np.zeros(0),
                    time_from_start=T['builtin_interfaces/msg/Duration'](sec=0, nanosec=0))
                msg = T[traj_type](header=header(ns), joint_names=['cart'], points=[point])
                w.write(ref, ns, ts.serialize_cdr(msg, traj_type))


def test_a_rosbag2_mcap_recording_gives_what_the_csv_gives(tmp_path):
    truth = TABLE1.replace(L1=0.5, L2=0.36, tau=0.02)
    rec = record(truth, reference=True)
    write_csv(tmp_path / 'move.csv', rec)
    write_bag(tmp_path / 'bag', rec)
    assert list((tmp_path / 'bag').glob('*.mcap')) and (tmp_path / 'bag' / 'metadata.yaml').is_file()
    from_csv, from_bag = (json.loads(run(*source, '--json').stdout)
                          for source in (('--csv', str(tmp_path / 'move.csv')), ('--bag', str(tmp_path / 'bag'))))
    for key in ('L1', 'L2', 'mass_ratio', 'omega1', 'omega2'):
        assert from_bag[key] == pytest.approx(from_csv[key], rel=1e-6), key
    assert from_bag['tau'] == pytest.approx(0.02, rel=0.05)  # the reference interpolated from 1 kHz samples
    empty = tmp_path / 'empty'
    empty.mkdir()
    out = run('--bag', str(empty))
    assert out.returncode == 2 and 'not a rosbag2 recording' in out.stderr


def test_the_params_file_sets_the_planner_nodes_model(ros_domain, tmp_path):
    """The planner started with identify's --params-out file (namespaced) reports the estimates as its parameters."""
    import rclpy
    from rclpy.parameter_client import AsyncParameterClient

    from crane_planner.tools.processes import PLANNER, NodeGroup
    truth = TABLE1.replace(L1=0.55, L2=0.3, tau=0.02, c1=0.003)
    write_csv(tmp_path / 'move.csv', record(truth, reference=True))
    out = run('--csv', str(tmp_path / 'move.csv'), '--json', '--params-out', str(tmp_path / 'crane.yaml'))
    estimates = json.loads(out.stdout)
    rclpy.init()
    node = rclpy.create_node('params_file_check', namespace='/cell_7')
    try:
        with NodeGroup(ros_domain, tmp_path / 'logs') as nodes:
            nodes.start(*PLANNER, namespace='/cell_7', params={'solver_processes': 1},
                        params_file=tmp_path / 'crane.yaml')
            client = AsyncParameterClient(node, 'crane_planner')
            deadline = time.monotonic() + 60.0
            while not client.wait_for_services(0.2):
                nodes.check_alive()
                assert time.monotonic() < deadline, 'planner parameter services never appeared'
            future = client.get_parameters(['L1', 'L2', 'm1', 'm2', 'c1', 'c2', 'tau'])
            rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
            values = {name: v.double_value for name, v in zip(['L1', 'L2', 'm1', 'm2', 'c1', 'c2', 'tau'],
                                                               future.result().values)}
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    assert values['L1'] == estimates['L1'] and values['L2'] == estimates['L2']
    assert values['c1'] == estimates['c1'] and values['tau'] == estimates['tau']
    total = TABLE1.m1 + TABLE1.m2
    assert values['m2'] / total == pytest.approx(estimates['mass_ratio'], rel=1e-12)
    assert values['m1'] + values['m2'] == pytest.approx(total, rel=1e-12)

"""Recorded moves for the identification tests: crane_sim's independent numpy simulator with seeded
sensor noise (crane_sim.measurement), as CSV and as rosbag2 MCAP, and ``crane-plan identify``."""
import numpy as np
from crane_plan_cli import crane_plan

from crane_msgs_py.crane.params import CraneParams
from crane_planner.identification import Recording
from crane_planner.planning.profiles import quintic
from crane_sim.measurement import measured_angles
from crane_sim.simulator import simulate

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


def write_csv(path, rec: Recording):
    rec.write_csv(path)


def run_identify(*args):
    """``crane-plan identify ARGS`` (``crane_plan_cli.Completed``)."""
    return crane_plan('identify', *args)


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

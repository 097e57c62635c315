"""``crane-plan report BAG``: figures and a residual-swing table from a rosbag2 recording of the crane.

Reads (with ``rosbags``, no ROS install needed) what ``crane-record`` or
``crane-demo --record`` store: ``joint_states`` (cart, theta1, theta2; bridge, phi1, phi2 of the spatial crane),
``reference`` (the streamer's 1 kHz samples), ``trajectory`` (the motions sent
for execution), ``/diagnostics`` (the streamer's tick timing) and
``crane_markers`` (the drawn crane, whose cable lengths the load's position
needs). Topics may be namespaced. Pure Python (no rclpy).

A motion starts where the reference starts it: a trajectory that reached the
streamer after its start stamp is streamed whole from a later tick, and its
settle window counts from there (the reference's first sample of it is the
last at rest: the next one moves).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from crane_msgs_py.crane.params import CraneParams
from crane_planner.identification.recording import RecordingError

#: The joint_states columns kept after the stamp (``BagData.states``), the planar crane's first.
STATE_JOINTS = ('cart', 'theta1', 'theta2', 'hoist', 'bridge', 'phi1', 'phi2')


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


@dataclass
class BagData:
    """What a recording holds, as arrays (times in s from the first joint_state)."""

    t0_ns: int
    states: np.ndarray                 # (n, 8): t, cart, theta1, theta2, hoist (the rope length), bridge, phi1,
    #                                    phi2 (NaN: a joint the crane has not)
    reference: np.ndarray              # (m, 3): t, position, moving (1: a joint's velocity is not 0)
    motions: list                      # [(start t as streamed, duration, goal position)]
    timing: np.ndarray                 # (k, 4): t, lateness p50, p99, max (us)
    markers: list = field(default_factory=list)  # [(t, [(x, y, z) of the trolley, m1, m2])]
    L1: float = CraneParams.L1
    L2: float = CraneParams.L2


def read_bag(path) -> BagData:
    """The topics of a recording; RecordingError if it is not one or holds no joint_states."""
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import Stores, get_typestore
    path = Path(path)
    if not (path / 'metadata.yaml').is_file():
        raise RecordingError(f'{path} is not a rosbag2 recording (no metadata.yaml in it)')
    states, reference, motions, timing, markers = [], [], [], [], []
    try:
        with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            for conn, received, raw in reader.messages():
                name = conn.topic.rsplit('/', 1)[-1]
                if name not in ('joint_states', 'reference', 'trajectory', 'diagnostics', 'crane_markers'):
                    continue
                msg = reader.deserialize(raw, conn.msgtype)
                if name == 'joint_states':
                    index = {j: k for k, j in enumerate(msg.name)}
                    if all(j in index for j in ('cart', 'theta1', 'theta2')):
                        states.append((_ns(msg.header.stamp), *(msg.position[index[j]] if j in index else math.nan
                                                              for j in STATE_JOINTS)))
                elif name == 'reference' and getattr(msg, 'points', None):
                    point = msg.points[0]
                    reference.append((_ns(msg.header.stamp), point.positions[_cart(msg)],
                                      float(any(v != 0.0 for v in point.velocities))))
                elif name == 'trajectory' and msg.points:
                    last = msg.points[-1]
                    motions.append((_ns(msg.header.stamp), _ns(last.time_from_start) * 1e-9,
                                    last.positions[_cart(msg)]))
                elif name == 'diagnostics':
                    for status in msg.status:
                        if status.name.endswith(': stream'):
                            values = {kv.key: kv.value for kv in status.values}
                            if 'lateness_p50_us' in values:
                                timing.append((received, *(float(values[k]) for k in
                                                           ('lateness_p50_us', 'lateness_p99_us', 'lateness_max_us'))))
                elif name == 'crane_markers' and len(msg.markers) >= 4:
                    pts = [(m.pose.position.x, m.pose.position.y, m.pose.position.z) for m in msg.markers]
                    markers.append((_ns(msg.markers[0].header.stamp), [pts[0], pts[2], pts[3]]))
    except AnyReaderError as exc:
        raise RecordingError(f'cannot read {path}: {exc}') from None
    if not states:
        raise RecordingError(f'{path} holds no joint_states with joints cart, theta1, theta2')
    states = np.array(sorted(states), dtype=float)
    t0 = int(states[0, 0])
    states[:, 0] = (states[:, 0] - t0) * 1e-9
    reference = np.array([((s - t0) * 1e-9, p, m) for s, p, m in sorted(reference)]).reshape(-1, 3)
    data = BagData(t0, states, reference, streamed_starts(reference, [((s - t0) * 1e-9, d, g)
                                                                     for s, d, g in sorted(set(motions))]),
                   np.array([((s - t0) * 1e-9, *v) for s, *v in sorted(timing)]).reshape(-1, 4),
                   [((s - t0) * 1e-9, p) for s, p in markers])
    if markers:  # the cable lengths the sim drew with
        _, (cart, m1, m2) = markers[-1]
        data.L1 = math.dist(m1, cart)
        data.L2 = math.dist(m2, m1)
    return data


def streamed_starts(reference: np.ndarray, motions: list) -> list:
    """``motions`` [(stamp t, duration, goal)] with each start where the reference starts it: the sample
    before its first moving one at or after the stamp (before the next motion's stamp); the stamp without
    such a sample (no reference recorded, or a handover: moving at its stamp already)."""
    t, moving = reference[:, 0], reference[:, 2] > 0
    starts = []
    for k, (stamp, duration, goal) in enumerate(motions):
        until = motions[k + 1][0] if k + 1 < len(motions) else math.inf
        first = np.flatnonzero((t >= stamp) & (t < until) & moving)
        start = stamp
        if first.size and first[0] > 0 and not moving[first[0] - 1] and t[first[0] - 1] >= stamp:
            start = float(t[first[0] - 1])
        starts.append((start, duration, goal))
    return starts


def _cart(msg) -> int:
    """The cart's column of a JointTrajectory (the first when it names no cart)."""
    names = list(msg.joint_names)
    return names.index('cart') if 'cart' in names else 0


def load_mm(data: BagData) -> np.ndarray:
    """Horizontal offset (mm) of the load from its rest below the cart at each joint_state (with a hoist,
    with the rope length that joint_state reports; with a bridge, the norm of the offset)."""
    from crane_msgs_py.crane.geometry import load_swing
    rope = data.states[:, 4]
    L1 = np.where(np.isnan(rope), data.L1, rope)
    phi = data.states[:, 6:8].T
    spatial = len(phi[0]) and np.isfinite(phi).all()
    return 1e3 * load_swing(data.states[:, 2], data.states[:, 3], L1, data.L2, *(phi if spatial else ()))


def motion_table(data: BagData, settle: float | None = None) -> list[dict]:
    """Per motion: start, duration, goal, and the peak load swing (mm) after it, until the next one starts
    (or ``settle`` s, or the recording ends)."""
    t, load = data.states[:, 0], load_mm(data)
    rows = []
    for k, (start, duration, goal) in enumerate(data.motions):
        end = start + duration
        until = data.motions[k + 1][0] if k + 1 < len(data.motions) else t[-1]
        if settle is not None:
            until = min(until, end + settle)
        after = (t >= end) & (t <= until)
        rows.append({'start_s': start, 'duration_s': duration, 'goal_m': goal,
                     'observed_s': max(until - end, 0.0),
                     'residual_mm': float(np.max(np.abs(load[after]))) if after.any() else None})
    return rows


def write_figures(data: BagData, out: Path) -> list[Path]:
    """report_motion.png (cart, load swing), report_timing.png (tick lateness), report_crane.png (markers)."""
    from .figures import plt, save_figure
    out.mkdir(parents=True, exist_ok=True)
    written = []
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True)
    if data.reference.size:
        ax.plot(data.reference[:, 0], data.reference[:, 1], lw=1.0, label='reference (1 kHz)')
    ax.plot(data.states[:, 0], data.states[:, 1], '.', ms=2, label='cart, measured (joint_states)')
    for start, duration, _ in data.motions:
        for a in (ax, ax2):
            a.axvspan(start, start + duration, color='0.9', zorder=0)
    ax.set_ylabel('cart position (m)')
    ax.legend(fontsize=8)
    ax2.plot(data.states[:, 0], load_mm(data), lw=0.9)
    ax2.set_ylabel('load swing (mm)')
    ax2.set_xlabel('time (s) from the first joint_state; shaded: motions')
    ax.set_title(f'recording: {len(data.motions)} motions, L1 {data.L1:.3f} m, L2 {data.L2:.3f} m', fontsize=10)
    written.append(save_figure(fig, out / 'report_motion.png'))
    if data.timing.size:
        fig, ax = plt.subplots(figsize=(10, 3.5))
        for k, label in ((1, 'p50'), (2, 'p99'), (3, 'max')):
            ax.plot(data.timing[:, 0], data.timing[:, k], '.-', ms=3, label=label)
        ax.set_yscale('log')
        ax.set_ylabel('streamer tick lateness (us)')
        ax.set_xlabel('time (s)')
        ax.legend(fontsize=8)
        written.append(save_figure(fig, out / 'report_timing.png'))
    if data.markers:
        written.append(plot_markers(data, out / 'report_crane.png'))
    return written


def plot_markers(data: BagData, path: Path, frames: int = 9):
    """What the markers draw, at ``frames`` instants around the largest swing: cart, cables, masses."""
    from .figures import plt, save_figure
    times = np.array([m[0] for m in data.markers])
    load = np.abs(load_mm(data))
    peak_t = data.states[int(np.argmax(load)), 0]
    picks = np.searchsorted(times, peak_t + np.linspace(-0.9, 0.9, frames))
    picks = np.clip(picks, 0, len(times) - 1)
    fig, ax = plt.subplots(figsize=(10, 4.2))
    cmap = plt.get_cmap('viridis')
    for i, k in enumerate(picks):
        _, (cart, m1, m2) = data.markers[k]
        color = cmap(i / max(frames - 1, 1))
        # the x-z side view (each point (x, y, z))
        ax.plot([cart[0], m1[0], m2[0]], [cart[2], m1[2], m2[2]], '-', color=color, lw=1.2)
        ax.plot([cart[0]], [cart[2]], 's', color=color, ms=9)
        ax.plot([m1[0]], [m1[2]], 'o', color=color, ms=6)
        ax.plot([m2[0]], [m2[2]], 'o', color=color, ms=8)
    ax.axhline(0.0, color='0.5', lw=3, zorder=0)
    ax.set_aspect('equal')
    ax.set_xlabel('x along the rail (m), frame crane_base')
    ax.set_ylabel('z (m)')
    ax.set_title(f'crane_markers at {frames} instants, {1.8:g} s around the largest swing (dark to light)',
                 fontsize=10)
    return save_figure(fig, path)

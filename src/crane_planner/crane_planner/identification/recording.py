"""A recorded move: time, cart position, the two swing angles and optionally the cart reference.

CSV layout (header row, any column order, extra columns ignored): ``t`` (s),
``cart`` (m, measured or reference cart position), ``theta1``, ``theta2``
(rad, paper conventions: theta2 relative to the upper cable), optional
``reference`` (m, the reference the axis was given). Pure Python + numpy.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass

import numpy as np

from crane_msgs_py.crane.errors import PlanError

REQUIRED_COLUMNS = ('t', 'cart', 'theta1', 'theta2')
#: Fewest samples a fit is attempted on.
MIN_SAMPLES = 20


class RecordingError(PlanError):
    """The data cannot be used as given; the message says why."""


@dataclass(frozen=True)
class Recording:
    """Samples of one move, strictly increasing in time, all finite (checked on construction).

    Attributes:
        t: sample times (s).
        cart: cart position (m).
        theta1, theta2: swing angles (rad).
        reference: cart reference position (m) at the same times, or None.
    """

    t: np.ndarray
    cart: np.ndarray
    theta1: np.ndarray
    theta2: np.ndarray
    reference: np.ndarray | None = None

    def __post_init__(self):
        columns = {'t': self.t, 'cart': self.cart, 'theta1': self.theta1, 'theta2': self.theta2}
        if self.reference is not None:
            columns['reference'] = self.reference
        n = None
        for name, values in columns.items():
            values = np.asarray(values, dtype=float)
            if values.ndim != 1:
                raise RecordingError(f'{name} must be one column of numbers')
            if n is not None and values.size != n:
                raise RecordingError(f'{name} has {values.size} samples, t has {n}')
            n = values.size
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                raise RecordingError(f'{name} is not finite at sample {bad[0]} (of {n})')
            object.__setattr__(self, name, values)
        if n < MIN_SAMPLES:
            raise RecordingError(f'a recording needs at least {MIN_SAMPLES} samples, got {n}')
        step = np.diff(self.t)
        if np.any(step <= 0.0):
            k = int(np.flatnonzero(step <= 0.0)[0])
            raise RecordingError(f't must increase strictly; sample {k + 1} ({self.t[k + 1]:g} s) '
                                 f'does not follow {self.t[k]:g} s')
        if np.max(step) > 3.0 * np.median(step):
            k = int(np.argmax(step))
            raise RecordingError(f'a gap of {step[k]:g} s after t = {self.t[k]:g} s (median step '
                                 f'{np.median(step):g} s): the samples must be evenly spaced')

    def write_csv(self, path) -> None:
        """Write the CSV layout ``read_csv`` reads (full float precision)."""
        names = ['t', 'cart', 'theta1', 'theta2'] + (['reference'] if self.reference is not None else [])
        with open(path, 'w', newline='') as f:
            writer = csv.writer(f)
            writer.writerow(names)
            writer.writerows(zip(*(getattr(self, n).tolist() for n in names)))

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def period(self) -> float:
        """Median sample spacing (s)."""
        return float(np.median(np.diff(self.t)))


def read_csv(path) -> Recording:
    """A Recording from a CSV file; RecordingError names what is wrong with it."""
    try:
        with open(path, newline='') as f:
            reader = csv.reader(f)
            header = next(reader, None)
            rows = [row for row in reader if row and any(cell.strip() for cell in row)]
    except OSError as exc:
        raise RecordingError(f'cannot read {path}: {exc.strerror or exc}') from None
    except (csv.Error, UnicodeDecodeError) as exc:
        raise RecordingError(f'{path} is not a readable CSV file: {exc}') from None
    if header is None:
        raise RecordingError(f'{path} is empty')
    header = [h.strip() for h in header]
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        raise RecordingError(f'{path} lacks column(s) {", ".join(missing)} (header: {", ".join(header)})')
    index = {name: header.index(name) for name in (*REQUIRED_COLUMNS, 'reference') if name in header}
    columns = {name: [] for name in index}
    for line, row in enumerate(rows, start=2):
        for name, k in index.items():
            try:
                columns[name].append(float(row[k]))
            except (IndexError, ValueError):
                raise RecordingError(f'{path}, line {line}: column {name} is not a number: '
                                     f'{row[k] if k < len(row) else "(missing)"!r}') from None
    return Recording(**{name: np.array(values) for name, values in columns.items()})


#: Topic names (their last part: the recording may be namespaced) read from a rosbag2 recording.
JOINT_STATES_NAME, REFERENCE_NAME = 'joint_states', 'reference'
#: How far (m) the rope (or the bridge) may move in a recording crane-plan identify takes: beyond, it moved.
HELD_ROPE = 1e-3


def read_bag(path) -> Recording:
    """A Recording from a rosbag2 recording (a folder with ``metadata.yaml``; MCAP or SQLite storage).

    ``joint_states`` (``sensor_msgs/JointState``, joints ``cart``, ``theta1``,
    ``theta2``) gives the samples, at their header stamps; ``reference``
    (``trajectory_msgs/JointTrajectory``, the streamer's one-point samples), when
    recorded, is interpolated onto them by stamp. A topic whose name ends in
    ``/joint_states`` counts, so a namespaced setup's recording works too.
    Read with ``rosbags`` (no ROS install needed).
    """
    from pathlib import Path

    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if not (path / 'metadata.yaml').is_file():
        raise RecordingError(f'{path} is not a rosbag2 recording (no metadata.yaml in it)')
    try:
        with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            def named(name):
                found = sorted({c.topic for c in reader.connections
                                if c.topic == name or c.topic.endswith('/' + name)})
                if len(found) > 1:
                    raise RecordingError(f'{path} holds several {name} topics ({", ".join(found)}); '
                                         'record one crane')
                return [c for c in reader.connections if found and c.topic == found[0]]

            states = named(JOINT_STATES_NAME)
            if not states:
                raise RecordingError(f'{path} holds no joint_states topic (topics: '
                                     f'{", ".join(sorted({c.topic for c in reader.connections})) or "none"})')
            rows, ropes, bridges = [], [], []
            for conn, _, raw in reader.messages(connections=states):
                msg = reader.deserialize(raw, conn.msgtype)
                index = {name: k for k, name in enumerate(msg.name)}
                if not all(j in index for j in ('cart', 'theta1', 'theta2')):
                    raise RecordingError(f'joint_states in {path} lacks joint(s) cart, theta1 or theta2 '
                                         f'(has {", ".join(msg.name)})')
                stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
                rows.append((stamp, *(float(msg.position[index[j]]) for j in ('cart', 'theta1', 'theta2'))))
                if 'hoist' in index:
                    ropes.append(float(msg.position[index['hoist']]))
                if 'bridge' in index:
                    bridges.append(float(msg.position[index['bridge']]))
            references = []
            for conn, _, raw in reader.messages(connections=named(REFERENCE_NAME)):
                msg = reader.deserialize(raw, conn.msgtype)
                if getattr(msg, 'points', None) and len(msg.points[0].positions):  # unstamped arrays are skipped
                    stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
                    references.append((stamp, float(msg.points[0].positions[0])))
    except AnyReaderError as exc:
        raise RecordingError(f'cannot read {path}: {exc}') from None
    if not rows:
        raise RecordingError(f'{path} holds no joint_states messages')
    if ropes and max(ropes) - min(ropes) > HELD_ROPE:  # the model has one L1: the fit needs the rope held
        raise RecordingError(f'the hoist moved during the recording (the rope from {min(ropes):.4g} to '
                             f'{max(ropes):.4g} m): identify needs a recording with the rope held')
    if bridges and max(bridges) - min(bridges) > HELD_ROPE:  # the fit is of the x-z plane: the cart's move
        raise RecordingError(f'the bridge moved during the recording (from {min(bridges):.4g} to '
                             f'{max(bridges):.4g} m): identify fits a move of the cart alone (the swing\'s '
                             'parameters are the same in both directions); record one with the bridge held')
    data = np.array(sorted(rows))
    t0 = data[0, 0]
    reference = None
    if references:
        ref = np.array(sorted(references))
        reference = np.interp(data[:, 0], ref[:, 0], ref[:, 1])
    return Recording(data[:, 0] - t0, data[:, 1], data[:, 2], data[:, 3], reference)

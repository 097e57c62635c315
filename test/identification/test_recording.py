"""Recordings (crane_planner.identification.recording): CSV round trips, evenly spaced samples, and
rosbag2 MCAP recordings that give what the CSV gives."""
import json

import numpy as np
import pytest

from crane_planner.identification import Recording, read_csv
from crane_planner.identification.recording import RecordingError
from identification.recordings import TABLE1, record, run_identify, write_bag, write_csv


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


def test_a_rosbag2_mcap_recording_gives_what_the_csv_gives(tmp_path):
    truth = TABLE1.replace(L1=0.5, L2=0.36, tau=0.02)
    rec = record(truth, reference=True)
    write_csv(tmp_path / 'move.csv', rec)
    write_bag(tmp_path / 'bag', rec)
    assert list((tmp_path / 'bag').glob('*.mcap')) and (tmp_path / 'bag' / 'metadata.yaml').is_file()
    from_csv, from_bag = (json.loads(run_identify(*source, '--json').stdout)
                          for source in (('--csv', str(tmp_path / 'move.csv')), ('--bag', str(tmp_path / 'bag'))))
    for key in ('L1', 'L2', 'mass_ratio', 'omega1', 'omega2'):
        assert from_bag[key] == pytest.approx(from_csv[key], rel=1e-6), key
    assert from_bag['tau'] == pytest.approx(0.02, rel=0.05)  # the reference interpolated from 1 kHz samples
    empty = tmp_path / 'empty'
    empty.mkdir()
    out = run_identify('--bag', str(empty))
    assert out.returncode == 2 and 'not a rosbag2 recording' in out.stderr

"""crane_sim.sensor: a camera's samples released after its latency with their own stamps and in order, lost at
its dropout rate, seeded, its settings changed while it runs."""
import math

import numpy as np
import pytest

from crane_msgs_py.crane.params import ParameterError
from crane_sim.measurement import AngleNoise
from crane_sim.sensor import Sensor, SensorSettings

STEP = 1e-3  # s, the sim's loop period: the clock the sensor is asked by
EVERY = 20   # steps between samples (50 Hz)


def run(sensor: Sensor, steps: int, start: int = 0, on_step=None):
    """Step a 1 kHz clock, a sample every 20 steps (stamp: its step, angles: (step, -step), values: ('v', step)):
    [(step released at, sample)]."""
    out = []
    for k in range(start, start + steps):
        if on_step is not None:
            on_step(k)
        now = k * STEP
        if k % EVERY == 0:
            sensor.measure(now, k, (float(k), -float(k)), 'v', k)
        out += [(k, s) for s in sensor.released(now)]
    return out


def test_without_latency_dropout_or_noise_each_sample_is_released_as_measured_at_once():
    sensor = Sensor()
    sample = sensor.measure(0.2, 123, (0.1, -0.2), [1.0, 2.0], [3.0])
    assert sensor.released(0.2) == [sample] and sensor.pending == 0
    assert sample.stamp == 123 and sample.angles == (0.1, -0.2) and sample.values == ([1.0, 2.0], [3.0])


def test_with_latency_each_sample_is_released_that_much_later_with_its_stamp_in_order():
    sensor = Sensor(SensorSettings(latency=0.05))
    released = run(sensor, 1000)
    assert [s.stamp for _, s in released] == list(range(0, 1000 - 50, EVERY))  # every one, in order
    for k, s in released:
        assert k == s.stamp + 50  # the step 50 ms after it was taken, not one later
        assert s.taken == pytest.approx(s.stamp * STEP) and s.angles == (s.stamp, -s.stamp)
        assert s.values == ('v', s.stamp)
    assert sensor.pending == 2  # taken within the last 50 ms (at 960 and 980): still being processed


def test_a_latency_that_is_not_a_whole_number_of_steps_releases_at_the_first_step_after_it():
    sensor = Sensor(SensorSettings(latency=0.0305))
    assert {k - s.stamp for k, s in run(sensor, 500)} == {31}


def test_the_dropout_loses_its_share_of_the_samples_and_never_releases_them():
    sensor = Sensor(SensorSettings(dropout=0.3), seed=4)
    n = 20_000
    kept = [s for s in (sensor.measure(k * 0.02, k, (0.0,)) for k in range(n)) if s is not None]
    assert sensor.taken == n and sensor.dropped == n - len(kept)
    assert sensor.dropped / n == pytest.approx(0.3, abs=4 * math.sqrt(0.3 * 0.7 / n))
    assert sensor.released(n * 0.02) == kept
    # lost ones in a row as often as independent losses would be: not in bursts
    lost = np.ones(n, bool)
    lost[[s.stamp for s in kept]] = False
    both = np.mean(lost[1:] & lost[:-1])
    assert both == pytest.approx(0.09, abs=0.01)


def test_a_seed_makes_the_losses_and_the_noise_reproducible_and_the_noise_independent_of_the_dropout():
    def samples(seed, dropout):
        sensor = Sensor(SensorSettings(dropout=dropout, noise=1e-3), seed=seed)
        return [sensor.measure(k * 0.02, k, (0.1, 0.2)) for k in range(500)]

    one, same, other = samples(3, 0.4), samples(3, 0.4), samples(5, 0.4)
    assert one == same
    assert [s is None for s in one] != [s is None for s in other]
    # the noise of every kept sample is the noise AngleNoise of the same seed draws, lost samples counted
    noise = AngleNoise(1e-3, 3)
    expected = [tuple(noise(0.1, 0.2)) for _ in range(500)]
    assert all(s.angles == e for s, e in zip(one, expected) if s is not None)
    assert [s.angles for s in samples(3, 0.0)] == expected


def test_latency_and_dropout_change_while_running_and_the_order_holds():
    sensor = Sensor(SensorSettings(latency=0.1))

    def change(k):
        if k == 300:  # shorter: what was queued is due at once, in order
            sensor.settings = SensorSettings(latency=0.02)
        elif k == 600:  # everything lost
            sensor.settings = SensorSettings(latency=0.02, dropout=1.0)
        elif k == 800:  # longer again, nothing lost
            sensor.settings = SensorSettings(latency=0.06)

    released = run(sensor, 1200, on_step=change)
    stamps = [s.stamp for _, s in released]
    assert stamps == sorted(stamps)
    delays = {s.stamp: k - s.stamp for k, s in released}
    assert delays[180] == 100 and delays[200] == 100  # released at 280 and 300 (due then)
    assert all(300 - stamp == delays[stamp] for stamp in (220, 240, 260))  # the burst at the change
    assert delays[280] == 20 and delays[580] == 20
    assert not any(600 <= s < 800 for s in stamps) and sensor.dropped == 10
    assert delays[800] == 60 and delays[1120] == 60 and 1140 not in delays


def test_bad_settings_are_named():
    for kwargs, match in (({'latency': -0.1}, 'sensor_latency'), ({'dropout': 1.5}, 'sensor_dropout'),
                          ({'dropout': math.nan}, 'sensor_dropout'), ({'noise': -1.0}, 'noise'),
                          ({'latency': math.inf}, 'sensor_latency')):
        with pytest.raises(ParameterError, match=match):
            SensorSettings(**kwargs)

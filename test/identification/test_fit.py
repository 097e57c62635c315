"""Commissioning: identify the crane from a recorded move (crane_planner.identification.fit).

Data come from crane_sim's independent numpy simulator with seeded sensor noise
(crane_sim.measurement); the truth is the simulated plant. Damping ratios are
checked against the eigenvalues of a finite-difference linearization of that
simulator, not against the planner's model.
"""
import math

import numpy as np
import pytest
from references import linearized_modes

from crane_planner.identification import IdentificationError, Recording, identify
from identification.recordings import TABLE1, random_plant, record


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

"""Model parameters and the linearized crane, against closed forms."""
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from crane_msgs_py.crane.params import CraneParams, ParameterError
from crane_planner.planning.model import linearized_matrices, modal_frequencies


def double_pendulum_frequencies(L1, L2, m1, m2, g):
    """Textbook closed form of the two natural frequencies of a double pendulum (fixed pivot)."""
    M = m1 + m2
    s = L1 + L2
    root = math.sqrt(M * M * s * s - 4.0 * M * m1 * L1 * L2)
    den = 2.0 * m1 * L1 * L2
    return math.sqrt(g * (M * s - root) / den), math.sqrt(g * (M * s + root) / den)


def test_table1_defaults():
    p = CraneParams()
    assert (p.L1, p.L2, p.m1, p.m2, p.g, p.tau) == (0.470, 0.391, 0.192, 0.201, 9.81, 0.01)


def test_table1_frequencies_match_closed_form_and_paper():
    w1, w2 = modal_frequencies(CraneParams())
    assert (w1, w2) == pytest.approx(double_pendulum_frequencies(0.470, 0.391, 0.192, 0.201, 9.81), rel=1e-12)
    assert w1 == pytest.approx(3.642, abs=5e-4) and w2 == pytest.approx(8.990, abs=5e-4)
    # The paper's Table 1 lists 3.640 and 9.017 (rounded from another g or geometry): within 0.4 %.
    assert w1 == pytest.approx(3.640, rel=4e-3) and w2 == pytest.approx(9.017, rel=4e-3)


@given(L1=st.floats(0.05, 5), L2=st.floats(0.05, 5), m1=st.floats(0.01, 10), m2=st.floats(0.01, 10))
def test_frequencies_closed_form_any_crane(L1, L2, m1, m2):
    w = modal_frequencies(CraneParams(L1=L1, L2=L2, m1=m1, m2=m2))
    assert w == pytest.approx(double_pendulum_frequencies(L1, L2, m1, m2, 9.81), rel=1e-9)


def test_static_deflection_under_constant_acceleration():
    # A constant cart acceleration a tilts the whole pendulum by a/g (small angles): theta1 = a/g, theta2 = 0.
    M, K, b = linearized_matrices(CraneParams())
    q = np.linalg.solve(K, b * 0.5)
    assert q == pytest.approx([0.5 / 9.81, 0.0], abs=1e-15)


@pytest.mark.parametrize('field, value, needle', [
    ('L1', 0.0, 'L1 must be > 0'), ('L2', -1.0, 'L2 must be > 0'), ('m1', 0.0, 'm1 must be > 0'),
    ('m2', float('nan'), 'm2 must be finite'), ('g', float('inf'), 'g must be finite'),
    ('tau', -0.01, 'tau must be >= 0'), ('L1', 'abc', 'L1 must be a number'),
])
def test_invalid_parameters_name_the_problem(field, value, needle):
    with pytest.raises(ParameterError, match=needle):
        CraneParams(**{field: value})


def test_replace_validates_and_rejects_unknown_names():
    assert CraneParams().replace(L1=0.42).L1 == 0.42
    with pytest.raises(ParameterError, match='unknown model parameter'):
        CraneParams().replace(L3=1.0)
    with pytest.raises(ParameterError, match='tau must be >= 0'):
        CraneParams().replace(tau=-1)

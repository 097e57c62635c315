"""The transcription's derivatives, assembled point by point, are CasADi's own of the whole NLP.

The reference is CasADi's symbolic differentiation of the whole NLP (``nlpsol`` asked for nothing but the
NLP), evaluated at random variables, parameters and multipliers: a Jacobian or Hessian block put in the
wrong place, scaled by the wrong interval or left out would differ.
"""
import casadi as ca
import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.collocation import Transcription
from crane_planner.planning.problem import Form, Problem

CASES = {  # robust, hoist, bridge, limits, keep-out boxes, via points, free final time
    'nvf': ((), False, False, False, 0, 0, False),
    'rvf-free-time': (('L1',), False, False, True, 0, 0, True),
    'spatial-rvf-free-time': (('L1',), False, True, True, 0, 0, True),
    'rvf-limits': (('L1',), False, False, True, 0, 0, False),
    'rvf-hoist': (('L1',), True, False, False, 0, 0, False),
    'spatial-nvf-box': ((), False, True, False, 1, 0, False),
    'spatial-rvf-via': (('L1',), False, True, True, 0, 1, False),
    'hoist-limits-boxes-via': ((), True, False, True, 2, 1, False),  # keep-out rows between limits and via
}


@pytest.mark.parametrize('case', list(CASES))
def test_the_derivatives_by_point_are_casadis_of_the_whole_nlp(case):
    robust, hoist, bridge, limits, boxes, vias, free_time = CASES[case]
    tr = Transcription(Problem(robust, Form.of(CraneParams(), hoist, bridge)), 6, limits, free_time=free_time,
                       boxes=boxes, vias=vias)
    options = {'print_time': False, 'ipopt.print_level': 0, 'ipopt.sb': 'yes'}
    ours = tr.nlpsol(options)
    whole = ca.nlpsol('whole', 'ipopt', tr.nlp, options)
    rng = np.random.default_rng(7)
    x, lam_g = rng.normal(size=tr.nw), rng.normal(size=tr.ng)
    p = 0.5 + rng.random(tr.nlp['p'].shape[0])  # positive: lengths, masses, durations, interval fractions
    for name, args in (('nlp_grad_f', (x, p)), ('nlp_jac_g', (x, p)), ('nlp_hess_l', (x, p, 0.7, lam_g))):
        mine, theirs = ours.get_function(name)(*args), whole.get_function(name)(*args)
        for a, b in zip(mine if isinstance(mine, tuple) else [mine], theirs if isinstance(theirs, tuple) else [theirs]):
            a, b = np.array(ca.DM(a)), np.array(ca.DM(b))
            assert a.shape == b.shape
            assert np.allclose(a, b, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(b).max())), (name, np.abs(a - b).max())

"""The planning core: the paper's crane model and its methods. Pure mathematics: no ROS import, and
nothing of the serving machinery (``crane_planner.serving``).

One request: ``dispatch.plan(method, displacement, duration, params, options)``;
to serve many, use ``crane_planner.serving.Planner``.
"""
import os

# CasADi's OpenBLAS (under MUMPS) would start a thread per core that spins between
# calls: on matrices this small one thread is faster alone and far faster beside
# other solves. Set here, before any module of the package loads CasADi; an explicit
# setting is kept.
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

from .dispatch import PlanOptions, check_request  # noqa: E402
from .methods import METHODS, ROBUST_PARAMETERS, SHAPER_METHODS, VARIATIONAL_METHODS  # noqa: E402
from .plan import Plan, PlanError, Samples  # noqa: E402

__all__ = ['METHODS', 'ROBUST_PARAMETERS', 'SHAPER_METHODS', 'VARIATIONAL_METHODS', 'Plan', 'PlanError',
           'Samples', 'PlanOptions', 'check_request']

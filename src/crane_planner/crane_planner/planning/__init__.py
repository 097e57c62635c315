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

from .methods import (  # noqa: E402
    METHODS,
    ROBUST_PARAMETERS,
    SHAPER_METHODS,
    VARIATIONAL_METHODS,
    Family,
    MethodSpec,
    Supports,
    method_spec,
)
from .plan import Plan, PlanError, Samples  # noqa: E402


def __getattr__(name: str):
    # dispatch (and CasADi with it) loads on first use: the streamer imports the pure modules of this
    # package (the model, the shapers) and must not load CasADi
    if name in ('PlanOptions', 'check_request'):
        from . import dispatch
        return getattr(dispatch, name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


__all__ = ['METHODS', 'ROBUST_PARAMETERS', 'SHAPER_METHODS', 'VARIATIONAL_METHODS', 'Family', 'MethodSpec', 'Supports',
           'method_spec', 'Plan', 'PlanError',
           'Samples', 'PlanOptions', 'check_request']

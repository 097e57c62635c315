"""The names of the planning methods the facade serves (contract: Methods).

Kept apart from the solvers so that naming a method loads neither CasADi
nor the solvers themselves.
"""
from __future__ import annotations

from .shapers import SHAPERS

#: The paper's variational formulations (optimal control).
VARIATIONAL_METHODS = ('nvf', 'rvf')
#: Input shapers, cascaded over both pendulum modes (``shapers.SHAPERS``).
SHAPER_METHODS = tuple(SHAPERS)
METHODS = VARIATIONAL_METHODS + SHAPER_METHODS

#: Parameters RVF may be made insensitive to.
ROBUST_PARAMETERS = ('L1', 'L2', 'm1', 'm2', 'tau')

"""The planning core: the paper's crane model, its methods and the ``Planner`` facade. No ROS import.

Use the facade: ``Planner().plan(method, displacement, duration, params, options)``.
"""
from .methods import METHODS, ROBUST_PARAMETERS, SHAPER_METHODS, VARIATIONAL_METHODS
from .plan import Plan, PlanError, Samples
from .planner import PlanOptions, Planner, check_request

__all__ = ['METHODS', 'ROBUST_PARAMETERS', 'SHAPER_METHODS', 'VARIATIONAL_METHODS', 'Plan', 'PlanError',
           'Samples', 'PlanOptions', 'Planner', 'check_request']

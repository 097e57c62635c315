"""The methods registry: each method's entry says its family, what it supports and how it is planned."""
import subprocess
import sys

import pytest

from crane_planner.planning import METHODS, SHAPER_METHODS, VARIATIONAL_METHODS, PlanError
from crane_planner.planning.methods import (
    REGISTRY,
    Family,
    MethodSpec,
    Supports,
    family_of,
    find_method,
    lacks,
    method_spec,
    methods_of,
    methods_supporting,
)
from crane_planner.planning.shapers import SHAPERS


def test_every_method_of_the_contract_has_an_entry_in_its_order():
    assert METHODS == ('nvf', 'rvf', 'zv', 'nzv', 'zvd', 'ei', 'mzv', 'zvdd')
    assert VARIATIONAL_METHODS == ('nvf', 'rvf') == methods_of(Family.VARIATIONAL)
    assert SHAPER_METHODS == tuple(SHAPERS) == methods_of(Family.SHAPER)
    assert all(isinstance(spec, MethodSpec) and spec.name == name for name, spec in REGISTRY.items())


def test_a_shaper_is_planned_by_its_design_function_a_variational_method_by_a_solver():
    for name in SHAPER_METHODS:
        assert method_spec(name).design is SHAPERS[name]
    for name in VARIATIONAL_METHODS:
        assert method_spec(name).design is None
    assert [name for name, spec in REGISTRY.items() if spec.robust] == ['rvf']


def test_what_each_family_supports():
    nvf, zv = method_spec('nvf').supports, method_spec('zv').supports
    for supports in (nvf, zv):  # both plan every axis, route past boxes and start in motion
        assert supports.hoisting and supports.bridge and supports.routes and supports.start_in_motion
        assert supports.fastest
    assert nvf.exact_vias and nvf.routes_with_vias and nvf.settle and nvf.fastest_hoisting
    assert nvf.retarget_while_hoisting
    # a shaper: via points within a tolerance, no route through them, no settle, no fastest hoisting
    # plan, no new goal while the rope length changes
    assert not (zv.exact_vias or zv.routes_with_vias or zv.settle or zv.fastest_hoisting
                or zv.retarget_while_hoisting)
    assert methods_supporting('settle') == VARIATIONAL_METHODS


def test_an_unknown_name_is_refused_by_the_same_message_everywhere():
    with pytest.raises(PlanError, match=r"^unknown method 'lqr'; choose from nvf, rvf, zv, nzv, zvd, ei, mzv, zvdd$"):
        method_spec('lqr')
    with pytest.raises(PlanError, match='unknown method'):
        method_spec(['nvf'])  # unhashable
    assert find_method('lqr') is None and family_of('lqr') is None and family_of(None) is None
    assert not lacks('lqr', 'settle')  # left to the request's check
    assert lacks('zv', 'settle') and not lacks('rvf', 'settle')


def test_entries_are_frozen():
    spec = method_spec('zv')
    with pytest.raises(AttributeError):
        spec.family = Family.VARIATIONAL
    with pytest.raises(AttributeError):
        spec.supports.settle = True
    assert isinstance(spec.supports, Supports)


def test_naming_a_method_loads_no_solver():
    code = ('import sys; from crane_planner.planning.methods import method_spec; method_spec("rvf"); '
            'print(sorted(m for m in sys.modules if m.split(".")[0] == "casadi" or m.endswith(".variational")))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == '[]'

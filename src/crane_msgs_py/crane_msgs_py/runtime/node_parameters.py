"""Node parameters as the contract wants them: declared with descriptions and ranges, validated as a set.

Each node describes its parameters in a table ``name -> (default, description,
descriptor fields)`` and validates a whole proposed set with one function
that raises ParameterError (or ValueError) naming the problem. ``Guard``
then refuses a bad change with that reason, logs it and reports it on
/diagnostics, including changes rclpy itself refuses for being out of a
declared range (those never reach an on-set callback).

A parameter renamed (``params.renamed_from`` among its fields) keeps its
former name for one release: ``declare`` declares that too, untyped and
unset, and applies a value given to it at start-up (a parameters file, an
override) to the new name; ``Guard`` turns a set of it into a set of the new
name. Either logs a deprecation warning naming the new name.
"""
from __future__ import annotations

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.parameter import Parameter

from crane_msgs_py.crane.params import RENAMED_FROM, renamed
from crane_msgs_py.runtime.diagnostics import ERROR

#: The diagnostic task of refused parameter changes (status ``<node>: parameters``).
PARAMETERS_TASK = 'parameters'


def float_range(lo: float, hi: float) -> dict:
    """Descriptor fields of a double parameter in [lo, hi]."""
    return {'floating_point_range': [FloatingPointRange(from_value=float(lo), to_value=float(hi), step=0.0)]}


def int_range(lo: int, hi: int) -> dict:
    """Descriptor fields of an integer parameter in [lo, hi]."""
    return {'integer_range': [IntegerRange(from_value=int(lo), to_value=int(hi), step=1)]}


def _descriptor_fields(extra: dict) -> dict:
    """``extra`` with its plain (lo, hi) ranges as rcl's range messages (a former name is no descriptor field)."""
    fields = {key: value for key, value in extra.items() if key != RENAMED_FROM}
    for key, make in (('floating_point_range', float_range), ('integer_range', int_range)):
        if isinstance(fields.get(key), tuple):
            fields.update(make(*fields[key]))
    return fields


def declare(node, table: dict) -> dict:
    """Declare every parameter of ``table``; their values (overrides applied) by name.

    A range is given as ``float_range``/``int_range`` make it, or plain as
    (lo, hi) (the table of a pure module, e.g. ``streaming.config``). An empty
    list default declares an empty double array (rclpy would type it as a byte
    array).
    """
    for name, (default, description, extra) in table.items():
        descriptor = ParameterDescriptor(description=description, **_descriptor_fields(extra))
        if isinstance(default, list) and not default:
            node.declare_parameter(name, Parameter.Type.DOUBLE_ARRAY, descriptor)
            if node.get_parameter_or(name).type_ == Parameter.Type.NOT_SET:  # no override given
                node.set_parameters([Parameter(name, Parameter.Type.DOUBLE_ARRAY, [])])
        else:
            node.declare_parameter(name, default, descriptor)
    for old, new in renamed(table).items():
        # untyped and unset unless given: a value of it is the user's, not a default
        node.declare_parameter(old, None, ParameterDescriptor(
            description=f'deprecated: the former name of {new}, taken for one release', dynamic_typing=True))
        given = node.get_parameter(old)
        if given.type_ != Parameter.Type.NOT_SET:
            _deprecated(node, old, new)
            result = node.set_parameters([Parameter(new, value=given.value)])[0]
            if not result.successful:
                raise ValueError(f'{old} (now {new}): {result.reason}')
    return {name: node.get_parameter(name).value for name in table}


def _deprecated(node, old: str, new: str) -> None:
    node.get_logger().warning(f'parameter {old} is deprecated and will be removed: it is applied to {new}; '
                              f'set {new} instead')


def renaming(changes, former: dict, node=None) -> list:
    """``changes`` (Parameters) with each one of a former name (``former``: old -> new) made one of its new
    name, in its place, a deprecation warning logged on ``node`` for each."""
    out = []
    for change in changes:
        new = former.get(change.name)
        if new is not None:
            if node is not None:
                _deprecated(node, change.name, new)
            change = Parameter(new, value=change.value)
        out.append(change)
    return out


class Guard:
    """Validates every parameter change as part of the node's whole parameter set.

    Args:
        node: the node (its parameters of ``names`` are validated together).
        names: the parameter names ``check`` needs (its parameter table: a set of a renamed one's former name
            is one of it).
        check: ``check(values) -> result``; raises ParameterError/ValueError naming the problem.
        apply: ``apply(result, values, changes)``, called for an accepted change before it is set.
        diagnostics: the node's DiagnosticsPublisher.
    """

    def __init__(self, node, names, check, apply, diagnostics):
        self._node, self._names = node, tuple(names)
        self._former = renamed(names) if isinstance(names, dict) else {}
        self._check, self._apply, self._diagnostics = check, apply, diagnostics
        node.add_pre_set_parameters_callback(self._report)
        node.add_on_set_parameters_callback(self._decide)

    def _proposed(self, changes) -> dict:
        values = {name: self._node.get_parameter(name).value for name in self._names}
        values.update((c.name, c.value) for c in changes)
        return values

    def _validate(self, changes):
        values = self._proposed(changes)
        try:
            return self._check(values), values, ''
        except (TypeError, ValueError) as exc:  # ParameterError is a ValueError
            return None, values, str(exc)

    def _report(self, changes):
        # A pre-set callback runs before rclpy's range checks, so every refusal gets reported; it may change
        # what is set: a former name is set as its new one.
        changes = renaming(changes, self._former, self._node)
        result, _, reason = self._validate(changes)
        if reason:
            self._node.get_logger().error(f'parameter change refused: {reason}')
            self._diagnostics.report(PARAMETERS_TASK, ERROR, reason, error=reason,
                                     **{c.name: c.value for c in changes})
        return changes

    def _decide(self, changes) -> SetParametersResult:
        result, values, reason = self._validate(changes)
        if reason:
            return SetParametersResult(successful=False, reason=reason)
        self._apply(result, values, changes)
        self._node.get_logger().info('parameters set: ' + ', '.join(f'{c.name}={c.value}' for c in changes))
        return SetParametersResult(successful=True)

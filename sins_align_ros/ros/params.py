"""Parameter declaration with descriptors, ranges and validation for rclpy nodes."""
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)

from ..align.params import Param, markdown_table  # noqa: F401  (re-exported for nodes)


def descriptor(p):
    """Build the rcl ParameterDescriptor of a :class:`Param` (type, range, choices)."""
    d = ParameterDescriptor(name=p.name, description=p.description, read_only=p.read_only)
    if p.is_array:
        d.type = ParameterType.PARAMETER_DOUBLE_ARRAY
    elif isinstance(p.default, bool):
        d.type = ParameterType.PARAMETER_BOOL
    elif isinstance(p.default, int):
        d.type = ParameterType.PARAMETER_INTEGER
        if p.lo is not None:
            d.integer_range = [IntegerRange(from_value=int(p.lo), to_value=int(p.hi), step=0)]
    elif isinstance(p.default, float):
        d.type = ParameterType.PARAMETER_DOUBLE
        if p.lo is not None:
            d.floating_point_range = [FloatingPointRange(from_value=float(p.lo),
                                                         to_value=float(p.hi), step=0.0)]
    else:
        d.type = ParameterType.PARAMETER_STRING
    if p.choices:
        d.additional_constraints = 'one of: ' + ', '.join(p.choices)
    return d


def declare(node, params, check=True):
    """Declare ``params`` on ``node``, validate them now and on every later change.

    Returns a dict name -> current value. Invalid start-up values raise
    ``ValueError`` with the reason (with ``check`` false they are kept, for a managed
    node that checks them when it is configured); invalid runtime changes are refused
    with the reason in the SetParametersResult.
    """
    by_name = {p.name: p for p in params}
    values = {}
    for p in params:
        default = list(p.default) if p.is_array else p.default
        value = node.declare_parameter(p.name, default, descriptor(p)).value
        err = p.check(value) if check else None
        if err:
            raise ValueError(err)
        values[p.name] = p.normalise(value)

    def _on_set(changes):
        for c in changes:
            p = by_name.get(c.name)
            if p is None:
                continue
            err = p.check(c.value)
            if err:
                return SetParametersResult(successful=False, reason=err)
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(_on_set)
    return values

"""Parameter declaration with descriptors, ranges and validation for rclpy nodes."""
from dataclasses import dataclass

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)


@dataclass(frozen=True)
class Param:
    """One node parameter.

    ``choices`` restricts a string; ``lo``/``hi`` a number (inclusive);
    ``read_only`` parameters can only be set at start-up.
    """

    name: str
    default: object
    description: str
    lo: float = None
    hi: float = None
    choices: tuple = None
    read_only: bool = False

    def descriptor(self):
        """Build the rcl ParameterDescriptor with type, range and constraint text."""
        d = ParameterDescriptor(name=self.name, description=self.description,
                                read_only=self.read_only)
        if isinstance(self.default, bool):
            d.type = ParameterType.PARAMETER_BOOL
        elif isinstance(self.default, int):
            d.type = ParameterType.PARAMETER_INTEGER
            if self.lo is not None:
                d.integer_range = [IntegerRange(from_value=int(self.lo), to_value=int(self.hi),
                                                step=0)]
        elif isinstance(self.default, float):
            d.type = ParameterType.PARAMETER_DOUBLE
            if self.lo is not None:
                d.floating_point_range = [FloatingPointRange(from_value=float(self.lo),
                                                             to_value=float(self.hi), step=0.0)]
        else:
            d.type = ParameterType.PARAMETER_STRING
        if self.choices:
            d.additional_constraints = 'one of: ' + ', '.join(self.choices)
        return d

    def check(self, value):
        """Return an error message for ``value`` or None if it is acceptable."""
        if self.choices and value not in self.choices:
            return f'{self.name}={value!r} is not one of {", ".join(self.choices)}'
        if self.lo is not None and not (self.lo <= value <= self.hi):
            return f'{self.name}={value!r} is outside [{self.lo}, {self.hi}]'
        return None


def declare(node, params):
    """Declare ``params`` on ``node``, validate them now and on every later change.

    Returns a dict name -> current value. Invalid start-up values raise
    ``ValueError`` with the reason; invalid runtime changes are refused with the
    reason in the SetParametersResult.
    """
    by_name = {p.name: p for p in params}
    values = {}
    for p in params:
        values[p.name] = node.declare_parameter(p.name, p.default, p.descriptor()).value
        err = p.check(values[p.name])
        if err:
            raise ValueError(err)

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


def markdown_table(params):
    """Markdown rows documenting ``params`` (the README's parameter tables are built from this)."""
    rows = ['| name | default | range / values | description |', '|---|---|---|---|']
    for p in params:
        if p.choices:
            rng = ', '.join(f'`{c}`' for c in p.choices)
        elif p.lo is not None:
            rng = f'[{p.lo}, {p.hi}]'
        else:
            rng = ''
        rows.append(f'| `{p.name}` | `{p.default}` | {rng} | {p.description} |')
    return '\n'.join(rows)

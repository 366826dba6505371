"""Parameter declaration with descriptors, ranges and validation for rclpy nodes.

Beside declaring, :func:`declare` makes three things about the parameter overrides
(``-p``, ``--params-file``) forgiving or loud, as the replay tool is:

* an integer given for a double (``-p coarse_duration:=60``, a YAML ``60``, or an integer
  set at run time) is taken as that double: rclpy would refuse it as the wrong type;
* an override that names no declared parameter (a typo) is warned about with the closest
  declared name; the node keeps running (params files shared by several nodes through
  ``/**`` are common);
* a params file on the command line with no entry matching the node (a misspelt top-level
  node name: rcl ignores it) is warned about with the node names it holds.
"""
import re
import sys

import yaml
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)
from rclpy.parameter import Parameter

from ..align.params import Param, closest  # noqa: F401  (re-exported)
from ..align.param_text import markdown_table  # noqa: F401  (re-exported)

#: override names that rclpy or rcl declare themselves, or that configure rclpy (not ours)
_FOREIGN = ('qos_overrides.',)


def descriptor(p):
    """Build the rcl ParameterDescriptor of a :class:`Param` (type, range, choices).

    A parameter that takes NaN for "not set" (:attr:`Param.unset`) has no
    ``floating_point_range`` (rclpy would refuse NaN against it): its range is in
    ``additional_constraints`` and checked by :func:`declare`'s callback.
    """
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
        if p.unset:
            d.additional_constraints = (f'from {float(p.lo)} to {float(p.hi)}, '
                                        'or .nan: not set')
        elif p.lo is not None:
            d.floating_point_range = [FloatingPointRange(from_value=float(p.lo),
                                                         to_value=float(p.hi), step=0.0)]
    else:
        d.type = ParameterType.PARAMETER_STRING
    if p.choices:
        d.additional_constraints = 'one of: ' + ', '.join(p.choices)
    return d


def as_declared(p, param):
    """Return rclpy ``param`` with integers turned into the double (array) ``p`` declares.

    Anything else is returned unchanged (rclpy and :meth:`Param.check` judge it).
    """
    if p is None:
        return param
    if p.is_array and param.type_ == Parameter.Type.INTEGER_ARRAY:
        return Parameter(param.name, Parameter.Type.DOUBLE_ARRAY,
                         [float(v) for v in param.value])
    if (isinstance(p.default, float) and not isinstance(p.default, bool)
            and param.type_ == Parameter.Type.INTEGER):
        return Parameter(param.name, Parameter.Type.DOUBLE, float(param.value))
    return param


def overrides(node):
    """Return the node's parameter overrides, name -> rclpy ``Parameter`` (Context and node).

    rclpy keeps them in ``Node._parameter_overrides`` (there since Foxy, no public
    accessor); an empty dict where it is absent.
    """
    found = getattr(node, '_parameter_overrides', None)
    return found if isinstance(found, dict) else {}


def declare(node, params, check=True, argv=None):
    """Declare ``params`` on ``node``, validate them now and on every later change.

    Returns a dict name -> current value. Invalid start-up values raise
    ``ValueError`` with the reason (with ``check`` false they are kept, for a managed
    node that checks them when it is configured); invalid runtime changes are refused
    with the reason in the SetParametersResult. Integers for doubles are taken (at
    start-up and at run time); unknown override names and params files without an entry
    for the node (in ``argv``, default ``sys.argv``: the executables' command line)
    are warned about (module docstring). Call it once, after any other declaration.
    """
    by_name = {p.name: p for p in params}
    given = overrides(node)
    for name, param in list(given.items()):
        given[name] = as_declared(by_name.get(name), param)
    values = {}
    for p in params:
        default = list(p.default) if p.is_array else p.default
        value = node.declare_parameter(p.name, default, descriptor(p)).value
        err = p.check(value) if check else None
        if err:
            raise ValueError(err)
        values[p.name] = p.normalise(value)

    def _pre_set(changes):
        return [as_declared(by_name.get(c.name), c) for c in changes]

    def _on_set(changes):
        for c in changes:
            p = by_name.get(c.name)
            if p is None:
                continue
            err = p.check(c.value)
            if err:
                return SetParametersResult(successful=False, reason=err)
        return SetParametersResult(successful=True)

    node.add_pre_set_parameters_callback(_pre_set)
    node.add_on_set_parameters_callback(_on_set)
    for text in unknown_overrides(node, given, params):
        node.get_logger().warning(text)
    for text in unmatched_params_files(node, sys.argv if argv is None else argv):
        node.get_logger().warning(text)
    return values


def unknown_overrides(node, given, params):
    """Return one warning per override in ``given`` that ``node`` has not declared."""
    names = [p.name for p in params]
    out = []
    for name in sorted(given):
        if node.has_parameter(name) or name.startswith(_FOREIGN):
            continue
        near = closest(name, names)
        out.append(f'unknown parameter {name!r} ignored'
                   + (f' (did you mean {near!r}?)' if near else '')
                   + ': not a parameter of this node (a typo, or a params file shared '
                   'with other nodes)')
    return out


def params_files(argv):
    """Paths given with ``--params-file`` inside the ``--ros-args`` sections of ``argv``."""
    out, in_ros = [], False
    args = list(argv)
    for k, a in enumerate(args):
        if a == '--ros-args':
            in_ros = True
        elif a == '--':
            in_ros = False
        elif in_ros and a == '--params-file' and k + 1 < len(args):
            out.append(args[k + 1])
    return out


def _node_keys(data, prefix=''):
    """Node-name paths of a ROS params-file mapping (keys nested down to ``ros__parameters``)."""
    out = []
    for key, body in data.items():
        if not isinstance(body, dict):
            continue
        path = f'{prefix}/{str(key).strip("/")}' if prefix else str(key)
        if 'ros__parameters' in body:
            out.append(path)
        out.extend(_node_keys({k: v for k, v in body.items() if k != 'ros__parameters'},
                              path))
    return out


def _matches(key, fqn):
    """Tell whether params-file node name ``key`` applies to node ``fqn`` (rcl's wildcards).

    ``/**`` stands for any number of name tokens, ``*`` for one; a name without a
    leading slash is taken from the root.
    """
    key = key if key.startswith('/') else '/' + key
    parts = []
    for token in re.split(r'(\*\*|\*)', key):
        if token == '**':
            parts.append('.*')
        elif token == '*':
            parts.append('[^/]*')
        else:
            parts.append(re.escape(token))
    pattern = ''.join(parts)
    # '/**/name' also matches '/name' (no namespace)
    pattern = pattern.replace('/.*/', '(/.*)?/')
    return re.fullmatch(pattern, fqn) is not None


def unmatched_params_files(node, argv):
    """Return one warning per params file in ``argv`` with no entry for ``node``.

    Files that cannot be read or are not the node-name layout are left alone (rcl
    would have refused an unreadable file before the node existed).
    """
    fqn = node.get_fully_qualified_name()
    out = []
    for path in params_files(argv):
        try:
            with open(path) as f:
                data = yaml.safe_load(f)
        except (OSError, yaml.YAMLError):
            continue
        if not isinstance(data, dict):
            continue
        keys = _node_keys(data)
        if keys and not any(_matches(k, fqn) for k in keys):
            out.append(f'params file {path}: no entry for this node {fqn} (its node names: '
                       f'{", ".join(keys)}), so none of its parameters apply; use the node\'s '
                       'name or /**')
    return out


def startup_error(exc):
    """One line for an rclpy start-up failure ``exc`` (``rclpy.init``'s ``RCLError``).

    rcl reads every ``--params-file`` in ``rclpy.init``; a missing or malformed file
    fails there with rcl's message and source locations. This gives the path and the
    cause only.
    """
    text = str(exc)
    m = re.search(r"--params-file ([^']*)'\. Error: (.*?)(, at |$)", text)
    if m is None:
        return text.splitlines()[0] if text else type(exc).__name__
    path, cause = m.group(1), m.group(2)
    if cause.startswith('Error opening YAML file'):
        cause = 'cannot open it (no such file, or not readable)'
    return f'params file {path}: {cause}'

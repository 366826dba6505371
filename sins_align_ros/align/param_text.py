"""Parameters to and from text: ``--set name=value``, YAML parameter files, the docs' tables.

The declarations and their checks are :mod:`.params`'; this module reads what a user
writes (a replay's ``--set``, a ROS parameter file) into those declarations' types, and
writes the markdown tables the docs carry (a test keeps them equal).
"""
import yaml

from .params import ALIGNMENT_PARAMS, NODE_PARAMS, declaration, unknown_message


def parse_value(name, text):
    """Convert ``--set name=value`` text to the parameter's type (the value is read as YAML)."""
    p = declaration(name)
    if p is None:
        raise ValueError(unknown_message(name, ALIGNMENT_PARAMS + NODE_PARAMS))
    if isinstance(p.default, str):
        return text
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        raise ValueError(f'{name}: cannot read {text!r} as a value') from None
    if isinstance(p.default, bool) and type(value) is int and value in (0, 1):
        return bool(value)
    if p.is_array:
        value = p.normalise(value)
        if p.check(value):
            raise ValueError(f'{name} expects an array of {len(p.default)} numbers such as '
                             f'[0.0, 0.0, 0.0], got {text!r}')
        return value
    if isinstance(p.default, float) and type(value) is int:
        return float(value)
    if type(value) is not type(p.default):
        raise ValueError(f'{name} expects a {type(p.default).__name__}, got {text!r}')
    return value


def load_yaml(path, node_name='alignment_node'):
    """Read alignment parameters from a YAML file.

    Accepts the ROS parameter-file layout (``node: {ros__parameters: {...}}``,
    also with ``/**`` as node name) or a flat mapping of names to values.
    Raises ``ValueError`` with one line for a file that cannot be read, is not YAML,
    or holds no entry for ``node_name`` (naming the entries it holds).
    """
    try:
        with open(path) as f:
            data = yaml.safe_load(f) or {}
    except OSError as exc:
        raise ValueError(f'params file {path}: cannot open it ({exc.strerror})') from None
    except yaml.YAMLError as exc:
        where = getattr(exc, 'problem_mark', None)
        at = f' at line {where.line + 1}' if where is not None else ''
        what = getattr(exc, 'problem', None) or 'not valid YAML'
        raise ValueError(f'params file {path}: not valid YAML{at}: {what}') from None
    if not isinstance(data, dict):
        raise ValueError(f'{path}: expected a mapping of parameters')
    for key in (node_name, '/' + node_name, '/**'):
        if isinstance(data.get(key), dict) and 'ros__parameters' in data[key]:
            return dict(data[key]['ros__parameters'])
    nodes = [k for k, v in data.items() if isinstance(v, dict) and 'ros__parameters' in v]
    if nodes:
        raise ValueError(f'params file {path}: no parameters for {node_name} (its node names: '
                         f'{", ".join(map(str, nodes))}; use {node_name} or /**)')
    return dict(data)


def markdown_table(params):
    """Markdown rows documenting ``params`` (the docs' parameter tables are built from this)."""
    rows = ['| name | default | range / values | description |', '|---|---|---|---|']
    for p in params:
        if p.choices:
            rng = ', '.join(f'`{c}`' for c in p.choices)
        elif p.lo is not None:
            rng = f'[{p.lo}, {p.hi}]'
        else:
            rng = ''
        default = list(p.default) if p.is_array else p.default
        if p.unset:
            default = '.nan'
            rng += ' or `.nan`: not set'
        rows.append(f'| `{p.name}` | `{default}` | {rng} | {p.description} |')
    return '\n'.join(rows)

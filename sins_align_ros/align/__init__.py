"""The alignment layer's front door (no ROS imports).

ros/, cli/ and eval/ use these names, and the parameter table in :mod:`.params`; the rooms
behind them (``inputs``, ``engines``, ``stages``, ``forecast``: docs/layout.md) are
not theirs to import, which ``.importlinter``'s contract "Only the front door of align"
checks. The names load on first use (PEP 562), so that importing one input module does not
load every engine through this file.
"""
import importlib

#: public name -> the module of align that defines it
_EXPORTS = {
    'AlignmentSession': 'session',
    'AlignmentPipeline': 'pipeline',
    'PHASES': 'pipeline',
    'Output': 'output',
    'HEADING_UNKNOWN_VAR': 'output',
    'params': None,
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    """Return a public name of the alignment layer, importing its module on first use."""
    if name not in _EXPORTS:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    module = _EXPORTS[name]
    if module is None:
        return importlib.import_module(f'{__name__}.{name}')
    return getattr(importlib.import_module(f'{__name__}.{module}'), name)

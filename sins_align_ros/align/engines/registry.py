"""The engine class of every row of the filter table (:mod:`..filter_table`).

A row's engine is the class of its family (:data:`FAMILY_BASES`) that names the row in its
own ``fine_filter``: ``class UnscentedNavigation(IntegratedNavigation): fine_filter =
'ukf'``. The still family is the exception: one engine, :class:`~.stationary.StationaryEngine`,
runs each of seed 002's models by the row's name. A new fine filter is one engine class
plus one row (:func:`register` adds a row at run time, :func:`unregister` removes it);
:mod:`.factory` builds the engine from its family's parameters and the class's
``options(cfg)``.
"""
from ..filter_table import FILTERS, MOVING, NAVIGATION, ROBUST, STILL, add, remove
from . import moving, navigation_filters, robust  # noqa: F401  (their classes name rows)
from .navigation import IntegratedNavigation
from .stationary import StationaryEngine

#: family -> the class every engine of the family derives from
FAMILY_BASES = {STILL: StationaryEngine, MOVING: moving.MovingBaseAlignment,
                ROBUST: robust.RobustAlignment, NAVIGATION: IntegratedNavigation}


def _subclasses(cls):
    for sub in cls.__subclasses__():
        yield sub
        yield from _subclasses(sub)


def engine_class(name):
    """Return the engine class of fine filter ``name`` (ValueError for a name with no row).

    The one class of the row's family whose own ``fine_filter`` is ``name``; a still
    filter's is the stationary engine, which takes ``name`` as its model's.
    """
    row = FILTERS.get(name)
    if row is None:
        raise ValueError(f'unknown fine filter {name!r}')
    base = FAMILY_BASES[row.family]
    found = [c for c in _subclasses(base) if vars(c).get('fine_filter') == name]
    if row.family == STILL and not found:
        return base
    if len(found) != 1:
        raise ValueError(f'fine filter {name!r}: {len(found)} engine classes of the '
                         f'{row.family} family name it (one must)')
    return found[0]


def register(row):
    """Add ``row`` to the filter table; its engine class must name it (ValueError if not)."""
    add(row)
    try:
        engine_class(row.name)
    except ValueError:
        remove(row.name)
        raise


def unregister(name):
    """Remove the row of fine filter ``name`` from the filter table."""
    remove(name)

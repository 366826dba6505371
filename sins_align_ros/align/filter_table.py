"""The fine filters, one row each: the one table every list of filter names derives from.

A row says a filter's name, its family, the seed paper it follows, its states and use (its
line in docs/filters.md), the scenario of its paper (eval.scenarios: timings, the compiled
kernels' check) and the scenarios the integrity matrix runs it on (bench/integrity.py).
From it come the parameters' choices and families (:mod:`.params`), the factory's dispatch
(the row's family, and the engine class whose ``fine_filter`` is the row's name:
:mod:`.engines.registry`), the scenario tables and docs/filters.md's table
(test/test_registry.py checks it against :func:`markdown_table`).

Plain data at the bottom of align, so that :mod:`.params` can read it without loading an
engine (docs/layout.md). A new fine filter is one row here plus one engine class;
a row added at run time (:func:`add`) is in every name list at once, since the lists are
views (:class:`Names`), not copies.
"""
from collections.abc import Sequence
from dataclasses import dataclass

#: the families: seed 002's zero-velocity filters; seed 000's GNSS-aided cubature filters;
#: seed 004's robust ones (12 states, GNSS velocity); the integrated navigation of seeds
#: 001/003 (align, then go on navigating)
STILL, MOVING, ROBUST, NAVIGATION = 'still', 'moving', 'robust', 'navigation'
FAMILIES = (STILL, MOVING, ROBUST, NAVIGATION)
#: the GNSS-aided (moving-base) families
AIDED = (MOVING, ROBUST, NAVIGATION)


@dataclass(frozen=True)
class FilterRow:
    """One fine filter.

    ``family``: one of :data:`FAMILIES`; ``seed``: the paper in ../shared/seeds/
    (``'002'``); ``states``, ``use``: its line in docs/filters.md; ``scenario``: the
    :func:`~sins_align_ros.sim.presets.scenario` preset of its paper; ``checked_on``: the
    presets the integrity matrix runs it on, in table order; ``reported_covariance``: its
    engine sets R each epoch and may take it from the GNSS messages
    (``use_reported_gnss_covariance``); not the variational-Bayes filters, whose R is their
    own posterior.
    """

    name: str
    family: str
    seed: str
    states: str
    use: str
    scenario: str
    checked_on: tuple
    reported_covariance: bool = False


#: name -> :class:`FilterRow`, in family order (the order of every list derived from it)
FILTERS = {}


def add(row):
    """Add ``row`` to :data:`FILTERS` after the rows of its family (ValueError if known)."""
    if row.family not in FAMILIES:
        raise ValueError(f'{row.name}: unknown family {row.family!r}')
    if row.name in FILTERS or row.name == 'auto':
        raise ValueError(f'fine filter {row.name!r} exists')
    rows = list(FILTERS.values()) + [row]
    rows.sort(key=lambda r: FAMILIES.index(r.family))          # stable: family order
    FILTERS.clear()
    FILTERS.update((r.name, r) for r in rows)


def remove(name):
    """Remove the row of ``name`` (KeyError if it has none)."""
    del FILTERS[name]


class Names(Sequence):
    """The names of the rows of some families (all if none), read from the table when used.

    A tuple to its readers (``in``, iteration, ``len``, ``+``, equality with a tuple);
    ``head`` goes first (``('auto',)`` for the parameter's choices).
    """

    def __init__(self, *families, head=()):
        self.families, self.head = families, tuple(head)

    def _names(self):
        return self.head + tuple(n for n, r in FILTERS.items()
                                 if not self.families or r.family in self.families)

    def __getitem__(self, i):
        return self._names()[i]

    def __len__(self):
        return len(self._names())

    def __contains__(self, name):
        return name in self._names()

    def __iter__(self):
        return iter(self._names())

    def __add__(self, other):
        return self._names() + tuple(other)

    def __radd__(self, other):
        return tuple(other) + self._names()

    def __eq__(self, other):
        return self._names() == (tuple(other) if isinstance(other, (tuple, Names)) else other)

    def __hash__(self):
        return hash(self._names())

    def __repr__(self):
        return repr(self._names())


def markdown_table():
    """Markdown rows of docs/filters.md's filter table (test/test_registry.py checks it)."""
    rows = ['| `fine_filter` | states | seed | use it for |', '|---|---|---|---|']
    rows += [f'| `{r.name}` | {r.states} | {r.seed} | {r.use} |' for r in FILTERS.values()]
    return '\n'.join(rows)


_STILL_ON = ('static_navigation', 'ship_sway', 'seed003_car')
_NAV_ON = ('static_navigation', 'seed003_car', 'seed001_flight')
for _row in (
    FilterRow('reduced7', STILL, '002', '7: horizontal velocity, misalignment, north/up gyro '
              'bias', 'a base that does not translate (still, moored, swaying): fastest, '
              'honest sigma', 'static_navigation', _STILL_ON),
    FilterRow('stationary10', STILL, '002', '10: horizontal velocity, misalignment, 2 accel + '
              '3 gyro biases', 'the same, the classic full model', 'static_navigation',
              _STILL_ON),
    FilterRow('stationary12', STILL, '002', '12: 3-D velocity, misalignment, 3 accel + 3 gyro '
              'biases', 'the same, with the vertical channel', 'static_navigation', _STILL_ON),
    FilterRow('ckf', MOVING, '000', '13: large-azimuth model (velocity, position, '
              'misalignment, gyro drift) + accel bias', 'moving base with GNSS, conventional '
              'cubature KF', 'seed000_case1', ('static_navigation', 'ship_sway',
                                               'seed000_case1'), reported_covariance=True),
    FilterRow('asckf', MOVING, '000', '13: as `ckf`', 'moving base with GNSS whose noise may '
              'change; large heading errors', 'seed000_case1',
              ('static_navigation', 'ship_sway', 'seed000_case1'), reported_covariance=True),
    FilterRow('vbckf', ROBUST, '004', '12: large misalignment (misalignment, 3-D velocity, '
              'gyro drift, accel bias)', 'USV in severe sea, GNSS velocity with outliers',
              'seed004_medium', ('static_navigation', 'seed004_medium')),
    FilterRow('vbch', ROBUST, '004', '12: as `vbckf`', 'the same, with cubature H-infinity '
              'robustness', 'seed004_medium', ('static_navigation', 'seed004_medium')),
    FilterRow('kf', NAVIGATION, '001', '15: loosely coupled (misalignment, velocity, '
              'position, Markov gyro and accel errors)', 'align, then keep navigating '
              '(`~/odom`)', 'seed003_car', _NAV_ON, reported_covariance=True),
    FilterRow('vbakf', NAVIGATION, '001', '15: as `kf`', 'navigating when the GNSS noise is '
              'unknown or changes (seed 001\'s baseline)', 'seed001_flight', _NAV_ON),
    FilterRow('mvbakf', NAVIGATION, '001', '15: as `kf`', 'as `vbakf`, with P(k\\|k-1) and '
              'a full R estimated', 'seed001_flight', _NAV_ON),
    FilterRow('ukf', NAVIGATION, '003', '18: as `kf` with a constant and a Markov gyro drift',
              'a car with a MEMS IMU and a large heading error after coarse alignment',
              'seed003_car', _NAV_ON, reported_covariance=True),
):
    add(_row)

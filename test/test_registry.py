"""The filter registry: a new fine filter is one engine class plus one row of the table.

A test-only filter (seed 001's KF under a new name: one class naming its row, one row
registered for the test and removed after it) goes through the whole pipeline on a short
simulated car run; its output must be the KF's to the bit, since it is the same
arithmetic, and it must align (heading claimed, attitude inside 3 sigma of the truth).
And docs/filters.md's table is the table's.
"""
import re

import numpy as np
import pytest

from conftest import ROOT
from sins_align_ros.align import params as prm
from sins_align_ros.align.engines.heading_range import HEADING_CLAIM_MAX_DEG
from sins_align_ros.align.engines.navigation_filters import KalmanNavigation
from sins_align_ros.align.engines.registry import (FAMILY_BASES, engine_class, register,
                                                   unregister)
from sins_align_ros.align.filter_table import (FAMILIES, FILTERS, NAVIGATION, FilterRow,
                                               markdown_table)
from sins_align_ros.eval.run import run_pipeline
from sins_align_ros.eval.scenarios import named, simulate
from sins_align_ros.sim.presets import alignment_params

NAME = 'kf_registry_test'
#: the one row of the test filter
ROW = FilterRow(NAME, NAVIGATION, '001', '15: as `kf`', 'a test of the registry',
                'seed003_car', ('seed003_car',))


class RegistryTestNavigation(KalmanNavigation):
    """The one engine class of the test filter: seed 001's KF, named for its row."""

    fine_filter = NAME


@pytest.fixture
def registered():
    """The test filter's row in the table for one test, removed after it."""
    register(ROW)
    yield ROW
    unregister(NAME)


@pytest.fixture(scope='module')
def car():
    """150 s of seed 003's car (still 30 s, then driving, a turn at 100 s), GNSS, seed 3."""
    sc = named('seed003_car', 150.0)
    return sc, simulate(sc, 3)


def _run(car, fine_filter):
    sc, data = car
    cfg = alignment_params(sc, fine_filter, coarse_duration=20.0)
    return run_pipeline(prm.validate(cfg), data, block=700)


def test_a_registered_filter_is_in_every_name_list_and_gone_after(registered):
    assert NAME in prm.FINE_FILTERS and NAME in prm.FILTER_CHOICES
    assert NAME in prm.NAV_FILTERS and NAME in prm.MOVING_FILTERS
    assert NAME not in prm.STILL_FILTERS and NAME not in prm.ROBUST_FILTERS
    assert prm.validate({'fine_filter': NAME}) == {'fine_filter': NAME}
    assert engine_class(NAME) is RegistryTestNavigation
    unregister(NAME)
    try:
        assert NAME not in prm.FILTER_CHOICES and NAME not in prm.NAV_FILTERS
        with pytest.raises(ValueError, match=NAME):
            prm.validate({'fine_filter': NAME})
        with pytest.raises(ValueError):
            engine_class(NAME)
    finally:
        register(ROW)                                    # for the fixture to remove


def test_a_registered_filter_runs_through_the_pipeline_as_its_engine_computes(registered,
                                                                              car):
    test, kf = _run(car, NAME), _run(car, 'kf')
    assert type(test.pipeline.engine) is RegistryTestNavigation       # its class ran
    assert test.pipeline.status()['fine_filter'] == NAME                  # and says so
    fine = np.isin(test.out.phase, ('fine', 'aligned'))
    assert fine.any() and np.isfinite(test.out.q[fine]).all()
    assert 'aligned' in test.out.phase
    # the same engine on the same data: every published row is the KF's, bit for bit
    assert np.array_equal(test.out.phase, kf.out.phase)
    assert np.array_equal(test.out.q, kf.out.q, equal_nan=True)
    assert np.array_equal(test.out.P_phi, kf.out.P_phi, equal_nan=True)
    # and it is an alignment: the heading claimed, the final attitude inside 3 published
    # sigma of the truth
    err = test.final
    assert err.known and err.sigma[2] <= np.radians(HEADING_CLAIM_MAX_DEG)
    assert np.all(np.abs(err.euler) <= 3.0 * err.sigma)


def test_a_row_no_engine_class_names_is_refused_and_not_kept():
    row = FilterRow('kf_without_class', NAVIGATION, '001', '', '', 'seed003_car', ())
    with pytest.raises(ValueError, match='kf_without_class'):
        register(row)
    assert 'kf_without_class' not in FILTERS and 'kf_without_class' not in prm.FILTER_CHOICES


def test_every_row_has_one_engine_class_of_its_family():
    assert prm.FINE_FILTERS == tuple(FILTERS)
    for name, row in FILTERS.items():
        assert row.family in FAMILIES
        assert issubclass(engine_class(name), FAMILY_BASES[row.family]), name


def test_the_docs_filter_table_is_the_registry():
    page = (ROOT / 'docs' / 'filters.md').read_text()
    m = re.search(r'<!-- filters -->\n(.*?)\n<!-- /filters -->', page, re.S)
    assert m, 'docs/filters.md has no <!-- filters --> block'
    assert m.group(1).strip() == markdown_table(), (
        'docs/filters.md\'s filter table is stale; paste filter_table.markdown_table()')


def test_the_readme_filter_table_names_every_row_with_its_seed():
    """README's `fine_filter` table: `auto` plus exactly the registry's rows, seeds as theirs."""
    readme = (ROOT / 'README.md').read_text()
    rows = re.findall(r'^\| `(\w+)` \| ([\d-]+) \|', readme, re.M)
    assert rows[0] == ('auto', '-')
    assert {name: seed for name, seed in rows[1:]} == {n: r.seed for n, r in FILTERS.items()}

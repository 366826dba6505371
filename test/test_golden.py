"""Golden replay outputs: the pipeline, its fine filters, the node-side input rules of the
replay tool and the CSV writer give the results recorded in test/golden/ (commit 3010b60).

The cases (test/golden/cases.py) are short seeded runs, one per fine filter plus the two
real recordings, through the replay CLI on simulated rosbag2s and the PSINS log, and
through ``AlignmentPipeline`` + ``feed_arrays`` on the fog_mems car. A refactor must
reproduce them to round-off: same header, same number of rows, the same ``phase`` in
every row, and every number within rtol 1e-6 / atol 1e-9 of the golden (NaN exactly
where the golden has NaN). Two refinements of that rule, both for what the CSV can
show: a difference of one unit in the last decimal the CSV writes is accepted (a
round-off change can flip the rounding of a printed digit: heights and velocities are
written with 4 decimals), and the columns whose size says nothing about their precision
are held absolutely: ``t`` to 1 microsecond, latitude and longitude to 1e-9 deg
(0.1 mm), not to 1e-6 of an epoch stamp or of 114 deg. Angles are compared modulo
360 deg.

If a change is MEANT to change results, regenerate the goldens with
``test/golden/regenerate.py`` and say so in the commit message.
"""
import csv
import math

import pytest

from conftest import shared_data
from golden.cases import CASES, GOLDEN_DIR, run_case

#: not a round-off count: the worst-case round-off of a whole run (test/tolerance.py,
#: n samples x ~150 operations: 1e-9 relative for 150 s at 100 Hz, test_kernels.py) is
#: 1000 x smaller; the bound is what the CSV's printed digits and gating decisions allow
RTOL, ATOL = 1e-6, 1e-9
#: columns compared with an absolute tolerance only
ABSOLUTE = {'t': 1e-6, 'lat_deg': 1e-9, 'lon_deg': 1e-9}
#: columns compared modulo 360 deg
ANGLES = {'roll_deg', 'pitch_deg', 'yaw_deg', 'heading_deg'}


@pytest.fixture(scope='module')
def workdir(tmp_path_factory):
    """One folder for the module: cases that share a simulated bag write it once."""
    return tmp_path_factory.mktemp('golden')


def _read(path):
    with open(path, newline='') as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def _decimals(text):
    return len(text.split('.', 1)[1]) if '.' in text else 0


def golden_differences(result_path, golden_path, limit=10):
    """Compare a result CSV with its golden; return a list of differences (empty: equal)."""
    header, rows = _read(result_path)
    g_header, g_rows = _read(golden_path)
    if header != g_header:
        return [f'header {header} != golden {g_header}']
    if len(rows) != len(g_rows):
        return [f'{len(rows)} rows, golden has {len(g_rows)}']
    diffs = []
    for i, (row, g_row) in enumerate(zip(rows, g_rows)):
        for name, text, g_text in zip(header, row, g_row):
            if name == 'phase':
                ok = text == g_text
            else:
                v, g = float(text), float(g_text)
                if math.isnan(g) or math.isnan(v):
                    ok = math.isnan(g) and math.isnan(v)
                else:
                    d = v - g
                    if name in ANGLES:
                        d = (d + 180.0) % 360.0 - 180.0
                    tol = ABSOLUTE.get(name, ATOL + RTOL * abs(g))
                    ok = abs(d) <= max(tol, 1.5 * 10.0 ** -_decimals(g_text))
            if not ok:
                diffs.append(f'row {i + 1} (t={row[0]}) {name}: {text}, golden {g_text}')
                if len(diffs) >= limit:
                    return diffs + ['...']
    return diffs


@pytest.mark.parametrize('case', CASES, ids=[c.name for c in CASES])
def test_replay_output_equals_the_golden_csv_to_round_off(case, workdir):
    """The case run with the current code reproduces test/golden/<case>.csv."""
    assert case.golden.exists(), f'no golden {case.golden} (run test/golden/regenerate.py)'
    out = run_case(case, workdir, shared_data)
    diffs = golden_differences(out, case.golden)
    assert not diffs, (f'{case.name} ({case.what}) differs from its golden:\n'
                       + '\n'.join(diffs))


def test_golden_cases_cover_every_fine_filter_and_every_golden_file_has_a_case():
    from sins_align_ros.align.params import FINE_FILTERS
    assert {c.fine_filter for c in CASES} == set(FINE_FILTERS)
    assert len({c.name for c in CASES}) == len(CASES)
    assert {p.stem for p in GOLDEN_DIR.glob('*.csv')} == {c.name for c in CASES}


def test_golden_comparison_accepts_round_off_and_catches_a_changed_number(tmp_path):
    """The comparison itself: a last-digit flip and a wrap of the yaw pass; a change
    of 1e-5 in a quaternion, a changed phase, NaN for a number, a missing row fail."""
    golden = tmp_path / 'golden.csv'
    header = 't,qw,yaw_deg,h_m,phase'
    golden.write_text(f'{header}\n1700000000.010000000,0.707106781187,179.999999999,'
                      f'30.1234,fine\n1700000000.020000000,nan,nan,nan,coarse\n')

    def diffs(*rows):
        p = tmp_path / 'r.csv'
        p.write_text('\n'.join([header, *rows]) + '\n')
        return golden_differences(p, golden)

    coarse = '1700000000.020000000,nan,nan,nan,coarse'
    assert diffs('1700000000.010000000,0.707106781187,179.999999999,30.1234,fine',
                 coarse) == []
    assert diffs('1700000000.010000000,0.707106781188,-179.999999999,30.1235,fine',
                 coarse) == []
    assert diffs('1700000000.010000000,0.707116781187,179.999999999,30.1234,fine', coarse)
    assert diffs('1700000000.010000000,0.707106781187,179.999999999,30.1234,aligned',
                 coarse)
    assert diffs('1700000000.010000000,0.707106781187,179.999999999,30.1234,fine',
                 '1700000000.020000000,1.0,nan,nan,coarse')
    assert diffs('1700000000.010000000,0.707106781187,179.999999999,30.1234,fine')
    assert diffs('1700000000.011000000,0.707106781187,179.999999999,30.1234,fine', coarse)

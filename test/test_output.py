"""Output rows (align/output.py): fine-phase Rows converted in one pass, as one by one."""
import numpy as np
import pytest

from sins_align_ros.align.output import Output, Rows, assemble, convert, unknown
from sins_align_ros.nav.frames import euler_to_dcm


def test_a_run_of_rows_converts_as_each_part_alone():
    """Each part's one covariance and phase cover exactly its rows; navigation rows stay
    with their samples (NaN for a part without); an Output between runs splits them."""
    rng = np.random.default_rng(4)
    parts, want_P, want_phase = [], [], []
    t0 = 0.0
    for k, n in enumerate((3, 1, 5, 2, 4)):
        t = t0 + 0.01 * np.arange(1, n + 1)
        t0 = t[-1]
        if k == 2:                                     # an unknown stretch between runs
            parts.append(unknown(t, 'coarse'))
            want_P.append(np.full((n, 3, 3), np.nan))
            want_phase += ['coarse'] * n
            continue
        C = np.array([euler_to_dcm(rng.normal(scale=0.3, size=3)) for _ in range(n)])
        A = rng.normal(scale=1e-3, size=(3, 3))
        P = A @ A.T + 1e-8 * np.eye(3)
        phase = ('fine', 'aligned')[k % 2]
        nav = rng.normal(size=(n, 6)) if k != 1 else None
        parts.append(Rows(t, C, P, phase, nav))
        want_P.append(np.broadcast_to(P, (n, 3, 3)))
        want_phase += [phase] * n
    out = convert(parts)
    alone = Output.concat([p.output() if isinstance(p, Rows) else p for p in parts])
    assert list(out.phase) == want_phase == list(alone.phase)
    np.testing.assert_array_equal(out.P_phi, np.concatenate(want_P))
    for name in ('t', 'q', 'euler', 'sigma', 'nav'):
        np.testing.assert_array_equal(getattr(out, name), getattr(alone, name), err_msg=name)
    assert np.isnan(out.nav[3:4]).all() and np.isfinite(out.nav[:3]).all()
    assert len(assemble(parts)) == len(out) == 15


def test_a_result_csv_is_written_whole_or_not_at_all(tmp_path):
    """A failure part-way (here a phase name that is no ASCII) keeps the previous file."""
    from sins_align_ros.io.results import read_csv, write_csv
    path = tmp_path / 'out.csv'
    good = unknown(np.arange(3.0), 'waiting')
    write_csv(path, good)
    before = path.read_bytes()
    assert read_csv(path)['phase'].tolist() == ['waiting'] * 3
    bad = unknown(np.arange(5.0), 'wait\u00e9')
    with pytest.raises(UnicodeEncodeError):
        write_csv(path, bad)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ['out.csv']

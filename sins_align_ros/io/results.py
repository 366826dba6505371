"""The result CSV of the replay tool (docs/contracts.md and ../shared/DESIGN.md: a contract).

Columns: ``t,qx,qy,qz,qw,roll_deg,pitch_deg,yaw_deg,sigma_roll_deg,sigma_pitch_deg,
sigma_yaw_deg,phase`` followed by ``heading_deg`` (navigation heading, clockwise
from north, for people) and, when a navigation filter ran with
``continue_navigation`` (``kf``, ``vbakf``, ``mvbakf``, ``ukf``), :data:`NAV_COLUMNS`:
latitude, longitude (deg), height (m) and ENU velocity (m/s). One row per output
epoch; the last row is the final result. Unknown values (waiting/coarse phases) are
written as ``nan``.
"""
import csv
import os
from pathlib import Path

import numpy as np

from ..nav.frames import yaw_to_heading
from .fixed_text import write_table

COLUMNS = ('t', 'qx', 'qy', 'qz', 'qw', 'roll_deg', 'pitch_deg', 'yaw_deg',
           'sigma_roll_deg', 'sigma_pitch_deg', 'sigma_yaw_deg', 'phase', 'heading_deg')
NAV_COLUMNS = ('lat_deg', 'lon_deg', 'h_m', 've_mps', 'vn_mps', 'vu_mps')


def write_csv(path, out, every=1):
    """Write an :class:`~sins_align_ros.align.pipeline.Output` to ``path``.

    ``every`` keeps one row in ``every`` (the last row is always written).
    """
    n = len(out.t)
    step = max(1, int(every))
    if step == 1:
        rows = slice(None)                # every row: views, no gathered copies
    else:
        rows = np.arange(0, n, step)
        if n and rows[-1] != n - 1:
            rows = np.append(rows, n - 1)
    euler = out.euler[rows]
    names = COLUMNS + (NAV_COLUMNS if out.nav is not None else ())
    # the table in place, column by column (t, q, Euler, sigmas, heading[, navigation])
    values = np.empty((len(euler), len(names) - 1))
    values[:, 0] = out.t[rows]
    values[:, 1:5] = out.q[rows]
    np.degrees(euler, out=values[:, 5:8])
    np.degrees(out.sigma[rows], out=values[:, 8:11])
    values[:, 11] = np.degrees(yaw_to_heading(euler[:, 2]))
    decimals = [9] + [12] * 4 + [9] * 7
    if out.nav is not None:
        nav = out.nav[rows]
        np.degrees(nav[:, :2], out=values[:, 12:14])
        values[:, 14:] = nav[:, 2:]
        decimals += [10, 10] + [4] * 4
    _write_whole(path, (','.join(names) + '\r\n').encode('ascii'),
                 lambda f: write_table(f, values, decimals, np.asarray(out.phase)[rows],
                                       text_col=COLUMNS.index('phase')))


def _write_whole(path, head, write_body):
    """Write ``head`` then ``write_body(f)`` to ``path``, all or nothing.

    The text is written as it is formatted: into a temporary file beside ``path`` that
    replaces it only once complete, so a failure part-way leaves the previous file (or
    none), not a truncated one. A ``path`` that exists and is no regular file (a pipe,
    ``/dev/stdout``) is written directly.
    """
    target = Path(path)
    if target.exists() and not target.is_file():
        with open(target, 'wb') as f:
            f.write(head)
            write_body(f)
        return
    tmp = target.with_name(f'.{target.name}.{os.getpid()}.tmp')
    try:
        with open(tmp, 'wb') as f:
            f.write(head)
            write_body(f)
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def read_csv(path):
    """Read a result CSV back: dict of column -> ndarray (``phase`` as str array)."""
    with open(path, newline='') as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    cols = {}
    for i, name in enumerate(header):
        vals = [r[i] for r in body]
        cols[name] = np.array(vals) if name == 'phase' else np.array(vals, dtype=float)
    return cols

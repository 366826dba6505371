"""The result CSV of the replay tool (DESIGN.md contract).

Columns: ``t,qx,qy,qz,qw,roll_deg,pitch_deg,yaw_deg,sigma_roll_deg,sigma_pitch_deg,
sigma_yaw_deg,phase`` followed by ``heading_deg`` (navigation heading, clockwise
from north, for people) and, when a navigation filter ran with
``continue_navigation`` (``kf``, ``vbakf``, ``mvbakf``, ``ukf``), :data:`NAV_COLUMNS`:
latitude, longitude (deg), height (m) and ENU velocity (m/s). One row per output
epoch; the last row is the final result. Unknown values (waiting/coarse phases) are
written as ``nan``.
"""
import csv

import numpy as np

from ..nav.frames import yaw_to_heading
from .fixed_text import format_table

COLUMNS = ('t', 'qx', 'qy', 'qz', 'qw', 'roll_deg', 'pitch_deg', 'yaw_deg',
           'sigma_roll_deg', 'sigma_pitch_deg', 'sigma_yaw_deg', 'phase', 'heading_deg')
NAV_COLUMNS = ('lat_deg', 'lon_deg', 'h_m', 've_mps', 'vn_mps', 'vu_mps')


def write_csv(path, out, every=1):
    """Write an :class:`~sins_align_ros.align.pipeline.Output` to ``path``.

    ``every`` keeps one row in ``every`` (the last row is always written).
    """
    n = len(out.t)
    idx = np.arange(0, n, max(1, int(every)))
    if n and idx[-1] != n - 1:
        idx = np.append(idx, n - 1)
    eul = np.degrees(out.euler[idx])
    sig = np.degrees(out.sigma[idx])
    head = np.degrees(yaw_to_heading(out.euler[idx, 2]))
    nav = None
    if out.nav is not None:
        nav = out.nav[idx].copy()
        nav[:, :2] = np.degrees(nav[:, :2])
    cols = [out.t[idx], *out.q[idx].T, *eul.T, *sig.T, head]
    decimals = [9] + [12] * 4 + [9] * 7
    if nav is not None:
        cols += [nav[:, 0], nav[:, 1], *nav[:, 2:].T]
        decimals += [10, 10] + [4] * 4
    text = format_table(np.column_stack(cols), decimals, np.asarray(out.phase)[idx],
                        text_col=COLUMNS.index('phase'))
    with open(path, 'wb') as f:
        f.write((','.join(COLUMNS + (NAV_COLUMNS if nav is not None else ())) + '\r\n')
                .encode('ascii'))
        f.write(text)


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

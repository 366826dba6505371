"""Errors of a pipeline output against the truth of its data.

Conventions: the attitude error ``phi`` is the misalignment about the ENU axes
(:func:`~sins_align_ros.nav.frames.attitude_error` of estimate and truth, rad); the
Euler error is estimate minus truth, REP-103 roll / pitch / yaw with the wrap
removed (rad); NEES is ``phi' P_phi^-1 phi`` with the reported misalignment
covariance (3 degrees of freedom: 3 on average for a consistent filter).
"""
from dataclasses import dataclass

import numpy as np

from ..nav import earth
from ..nav.frames import attitude_error, euler_error, euler_to_dcm, quat_to_dcm
from ..units import DEG


def truth_rows(t_truth, t):
    """Index of the truth sample at each output stamp ``t`` (the sample ending at it)."""
    return np.clip(np.searchsorted(t_truth, np.asarray(t) - 1e-9), 0, len(t_truth) - 1)


def nees(phi, P_phi):
    """Normalised estimation error squared of a misalignment ``phi`` (3,), covariance (3, 3)."""
    return float(phi @ np.linalg.solve(P_phi, phi))


def attitude_errors(out, truth_euler, rows):
    """ENU misalignment (len(rows), 3) of output rows ``rows``; NaN where the attitude is unknown.

    ``truth_euler`` (N, 3): the truth at every output row.
    """
    rows = np.asarray(rows)
    ok = np.isfinite(out.q[rows, 3])
    phi = np.full((len(rows), 3), np.nan)
    good = rows[ok]
    phi[ok] = attitude_error(quat_to_dcm(out.q[good]), euler_to_dcm(truth_euler[good]))
    return phi


@dataclass
class FinalError:
    """Error of one output row against the truth (rad), and how the filter saw it.

    ``phi`` (3,) ENU misalignment; ``euler`` (3,) Euler error (roll, pitch, yaw);
    ``sigma`` (3,) reported 1-sigma of the Euler angles; ``nees`` of ``phi``. All NaN
    when the attitude is unknown (``known`` False).
    """

    phi: np.ndarray
    euler: np.ndarray
    sigma: np.ndarray
    nees: float

    @property
    def known(self):
        """Tell whether the row has an attitude."""
        return bool(np.all(np.isfinite(self.phi)))


def final_error(out, truth_euler, row=-1):
    """:class:`FinalError` of output row ``row`` against ``truth_euler`` (3,) at that row."""
    if not np.isfinite(out.q[row, 3]):
        nan = np.full(3, np.nan)
        return FinalError(nan, nan.copy(), nan.copy(), float('nan'))
    phi = attitude_error(quat_to_dcm(out.q[row]), euler_to_dcm(truth_euler))
    return FinalError(phi, euler_error(out.euler[row], truth_euler), out.sigma[row],
                      nees(phi, out.P_phi[row]))


def navigation_rmse(out, imu, t_from, track=None, rate_hz=100.0):
    """RMSE of attitude, position and velocity from ``t_from`` on, at 1 Hz.

    ``imu``: the truth at every output row (``euler``, ``v_n``, ``pos``), sampled at
    ``rate_hz``. Returns a dict: ``att`` (3,) Euler RMSE in deg per axis; ``pos`` 3-D
    and ``pos_h`` horizontal position RMSE (m); ``vel`` 3-D velocity RMSE (m/s). The
    position and velocity are the navigation solution's (``out.nav``); without one
    (an alignment-only filter) the position of ``track``, rows ``(t, lat, lon, h)``
    recorded while feeding, and no velocity (NaN).
    """
    step = int(rate_hz)
    k = np.arange(int(t_from * rate_hz), len(out.t), step)
    k = k[np.isfinite(out.q[k, 0])]
    e = euler_error(out.euler[k], imu.euler[k])
    res = {'att': np.sqrt(np.mean(e ** 2, axis=0)) / DEG}
    if out.nav is not None:
        nav = out.nav[k]
        ok = np.isfinite(nav[:, 0])
        truth = imu.pos[k][ok]
        d = earth.local_offset_m(truth[:, 0], truth[:, 1], truth[:, 2], nav[ok, 0],
                                 nav[ok, 1], nav[ok, 2])
        dv = nav[ok, 3:] - imu.v_n[k][ok]
        res['vel'] = float(np.sqrt(np.mean(np.sum(dv ** 2, axis=1))))
    else:
        tr = np.array([r for r in track if r[0] >= t_from])
        idx = np.clip(np.searchsorted(imu.t, tr[:, 0]), 0, len(imu.t) - 1)
        truth = imu.pos[idx]
        d = earth.local_offset_m(truth[:, 0], truth[:, 1], truth[:, 2], tr[:, 1], tr[:, 2],
                                 tr[:, 3])
        res['vel'] = float('nan')
    res['pos'] = float(np.sqrt(np.mean(np.sum(d ** 2, axis=1))))
    res['pos_h'] = float(np.sqrt(np.mean(np.sum(d[:, :2] ** 2, axis=1))))
    return res

"""Fault injection: a simulated run as columns of messages, corrupted on purpose.

:class:`MessageStream` holds what a driver would publish for a
:class:`~sins_align_ros.sim.scenario.SimBlock`: IMU rate samples (mean rate and
specific force over each interval, stamped at its end) and GNSS fixes and
velocities, each with the time it is *published* (``t_pub``, the original
stamp) and the stamp it *carries* (``t``). :func:`inject` applies one named
fault of :data:`FAULTS` over a window of publication time; the ROS layer
(:mod:`sins_align_ros.ros.playback`) turns the columns into messages. Used by
the fault-injection tests and the soak benchmark. No ROS here.
"""
import math

import numpy as np

from ..nav import earth

#: the faults :func:`inject` knows, with what each does inside its window
FAULTS = {
    'imu_nan': 'angular velocity x is NaN',
    'imu_inf': 'specific force z is +Inf',
    'imu_repeated': 'every sample is published twice (repeated stamps, zero dt)',
    'imu_out_of_order': 'the stamps of consecutive pairs are swapped (negative dt)',
    'imu_dropped': 'samples are missing (a gap shorter than max_gap: bridged)',
    'imu_gap': 'no samples (a gap longer than max_gap)',
    'imu_rate_change': 'every other sample is dropped from the window start on (rate halves)',
    'imu_saturated': 'angular velocity x sits at the sensor range',
    'imu_wrong_frame': "frame_id is 'wrong_link'",
    'imu_missing_field': 'angular velocity covariance[0] is -1 (field not provided)',
    'clock_back': 'every stamp from the window start on is `size` s earlier (a looping bag)',
    'clock_forward': 'every stamp from the window start on is `size` s later',
    'gnss_no_fix': 'status NO_FIX with NaN position',
    'gnss_unknown_status': 'status STATUS_UNKNOWN (-2)',
    'gnss_zero_cov': 'reported position variances are zero (known covariance type)',
    'gnss_absurd_cov': 'reported position sigma is 1e6 m',
    'gnss_jump': 'position jumps by `size` m north from the window start on (and stays)',
    'gnss_outliers': 'positions are `size` m off to the north-east',
    'gnss_outage': 'no GNSS messages',
}


class MessageStream:
    """Columns of IMU and GNSS messages of a simulated block (see the module docstring).

    ``imu``: dict of ``t_pub``, ``t`` (N,), ``w`` (N, 3) rad/s, ``f`` (N, 3) m/s^2,
    ``frame`` (N,) object, ``missing`` (N,) bool. ``gnss``: dict of ``t_pub``, ``t``
    (M,), ``status`` (M,) int, ``lat_deg``, ``lon_deg``, ``h`` (M,), ``pos_var`` (M, 2)
    m^2 east/north, ``vel`` (M, 3) m/s ENU, ``vel_var`` (M, 2), ``has_vel`` (M,) bool.
    ``truth``: the block's IMU chunk (for the attitude at any original time).
    """

    def __init__(self, block, imu_frame='imu_link'):
        imu = block.imu
        dts = np.diff(np.concatenate([[imu.t[0] - (imu.t[1] - imu.t[0])], imu.t]))
        n = len(imu.t)
        self.imu = {'t_pub': imu.t.copy(), 't': imu.t.copy(), 'w': imu.dtheta / dts[:, None],
                    'f': imu.dv / dts[:, None], 'frame': np.full(n, imu_frame, dtype=object),
                    'missing': np.zeros(n, dtype=bool)}
        g = block.gnss
        if g is None:
            m = 0
            self.gnss = {'t_pub': np.zeros(0), 't': np.zeros(0), 'status': np.zeros(0, int),
                         'lat_deg': np.zeros(0), 'lon_deg': np.zeros(0), 'h': np.zeros(0),
                         'pos_var': np.zeros((0, 2)), 'vel': np.zeros((0, 3)),
                         'vel_var': np.zeros((0, 2)), 'has_vel': np.zeros(0, bool)}
        else:
            m = len(g.t)
            fix = np.asarray(g.fix, dtype=bool)
            self.gnss = {'t_pub': g.t.copy(), 't': g.t.copy(),
                         'status': np.where(fix, 0, -1),
                         'lat_deg': np.where(fix, np.degrees(g.lat), np.nan),
                         'lon_deg': np.where(fix, np.degrees(g.lon), np.nan),
                         'h': np.where(fix, g.h, np.nan),
                         'pos_var': np.tile(np.asarray(g.pos_cov, float)[:2], (m, 1)),
                         'vel': (np.full((m, 3), np.nan) if g.v_n is None
                                 else np.asarray(g.v_n, float).copy()),
                         'vel_var': np.tile(np.asarray(g.vel_cov if g.v_n is not None
                                                       else (np.nan,) * 3, float)[:2], (m, 1)),
                         'has_vel': fix & (g.v_n is not None)}
        self.truth = imu

    def copy(self):
        """Return an independent copy of the columns (the truth is shared, read-only)."""
        out = MessageStream.__new__(MessageStream)
        out.imu = {k: v.copy() for k, v in self.imu.items()}
        out.gnss = {k: v.copy() for k, v in self.gnss.items()}
        out.truth = self.truth
        return out

    def window(self, kind, t0, t1):
        """Boolean mask of the ``kind`` ('imu' or 'gnss') messages published in [t0, t1)."""
        tp = getattr(self, kind)['t_pub']
        return (tp >= t0) & (tp < t1)

    def _keep(self, kind, keep):
        cols = getattr(self, kind)
        for k in cols:
            cols[k] = cols[k][keep]

    def _repeat(self, kind, counts):
        cols = getattr(self, kind)
        for k in cols:
            cols[k] = np.repeat(cols[k], counts, axis=0)

    def events(self, t0=-np.inf, t1=np.inf):
        """``(kind, index)`` of the messages published in [t0, t1), in publication order.

        At equal publication times GNSS comes first, as
        :func:`~sins_align_ros.eval.feed.feed_arrays` gives it.
        """
        ti = self.imu['t_pub']
        tg = self.gnss['t_pub']
        ii = np.flatnonzero((ti >= t0) & (ti < t1))
        gi = np.flatnonzero((tg >= t0) & (tg < t1))
        keys = np.concatenate([ti[ii], tg[gi]])
        kinds = np.concatenate([np.ones(len(ii), int), np.zeros(len(gi), int)])
        idx = np.concatenate([ii, gi])
        order = np.lexsort((kinds, keys))
        return [('imu' if kinds[o] else 'gnss', int(idx[o])) for o in order]

    def truth_euler(self, t):
        """Truth REP-103 Euler angles (3,) at the sample nearest original time ``t``."""
        k = int(np.clip(np.searchsorted(self.truth.t, t), 0, len(self.truth.t) - 1))
        return self.truth.euler[k]


def inject(stream, fault, t0, t1, size=None, gyro_range=None):
    """Apply ``fault`` (a key of :data:`FAULTS`) to ``stream`` for publication times [t0, t1).

    ``size``: the clock jump (s) or the GNSS jump / outlier size (m); defaults 30 s
    and 100 m. ``gyro_range`` (rad/s) for ``imu_saturated`` (default 2000 deg/s).
    Returns the stream.
    """
    if fault not in FAULTS:
        raise ValueError(f'unknown fault {fault!r}; known: {", ".join(FAULTS)}')
    imu, gnss = stream.imu, stream.gnss
    mi = stream.window('imu', t0, t1)
    mg = stream.window('gnss', t0, t1)
    if fault == 'imu_nan':
        imu['w'][mi, 0] = np.nan
    elif fault == 'imu_inf':
        imu['f'][mi, 2] = np.inf
    elif fault == 'imu_repeated':
        stream._repeat('imu', np.where(mi, 2, 1))
    elif fault == 'imu_out_of_order':
        k = np.flatnonzero(mi)
        k = k[: len(k) // 2 * 2].reshape(-1, 2)
        imu['t'][k[:, 0]], imu['t'][k[:, 1]] = imu['t'][k[:, 1]].copy(), imu['t'][k[:, 0]].copy()
    elif fault in ('imu_dropped', 'imu_gap'):
        stream._keep('imu', ~mi)
    elif fault == 'imu_rate_change':
        after = imu['t_pub'] >= t0
        k = np.cumsum(after)
        stream._keep('imu', ~after | (k % 2 == 0))
    elif fault == 'imu_saturated':
        imu['w'][mi, 0] = gyro_range or math.radians(2000.0)
    elif fault == 'imu_wrong_frame':
        imu['frame'][mi] = 'wrong_link'
    elif fault == 'imu_missing_field':
        imu['missing'][mi] = True
    elif fault in ('clock_back', 'clock_forward'):
        d = (size or 30.0) * (-1.0 if fault == 'clock_back' else 1.0)
        imu['t'][imu['t_pub'] >= t0] += d
        gnss['t'][gnss['t_pub'] >= t0] += d
    elif fault == 'gnss_no_fix':
        gnss['status'][mg] = -1
        for k in ('lat_deg', 'lon_deg', 'h'):
            gnss[k][mg] = np.nan
        gnss['has_vel'][mg] = False
    elif fault == 'gnss_unknown_status':
        gnss['status'][mg] = -2
        gnss['has_vel'][mg] = False
    elif fault == 'gnss_zero_cov':
        gnss['pos_var'][mg] = 0.0
    elif fault == 'gnss_absurd_cov':
        gnss['pos_var'][mg] = 1e12
    elif fault in ('gnss_jump', 'gnss_outliers'):
        m = gnss['t_pub'] >= t0 if fault == 'gnss_jump' else mg
        d = size or 100.0
        east = 0.0 if fault == 'gnss_jump' else d / math.sqrt(2.0)
        north = d if fault == 'gnss_jump' else d / math.sqrt(2.0)
        lat = np.radians(gnss['lat_deg'][m])
        R_M, R_N = earth.radii(lat)
        gnss['lat_deg'][m] += np.degrees(north / (R_M + gnss['h'][m]))
        gnss['lon_deg'][m] += np.degrees(east / ((R_N + gnss['h'][m]) * np.cos(lat)))
    elif fault == 'gnss_outage':
        stream._keep('gnss', ~mg)
    return stream

"""What a GNSS-aided engine does to its filter's prior before the first epoch.

A mixin of :class:`~.aided.GnssAidedEngine` (:class:`PriorShaping`): the level
accelerometer bias held at rest with the heading unknown, and a cubature filter's heading
prior capped at :data:`HEADING_PRIOR_MAX` (its points within the circle), the coarse prior
put back at output; with the angle cap every covariance shares (:func:`cap_angles`).
"""
import math

import numpy as np

from ...units import UG
from .force import ANGLE_UNKNOWN_VAR

#: prior sigma of a held accelerometer bias state, m/s^2
#: (:meth:`PriorShaping.hold_level_accel_bias`)
ACCEL_BIAS_HOLD = UG
#: largest initial heading sigma a cubature filter is given, rad (:func:`capped_heading_prior`)
HEADING_PRIOR_MAX = math.radians(45.0)


def cap_angles(P, rows):
    """Return covariance ``P`` with no variance of angle ``rows`` above :data:`ANGLE_UNKNOWN_VAR`.

    A misalignment is never more uncertain than an angle anywhere in a circle: those
    rows and columns are scaled down to it, which keeps ``P`` positive semi-definite.
    """
    s = np.ones(len(P))
    s[rows] = np.sqrt(np.minimum(1.0, ANGLE_UNKNOWN_VAR / np.diag(P)[rows]))
    return P * np.outer(s, s)


def capped_heading_prior(P0, k):
    """Return ``(P0', var0)``: P0 (n, n) with the heading variance (row ``k``) at most the cap's.

    The coarse stage hands over a conservative heading bound, up to 90 deg for a gyro
    that cannot gyrocompass (``coarse_window.coarse_sigma``). A cubature filter puts its
    points at +-sqrt(n) sigma: 90 deg with 12-13 states puts them past +-310 deg, beyond
    the circle's wrap, where the cubature means and cross-covariances lose their meaning
    (seed 004's USV, low grade told its sensors: 10 of 10 runs silent-wrong, one 175
    deg off; seed 000's CKF on a moored ship with a tactical gyro told 10x too good:
    heading pulled from 0.7 deg to 50 deg off, ending 24 deg off under a 6.4 deg
    sigma). So the filter is given at most :data:`HEADING_PRIOR_MAX` (45 deg: points
    within +-162 deg with 13 states) and :meth:`~.aided.GnssAidedEngine.attitude_cov` puts the
    coarse prior back in information form. ``var0`` is the heading variance P0 had
    (rad^2) when it was above the cap, else None (P0 unchanged); the heading row and
    column are scaled together (correlations kept).
    """
    P0 = np.array(P0, dtype=float)
    var0 = float(P0[k, k])
    if var0 <= HEADING_PRIOR_MAX ** 2:
        return P0, None
    s = np.ones(len(P0))
    s[k] = HEADING_PRIOR_MAX / math.sqrt(var0)
    return P0 * np.outer(s, s), var0


class PriorShaping:
    """What an engine does to its filter's prior before the first epoch.

    A mixin of :class:`~.aided.GnssAidedEngine`, whose ``kf``, ``i_phi``, ``Qc`` and process-noise
    bookkeeping (``_Qc0``, ``_held``) it uses.
    """

    #: accelerometer-bias slice (body x, y, z) of the state, None without one
    i_nab = None
    #: the coarse heading variance (rad^2) when the filter was given a capped one
    #: (:meth:`cap_heading_prior`), else None
    heading_prior_var = None

    def hold_level_accel_bias(self):
        """Stop estimating the body x/y accelerometer bias: at rest with the heading unknown.

        At rest a level accelerometer bias and a tilt are one (seed 002 eq. 15); a filter
        that estimates the bias takes its wandering unknown heading for a rotation of the
        base and "separates" them wrongly (still MEMS IMU: north tilt 24-32' RMS against
        the bias's 6'; docs/coarse.md). The two states' prior is scaled to
        :data:`ACCEL_BIAS_HOLD` and their process noise zeroed, which leaves the bias in
        the tilt, published at no less than ``(a / g)^2`` (``FineStage.tilt_bound``).
        Call before the first epoch.
        """
        if self.i_nab is None:
            return
        k = np.arange(len(self.kf.x))[self.i_nab][:2]
        s = np.ones(len(self.kf.x))
        s[k] = ACCEL_BIAS_HOLD / np.sqrt(np.maximum(np.diag(self.kf.P)[k], ACCEL_BIAS_HOLD ** 2))
        self.kf.transform(np.diag(s))
        self.Qc = self.Qc.copy()
        self.Qc[k] = self._Qc0[k] = 0.0
        self._held[k] = True

    def cap_heading_prior(self, P0):
        """Return P0 with its heading variance capped (:func:`capped_heading_prior`).

        Families with cubature filters call this on their P0 before building the filter
        (``i_phi`` must be set); the coarse variance is kept for
        :meth:`~.aided.GnssAidedEngine.attitude_cov`.
        """
        k = np.arange(len(P0))[self.i_phi][2]
        P0, self.heading_prior_var = capped_heading_prior(P0, k)
        return P0

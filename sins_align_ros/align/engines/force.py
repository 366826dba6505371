"""Which horizontal specific force a GNSS-aided error model may use.

Used by the navigation filters (:mod:`.navigation`), seed 000's CKF/ASCKF
(:mod:`.moving`) and seed 004's VBCKF/VBCH (:mod:`.robust`).

The heading error enters the velocity error only through the horizontal specific force
(``f_n x phi``; seed 000 eq. 3, seed 004 eq. 3, the navigation filters' F). The models
take the force the mechanization computed over the interval. On a straight,
unaccelerated leg the true horizontal force is zero and the computed one is the
filter's own tilt error times g plus the residual accelerometer bias: its product with
the heading error is a product of two errors, which a filter must not read as a
measurement of the heading (the inconsistency observability-constrained EKFs address,
Huang, Mourikis & Roumeliotis 2008). So the model is given the horizontal force only
when it is beyond :data:`FORCE_SIGNIFICANCE` sigma of what the filter's own tilt and
accelerometer-bias variances put on it; otherwise the heading sigma grows with the
gyro drift, as it should.

What this changed (measured, bench/results/integrity.md and variations*.md):

* The 15/18-state navigation filters (session 22): at 3 sigma a ship with a MEMS IMU
  turning at 1 deg/s (0.15 m/s^2 of centripetal force against 0.13 of tilt and bias)
  read the rotating accelerometer bias as heading, the vertical gyro drift estimate
  walked from +30 to -210 deg/h and the heading ended 15-30 deg off under a 4-6 deg
  sigma; 5 sigma cured it.
* Seed 000's CKF/ASCKF (here since session 23): on seed 000's ship with a MEMS IMU
  (0.01 m/s^2 of acceleration for minutes, 5 mg bias) the model read the bias's
  0.05 m/s^2 in the computed force as a force: the vertical drift's sigma fell from
  206 to 87 deg/h where the data cannot find it (a consistent 15-state filter's kept
  growing with the drift), the estimate walked 3.5 sigma from the truth and the heading
  ended 30 deg off under a 6 deg sigma (1 run in 10; the cell's heading RMS was twice
  its mean sigma).

* Seed 004's VBCKF/VBCH (since session 24): on the USV with a MEMS IMU, told the right
  model, one run in 10 of each had its heading 6-13 % of the time outside 3 sigma;
  with the rule, none (bench/results/integrity.md). (Tried before their feedback was
  corrected in session 23, the rule had traded those heading failures for tilt ones.)

A dropped force still carries the heading error into the velocity: ``P_psi |f_h|^2``
(m/s^2)^2 per horizontal axis, which the engine adds to the velocity process noise of
the interval (times ``T^2``), so the tilt does not take it (a USV in severe sea with a
MEMS IMU, 40 deg off in heading at the start of fine alignment, otherwise had its tilt
5 sigma off for a few seconds).
"""

import numpy as np

from ...nav import earth
from ..output import ANGLE_UNKNOWN_VAR  # noqa: F401  (the engines' name for it)

#: the horizontal specific force enters the error model only beyond this many sigma
FORCE_SIGNIFICANCE = 5.0
#: seconds a lost heading waits for a nonlinear acquisition with the horizontal force out
#: (:meth:`ForceModel._drop_horizontal_force`; :mod:`.navigation`, :mod:`.moving`)
LOST_WAIT_S = 60.0


def model_force(f_n, var_tilt, var_heading, var_bias, g):
    """Return ``(f_model, acc_var)``: the force (3,) the error model uses and the dropped part's.

    ``f_n`` (3,) the interval's mean computed specific force (ENU, m/s^2); ``var_tilt``
    the larger of the filter's two tilt variances (rad^2); ``var_heading`` its heading
    variance (rad^2); ``var_bias`` the largest accelerometer-bias variance of the state
    ((m/s^2)^2; 0 for a model without one, whose tilt variance carries the bias);
    ``g`` gravity (m/s^2). ``f_model`` is ``f_n``, or its vertical part alone when the
    horizontal part is within :data:`FORCE_SIGNIFICANCE` sigma of zero, the sigma being
    ``sqrt(g^2 var_tilt + var_bias)``; ``acc_var`` is then ``var_heading |f_h|^2``, the
    variance the heading error puts on each horizontal velocity rate, else 0.
    """
    f_n = np.asarray(f_n, dtype=float)
    s2 = g * g * var_tilt + var_bias
    h2 = float(f_n[0] ** 2 + f_n[1] ** 2)
    if h2 < FORCE_SIGNIFICANCE ** 2 * s2:
        return np.array([0.0, 0.0, f_n[2]]), float(var_heading) * h2
    return f_n, 0.0


class ForceModel:
    """The rule above for an engine: a mixin of :class:`~.aided.GnssAidedEngine`.

    Uses the engine's ``kf`` and its ``i_phi``, ``i_v`` and ``i_nab`` slices; keeps
    ``_unmodelled_acc_var`` for the interval's process noise.
    """

    #: acceleration variance (m/s^2)^2 the heading error puts on the horizontal velocity
    #: through a horizontal force the error model dropped (:meth:`_model_force`)
    _unmodelled_acc_var = 0.0

    def _model_force(self, f_n, lat, h, max_heading_var=np.inf):
        """Return the specific force (3,) the error model uses (:func:`model_force`).

        ``f_n`` (3,) the interval's mean force as the model takes it (ENU, m/s^2); the
        sigma is the filter's own tilt and accelerometer-bias variances'. A dropped
        force's heading variance (at most ``max_heading_var``, rad^2) is kept for
        :meth:`_force_noise`.
        """
        d = self.kf.P.diagonal()
        var_phi = d[self.i_phi].tolist()
        var_bias = 0.0 if self.i_nab is None else float(d[self.i_nab].max())
        f, self._unmodelled_acc_var = model_force(
            f_n, max(var_phi[0], var_phi[1]), min(var_phi[2], max_heading_var), var_bias,
            earth.gravity(lat, h))
        return f

    #: the heading is lost (an unknown angle): the horizontal force stays out of the model
    #: (:meth:`_drop_horizontal_force`) for at most :data:`LOST_WAIT_S`
    heading_lost = False
    #: seconds the heading has been lost
    lost_s = 0.0

    def _count_lost(self, T):
        """Add the interval's ``T`` s to the time the heading has been lost (0 once found)."""
        self.lost_s = self.lost_s + T if self.heading_lost else 0.0

    def _holding_lost(self):
        """Tell whether a lost heading still keeps the horizontal force out of the model."""
        return self.heading_lost and self.lost_s < LOST_WAIT_S

    def _drop_horizontal_force(self, f_n, lat, h, max_heading_var=np.inf):
        """Return the force (3,) the model uses while the heading is lost: the vertical alone.

        ``f_n`` (3,) the interval's mean specific force (ENU, m/s^2). A horizontal part
        beyond :data:`FORCE_SIGNIFICANCE` sigma of the filter's own tilt and
        accelerometer-bias errors is a real force (a turn, a braking): its velocity error,
        ``(C(psi) - I) f_h`` for a heading error ``psi`` anywhere in the circle, goes to the
        velocity process noise as an unknown angle's (``ANGLE_UNKNOWN_VAR |f_h|^2`` per
        axis, :meth:`_force_noise`) instead of into the heading and tilt rows (the lost
        heading of :mod:`.navigation` and :mod:`.moving`). One within it is the filter's
        own tilt error times g (a still base): dropped as :func:`model_force` drops it,
        with the heading variance taken at most ``max_heading_var`` (rad^2).
        """
        f_model = self._model_force(f_n, lat, h, max_heading_var=max_heading_var)
        f_n = np.asarray(f_n, dtype=float)
        if f_model[0] != 0.0 or f_model[1] != 0.0:
            self._unmodelled_acc_var = ANGLE_UNKNOWN_VAR * float(f_n[0] ** 2 + f_n[1] ** 2)
        return np.array([0.0, 0.0, f_n[2]])

    def _force_noise(self, T):
        """Velocity process noise (n, n) of a force dropped over ``T`` s, or None.

        The heading error's velocity error through the dropped force,
        ``P_psi |f_h|^2 T^2`` on each horizontal velocity (:mod:`.force`).
        """
        if self._unmodelled_acc_var <= 0.0:
            return None
        n = len(self.kf.x)
        k = np.arange(n)[self.i_v][:2]
        E = np.zeros((n, n))
        E[k, k] = self._unmodelled_acc_var * T * T
        return E

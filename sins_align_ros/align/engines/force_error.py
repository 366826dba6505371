"""The accelerometer scale-factor and misalignment errors as model error of the aided filters.

An accelerometer triad measures ``(I + S + M) f_b`` (issue 44): scale factors ``S``
(diagonal, 1-sigma ``s``) and axis misalignment ``M`` (off-diagonal, non-orthogonality,
1-sigma ``m`` per entry), random constants. No filter state models them. Their error
``(S + M) f_b`` has two parts:

* **Under gravity** (``f_b = C_n_b g``, nearly constant for a ground vehicle): a constant
  error in body axes, ``m g`` on each horizontal axis and ``s g`` on the vertical one. To
  the filters it is an accelerometer bias, which turns with the vehicle and is observed
  as one: ``accel_bias_ug`` must cover it (the self-check's MEMS class values do,
  :mod:`.self_check`; ``sim.presets.alignment_params`` folds a simulated IMU's
  misalignment into it). It is not added to the bias prior here: a wider bias prior
  also raises the threshold under which the horizontal force is dropped from the model
  (:mod:`.force`), and on the real fog_mems car (100 s, a consumer-class MEMS IMU the
  self-check gives 0.5 % misalignment) it took the heading from 2.15 to 4.88 deg RMS
  (published unknown at the end) with the fog parameters.
* **Under the vehicle's own acceleration** ``a_b = f_b - C_n_b g``: the error
  ``(S + M) a_b`` acts only while the vehicle brakes, accelerates or turns, exactly when
  the filter learns tilt and heading from the force: a vertical accelerometer that
  reads ``m`` of the forward force (entry ``M[z, x]``) makes a vertical velocity error
  that a tilt of ``m`` about the perpendicular axis would make, and the filter takes
  it for one (car_consumer seed 1004, kf told everything else right: north tilt 0.4
  deg off after one braking from 13.5 m/s, under a 0.16 deg sigma, 20 % of the 1-s rows
  outside 3 sigma; with the misalignment zeroed in the simulator none). Each filter
  interval adds to the velocity's process noise the growth of the coherent velocity
  error these constants make of the velocity the vehicle gained (``V``, body axes):

      error_j = s_j V_j + sum_{i != j} m_ji V_i,
      var_j(V) = s^2 V_j^2 + m^2 (|V|^2 - V_j^2)

  with ``V`` summed over the last :data:`FORCE_MEMORY_S` seconds (exponential
  forgetting, as :mod:`.rotation_error` does with the rotation: the velocity error is
  measured at every GNSS epoch, and one brake or turn's error is what matters) and the
  increment ``var(V + dV) - var(V)`` (never below zero) turned into the navigation frame
  with the interval's mean attitude. A braking from 13.5 m/s with ``m`` = 0.5 % adds
  ``(0.068 m/s)^2`` to the vertical velocity over the braking, most of it at its end,
  so the velocity innovations it causes are explained by the model error rather than
  by a tilt. As for the gyro, the velocity noise takes the sigmas
  :data:`~.rotation_error.COHERENCE_FACTOR` (2) times the told ones: white velocity
  noise still lets the filter read part of a coherent ramp as tilt (seed 1004 told
  right: 0.7 % of the rows outside 3 sigma at 1x, kf; 8 % for the ukf with node
  defaults; none at 2x or 3x). The bias prior takes the told sigmas as they are.

Not in the seeds (their IMUs are calibrated; seed 001/003's models have an
accelerometer bias only and seed 000's a tilt for it): the raw triads of an industrial MEMS AHRS
have scale factors of 0.3-0.5 % and axis misalignment of 0.5 % (issue 44), which the
seeds' models cannot represent. Here they are neither states nor estimated: the
filters are told how much error they can make, like the gyro's (:mod:`.rotation_error`).
"""

import numpy as np

from ...nav import earth
from .rotation_error import COHERENCE_FACTOR, coherent_increment, state_noise

#: seconds over which the velocity gained that the errors act on is remembered
FORCE_MEMORY_S = 10.0


class ForceError:
    """Mixin of :class:`~.aided.GnssAidedEngine`: the force-proportional model error.

    The engine calls :meth:`_force_error_noise` at every prediction, which reads the
    interval's sums (``sums.T``, ``sums.dv_sum`` and, when kept, ``sums.C_sum``) before
    they restart.
    """

    #: (scale factor, misalignment) 1-sigma, -; None: not modelled
    _force_sigma = None

    def set_force_error(self, scale, misalignment):
        """Model accelerometer scale factors ``scale`` and misalignment ``misalignment`` (1-sigma).

        The velocity noise takes :data:`~.rotation_error.COHERENCE_FACTOR` times the
        sigmas; the gravity part is left to ``accel_bias_ug`` (module docstring).
        """
        if scale <= 0.0 and misalignment <= 0.0:
            self._force_sigma = None
            return
        self._force_sigma = (COHERENCE_FACTOR * float(scale),
                             COHERENCE_FACTOR * float(misalignment))
        self._force_V = np.zeros(3)

    def _force_error_noise(self, T):
        """Velocity process noise (n, n) of the force since the last call (``T`` s), or None."""
        if self._force_sigma is None:
            return None
        s = self.sums
        if s.T <= 0.0:
            return None
        C = s.C_sum / s.T if s.C_sum is not None else self.mech.C_b_n
        g = earth.gravity(self.mech.lat, self.mech.h)
        # the vehicle's velocity gain over the interval (specific force less gravity's)
        dV_n = s.dv_sum + np.array([0.0, 0.0, -g]) * s.T
        dV_b = C.T @ dV_n
        self._force_V, inc = coherent_increment(self._force_V, dV_b, T, FORCE_MEMORY_S,
                                                *self._force_sigma)
        return state_noise(len(self.kf.x), self.i_v, C, inc)

"""Gyro scale factors as filter states of the GNSS-aided engines (issue 44).

A gyro triad measures ``(I + S) w`` (plus misalignment and bias): a scale-factor error
``s_j`` turns every rotation ``A_j`` about body axis ``j`` into an attitude error
``s_j A_j``. :mod:`.rotation_error` models it as process noise, which a turning vehicle
pays at every turn: 2 % told (times its coherence factor 2) puts 3.6 deg of heading
variance into a 90-deg junction turn, and the GNSS velocity has to find the heading
again after each (the RTK car of issue 44: heading sigma 0.6-1.1 deg at the end, held
up by the turns, not by the data). Here the three scale factors are random-constant
states instead, appended to the 15- or 18-state model (seed 001 eq. 2, seed 003 eq. 28)
when a scale factor is first modelled::

    x = [... seed model ... | ds_x ds_y ds_z]
    phi' = ... - C_b_n (eps + diag(w_b) ds),    ds' = 0

``w_b`` the body rate over the filter interval (the mechanized increments summed, over
its length), ``C_b_n`` its mean attitude: the same place in the model as the gyro
drift, scaled by the rate, so a turn with GNSS velocity makes ``ds_z`` observable
through the heading it leaves, and the heading no longer pays the whole error again at
each turn. The compensation divides each increment (after the drift) by ``1 + s``.
The unscented filter takes the term into its nonlinear drift
(:func:`~sins_align_ros.models.loosely_coupled.derivative18`, ``w_b``).

The seed 000 engine (:mod:`.moving`, ASCKF and CKF) has the same states: its drift is
resolved in the computed frame, so its transition adds ``C~ diag(w_b) ds`` to the drift
over the interval (both constant over it: exact in the nonlinear model), and the
square-root filter appends the states to its factor (``ASCKF.append_states``). Measured
(car:rtk, the plain MEMS grade with no scale factor, which the self-check models at 2 %,
ASCKF told right, 10 seeds): heading 30.7' RMS under a 35.1' sigma with the noise, 23.8'
under 28.4' with the states, as ``kf``'s 23.1' under 28.2'.

The prior 1-sigma is the told (or self-check-raised) scale factor times
:data:`SCALE_STATE_FACTOR`; a later raise (the motion check seeing turns) widens the
states' variance to it. Axis misalignment stays process noise (:mod:`.rotation_error`):
six more states that a car turning about one axis cannot observe.

The states replace the noise only once the heading is known to
:data:`HEADING_MAX_DEG` (1-sigma) and the filter measures GNSS velocity: a turn observes
the scale factor through the heading error it leaves (2 % of 90 deg: 1.8 deg), which a
heading known to tens of degrees cannot show, and which positions alone (a consumer
receiver's, correlated over tens of seconds) show too weakly to tell it from their own
errors. Until then the noise carries the scale factors. Measured with raw AHRS triads and
node defaults: robot_skid with a position-only receiver (heading declared unknown all
run, 4 seeds), states from the first turn: the UKF had 3 runs silent-wrong in tilt
instead of 1; the car with a position-only receiver (6 seeds), states once the heading
was known: 2 runs silent-wrong in heading instead of 1 (2-3 deg off under 0.6 deg).

Not in the seeds (their IMUs are calibrated).
"""
import math

import numpy as np

from .rotation_error import COHERENCE_FACTOR

#: prior 1-sigma of the scale-factor states per told 1-sigma
SCALE_STATE_FACTOR = 1.0
#: heading 1-sigma (deg) below which the scale factors become states (module docstring)
HEADING_MAX_DEG = 2.0
HEADING_MAX_VAR = math.radians(HEADING_MAX_DEG) ** 2


class GyroScaleStates:
    """Mixin of the GNSS-aided engines: the scale-factor states.

    Of :class:`~.navigation.IntegratedNavigation` and :class:`~.moving.MovingBaseAlignment`.
    Uses the engine's ``kf``, ``n``, ``i_phi``, ``Qc``, ``_Qc0``, ``_held`` and the
    interval's body rotation ``_rot`` (:class:`~.rotation_error.RotationError`); the engine
    calls :meth:`_scale_states_due` at each interval's end, :meth:`_compensate_scale` on its
    increments and :meth:`_feed_back_scale` in its feedback, and sets ``velocity_measured``.
    """

    #: slice of the scale-factor states in the state vector; None: not modelled
    i_sf = None
    #: the scale factors compensated (3,), and the prior 1-sigma the states were given
    sf = np.zeros(3)
    sf_sigma = 0.0
    #: the scale factor (1-sigma) modelled, as states or still as noise
    sf_wanted = 0.0
    #: the last GNSS epoch measured velocity (set by the engine's measurement)
    velocity_measured = False

    def _take_scale_states(self, scale):
        """Model gyro scale factors of 1-sigma ``scale`` (-) as states: append or widen them.

        Returns False (the noise keeps them) while the heading is not known to
        :data:`HEADING_MAX_DEG` and the states are not there yet.
        """
        self.sf_wanted = max(self.sf_wanted, float(scale))
        sigma = SCALE_STATE_FACTOR * self.sf_wanted
        if self.i_sf is None:
            if not self._scale_observable():
                return False
            self._append_scale_states(sigma * sigma)
        elif sigma > self.sf_sigma:
            k = np.arange(self.n)[self.i_sf]
            P = self.kf.P.copy()
            P[k, k] += sigma * sigma - self.sf_sigma ** 2
            self.kf.P = P
        self.sf_sigma = max(self.sf_sigma, sigma)
        return True

    def _scale_states_due(self):
        """Move the scale factors from the noise into states once the heading is known.

        Called at the end of each filter interval.
        """
        if self.i_sf is None and self.sf_wanted > 0.0 and self._scale_observable():
            mis = 0.0 if self._rot_sigma is None else self._rot_sigma[1] / COHERENCE_FACTOR
            self.set_rotation_error(self.sf_wanted, mis)

    def _scale_observable(self):
        """Tell whether turns show the scale factors: heading known, GNSS velocity measured."""
        k = np.arange(self.n)[self.i_phi][2]
        return self.velocity_measured and self.kf.P[k, k] <= HEADING_MAX_VAR

    def _counts_rotation(self):
        return self.i_sf is not None

    def _append_scale_states(self, var):
        """Grow the state by three random constants of variance ``var`` (zero mean).

        The filter appends them (:meth:`~.process_noise.ProcessNoise._append_states`,
        held constant). The states are appended at an
        interval's end, after the epoch's update and before its feedback, so the estimate
        is kept and grows by zeros: the epoch's correction is then fed back as every other
        epoch's. (Until session 37 the navigation engine started the whole state from zero
        here, dropping that epoch's correction while P kept the update's shrink:
        ``mvbakf_car``'s heading moved by up to 1.3 deg when that was mended.)
        """
        self.i_sf = self._append_states(np.full(3, var), np.zeros(3))
        self.sf = np.zeros(3)
        self._turn_scale_sigma = None     # the states carry it now (:meth:`set_turn_scale`)

    def _interval_rate(self, T):
        """Mean body rate (3,) over the interval of ``T`` s (rad/s)."""
        return self._rot / T

    def _scale_columns(self, F, C, w_b):
        """Put ``-C diag(w_b)`` into the attitude rows of the scale-factor columns of ``F``."""
        F[0:3, self.i_sf] = -C * w_b

    def _compensate_scale(self, dtheta):
        """Divide increments ``dtheta`` ((3,) or (N, 3)) by ``1 + s`` of the estimate.

        The estimate of the states, or the up scale factor measured from turns
        (:meth:`set_turn_scale`).
        """
        if self.i_sf is None and not self.sf[2]:
            return dtheta
        return dtheta / (1.0 + self.sf)

    def take_turn(self):
        """Return the rotation since the last call for :mod:`..stages.turn_scale`, or None.

        Returns ``(A, eps_applied, eps, var_eps, q_eps, prior_var)``: the increments'
        rotation about the local vertical (rad, as compensated: the drift where the engine
        takes it off, then :attr:`sf`), the vertical drift they were compensated by (rad/s),
        the engine's whole estimate of the vertical drift (rad/s: with what its filter still
        carries), that estimate's variance (rad^2/s^2) and its random walk's density
        (rad^2/s^3), and the scale factor's told 1-sigma squared. None (the rotation
        dropped) while the states carry the scale factors, while the GNSS velocity is
        measured (the states' domain, once the heading is known) and when no scale factor
        is modelled.
        """
        A, self._turn = self._turn, 0.0
        if self.i_sf is not None or self.velocity_measured or not self.sf_wanted > 0.0:
            return None
        C = self.mech.C_b_n
        h = np.zeros(len(self.kf.x))
        self._drift_row(h, C)
        applied = float(C[2] @ self._rate_compensation())
        return (A, applied, applied + float(h @ self.kf.x), float(h @ self.kf.P @ h),
                float((h * h) @ np.asarray(self.Qc, dtype=float)),
                (SCALE_STATE_FACTOR * self.sf_wanted) ** 2)

    def set_turn_scale(self, scale, sigma):
        """Compensate the z gyro's scale factor ``scale`` measured from turns, 1-sigma ``sigma``.

        The noise (:mod:`.rotation_error`) then takes ``sigma`` about the body's z axis;
        ``sigma`` None gives the told model back (no compensation). Returns False (nothing
        done) once the scale factors are states.
        """
        if self.i_sf is not None:
            return False
        self.sf = np.array([0.0, 0.0, float(scale) if sigma is not None else 0.0])
        self._turn_scale_sigma = None if sigma is None else float(sigma)
        return True

    def _feed_back_scale(self, x):
        """Move the scale-factor estimate of state ``x`` into the compensation."""
        if self.i_sf is not None:
            self.sf = self.sf + x[self.i_sf]

    def _heading_floor(self, P):
        """Return P (3, 3) with its heading variance at least the accelerometer misalignment's.

        Both engines apply it to the published attitude covariance
        (``IntegratedNavigation.attitude_cov``, ``MovingBaseAlignment.attitude_cov``); P is
        returned as it is until the scale factors are states.

        With the gyro scale factors as states (:mod:`.gyro_scale`) the heading is no longer
        held up by their noise at every turn, and it comes from the GNSS velocity in the
        vehicle's accelerations, where an accelerometer axis misalignment ``m`` turns a
        forward acceleration into a sideways one: a heading error of ``m`` rad, the same
        constant at every braking, which the force-proportional noise (:mod:`.force_error`)
        lets the filter average down as if it were white. Measured (car:rtk, raw AHRS triads
        told right, 10 seeds, m = 0.5 %): heading sigma 14' at the end, and one run 30-50'
        off under 11-18' for 4 min. So the published heading variance is at least ``m^2``
        (the told misalignment; row and column scaled, P stays semi-definite). A heading
        measured directly (an external heading, a GNSS compass's 0.1 deg) does not come from
        the accelerations: once a heading fix better than the floor has been used, there is
        none (a GNSS compass of 0.2 deg at 1 Hz, seed 003's car: 0.2 deg held at the fix's
        own sigma otherwise, where the filter averaging its fixes reaches 0.1).
        """
        if self.i_sf is None or self._force_sigma is None:
            return P
        floor = (self._force_sigma[1] / COHERENCE_FACTOR) ** 2
        if not 0.0 < P[2, 2] < floor or self.min_heading_fix_var < floor:
            return P
        s = np.ones(3)
        s[2] = math.sqrt(floor / P[2, 2])
        return P * np.outer(s, s)

    def scale_status(self):
        """Diagnostics figures of the states (empty when not modelled)."""
        if self.i_sf is None:
            return {}
        sd = np.sqrt(np.diag(self.kf.P)[self.i_sf])
        return {'gyro_scale_factor_ppm': [float(v) for v in self.sf * 1e6],
                'gyro_scale_factor_sigma_ppm': [float(v) for v in sd * 1e6]}

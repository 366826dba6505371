"""The stationary engine on a base that moves: coasting on the gyros, then resuming.

A mixin of :class:`~.stationary.StationaryEngine` (:class:`StillCoast`). When the rest
watch (:class:`~.still_watch.StillWatch`) finds the base moving, the zero-velocity filter
stops: the last seconds' feedbacks are undone and the attitude is integrated freely with
a growing covariance (:meth:`StillCoast.start_coast`, :class:`~.still_watch.Coast`); an
external heading still updates it (:meth:`StillCoast._coast_heading`). Once the IMU has
shown rest again, the filter resumes from the coasting attitude
(:meth:`StillCoast.resume`), with the variances an unseen cruise could add
(:func:`~.still_watch.cruise_floor`). Not from a seed: seed 002 assumes a base at rest.
"""
import numpy as np

from ..inputs.heading import LINEAR_MAX, take_heading
from .heading_update import gated_yaw_update
from .still_watch import Coast, cruise_floor
from ...nav.frames import rotvec_to_dcm


class StillCoast:
    """Coast and resume of the stationary engine (a mixin; module docstring).

    Uses the engine's ``mech``, ``model``, ``noise``, ``lat``, ``g``, ``period``,
    ``v0_sigma``, ``heading_gate``, the filter's ``x``, ``P``, the recent epochs
    ``_recent`` and ``_attitude_cov``; sets ``coast``, ``cruise_floor`` and ``last_gated``.
    """

    #: free gyro integration while the base moves (:class:`~.still_watch.Coast`), or None
    coast = None
    #: variances (3,) added to the misalignment's after the base moved and came to rest
    #: (:meth:`resume`)
    cruise_floor = None

    def start_coast(self, seconds_back, gyro_bias, heading_sigma):
        """Stop the zero-velocity filter: free gyro integration from ``seconds_back`` ago.

        The feedbacks of the epochs of the last ``seconds_back`` seconds (at most
        :data:`~.still_watch.ROLLBACK_S`) are undone on the attitude (the feedback is a
        rotation on the navigation side; the Earth rate turned the attitude by less than
        1e-3 rad in between, so the order of the two is immaterial), and the covariance
        restarts from the attitude covariance before them, grown over the time since
        (:class:`~.still_watch.Coast`; ``gyro_bias`` rad/s, ``heading_sigma`` rad). The
        velocity corrections of those epochs are undone as well, so that the integrated
        velocity counts the motion from its start. Returns the seconds actually undone.
        """
        n = min(len(self._recent) - 1, int(round(seconds_back / self.period)))
        recent = list(self._recent)
        C, dvel = self.mech.C_b_n, np.zeros(3)
        for _, phi, dv in reversed(recent[len(recent) - n:]):
            C = rotvec_to_dcm(-phi) @ C
            dvel -= dv
        self.mech.C_b_n = C
        self.mech.correct_velocity(dvel)
        P_before = recent[len(recent) - 1 - n][0]
        self.coast = Coast(self._attitude_cov(P_before), n * self.period, self.lat,
                           heading_sigma, gyro_bias, self.noise)
        self.last_gated = False
        return n * self.period

    def cruise_speed_bound(self):
        """Return the speed (m/s) the base may still have after coasting, or None if moving.

        None when the velocity integrated while coasting is not back to zero within
        3 :attr:`~.still_watch.Coast.v_sigma` (a base cruising at a constant velocity);
        else that velocity plus 3 sigma: what a base that shows rest may still cruise at.
        """
        c = self.coast
        speed = float(np.hypot(*self.mech.v_n[:2]))
        return None if speed > 3.0 * c.v_sigma else speed + 3.0 * c.v_sigma

    def resume(self, speed_bound):
        """Zero-velocity filtering again from the coasting attitude (the base shows rest).

        The velocity restarts at zero; the filter from its prior with the coasting
        misalignment covariance (its correlation with the biases is gone). The base may
        cruise at up to ``speed_bound`` m/s unseen (:meth:`cruise_speed_bound`): its
        Coriolis acceleration would tilt the zero-velocity solution and its transport rate
        turn the gyrocompass heading, so both are added to the attitude variances from now
        on (:func:`~.still_watch.cruise_floor`).
        """
        m = self.model
        P_phi = self.coast.P
        self.coast = None
        self.cruise_floor = cruise_floor(speed_bound, self.lat, self.g)
        self.mech.correct_velocity(self.mech.v_n)
        P = m.P0(self.v0_sigma, np.sqrt(np.diag(P_phi)), self.noise)
        P[np.ix_(m.i_phi, m.i_phi)] = P_phi
        self.x = np.zeros(m.n)
        self.P = P
        self._recent.clear()
        self._recent.append((P, np.zeros(3), np.zeros(3)))

    def _coast_heading(self, fix, yaw):
        """Apply :meth:`update_heading`'s yaw update to the coasting covariance."""
        c = self.coast
        if c.P[2, 2] > LINEAR_MAX ** 2:
            self.mech.C_b_n, c.P = take_heading(self.mech.C_b_n, c.P, 2, yaw, fix.var)
            return 'taken'
        upd = gated_yaw_update(self.heading_gate, c, np.zeros(3), c.P, np.arange(3),
                               self.mech.C_b_n, fix, yaw)
        if upd is None:
            return 'rejected'
        x, c.P = upd
        self.mech.C_b_n = rotvec_to_dcm(x) @ self.mech.C_b_n
        return 'used'

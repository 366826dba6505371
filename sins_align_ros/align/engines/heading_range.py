"""The navigation engine's heading: held in the linear model's range, lost, found, claimed.

A mixin of :class:`~.navigation.IntegratedNavigation` (:class:`HeadingRange`). Large
heading errors with a poor gyro (issue 21; not in the seeds, whose model assumes a
small misalignment and a tactical IMU). On seed 001's flight with a MEMS IMU (200 deg/h
gyro bias) the 15-state filters published 8-15 deg of heading sigma over a heading
54 deg off. Two causes, two remedies:

* Spurious heading information. The horizontal specific force enters the error model
  only when it is beyond 5 sigma of what the filter's own tilt and accelerometer
  variances put on it, and a dropped force's heading term joins the velocity process
  noise (:mod:`.force`, shared by every aided family; a MEMS ship turning at 1 deg/s
  otherwise read its rotating accelerometer bias as heading, 15-30 deg off under a
  4-6 deg sigma).
* A heading error beyond the small-angle range. The linear filters (``kf``, ``vbakf``,
  ``mvbakf``) hold the heading variance at :data:`HEADING_LINEAR_MAX_DEG` (1-sigma;
  sin and 1 - cos of a 3-sigma error stay within 10 % / 0.3 rad of the linear model)
  by scaling its row and column (P stays positive semi-definite); beyond that a
  linear update at the next turn would read a 100-deg error as a small one and corrupt
  tilt and gyro bias with it (the KF's tilt went 60 deg off). When the variance had to
  be held, the heading is lost to the linear model: at the next GNSS epoch with a
  velocity of at least ``track_min_speed_mps`` it is taken afresh from the GNSS track,
  as the coarse stage does (the vehicle's nose along its velocity; 1-sigma
  ``track_heading_sigma_deg``), a nonlinear re-acquisition that keeps position,
  velocity, tilt and sensor estimates. Where the filter has since found a heading
  better than the track's (its sigma below ``track_heading_sigma_deg``: manoeuvres did
  it) and the track agrees with it within 3 sigma, the filter's is kept and only the
  mark is cleared: a boat's track is off its heading by its crab and sway, and a mark
  left standing from the start had a USV in severe sea throw away a heading known to
  14' for a track 48 deg off, 220 s later. The UKF (``ukf``, seed 003) keeps the heading
  error nonlinear in its model instead (seed 004 eq. 3: its ``heading_cap`` is None) and
  keeps its own force.
* A lost heading is found again by a nonlinear acquisition only. While the heading is
  lost (held at the linear range, or handed over by the coarse stage beyond it: above
  :data:`HEADING_LINEAR_MAX_DEG` for ``kf``, above the UKF's 30-deg prior cap for
  ``ukf``) the error model is given the vertical specific force alone
  (:meth:`_drop_horizontal_force`); the horizontal force's velocity error is process noise
  of an unknown angle. The linear model would read the turns' accelerations in the GNSS
  velocity as heading information it cannot hold: a skid-steer robot at 1 m/s with
  Doppler velocity (robot:consumer, raw AHRS triads) started its fine stage 50-170 deg off
  (no track at 1 m/s, a coarse heading of an unknown angle), and within 8-12 s ``kf`` and
  ``ukf`` alike claimed 7-9 deg of sigma about it, their tilt was pulled 5-10 deg off
  under 0.8 deg in the turns, the vertical gyro drift estimate walked and the heading
  swept at 1-2 deg/s (4-8 silent-wrong runs of 10 per cell); the course heading aid,
  a bootstrap, never fed it since the heading looked found. The heading is found again
  by the GNSS track (above ``track_min_speed_mps``, below), a straight leg's course
  (:mod:`.course_heading`, taken directly) or an external heading taken directly. It
  waits for one at most :data:`~.force.LOST_WAIT_S` (two of the longest legs); a vehicle that
  offers none in that time is left to the linear model's own convergence, as before: a
  MEMS USV rolling in a seaway below the track speed (seed 004, no straight leg) had its
  heading found by it from 45 deg off (1-1.4 deg RMS at the end), and held lost it ended
  unknown, 55 deg off.
* The claim. The heading goes out with the filter's variance only while its 1-sigma is
  at most :data:`HEADING_CLAIM_MAX_DEG`, where the linearisation holds; above it the
  heading is published as unknown (variance pi^2/3, the fine stage's unknown angle),
  so a heading the model cannot represent is never claimed (:meth:`attitude_cov`).
"""
import math

import numpy as np

from ...models import loosely_coupled as lc
from ...nav.frames import dcm_to_euler, euler_to_dcm, wrap_pi
from .force import ANGLE_UNKNOWN_VAR

#: heading 1-sigma (deg) up to which the linear filters' small-angle model holds
HEADING_LINEAR_MAX_DEG = 15.0
#: heading 1-sigma (deg) above which the heading is published as unknown
HEADING_CLAIM_MAX_DEG = 10.0
HEADING_LINEAR_MAX_VAR = math.radians(HEADING_LINEAR_MAX_DEG) ** 2
HEADING_CLAIM_MAX_VAR = math.radians(HEADING_CLAIM_MAX_DEG) ** 2


class HeadingRange:
    """The heading rules of the module docstring, for an engine with ``kf``, ``mech``, ``n``.

    Needs ``heading_lost``, ``n_heading_held``, ``n_heading_reacquired``,
    ``track_heading_sigma``, ``track_min_speed`` (set by the engine) and
    ``_heading_floor`` (:mod:`.gyro_scale`).
    """

    #: the heading variance (rad^2) the linear model is held within; None: the model is
    #: nonlinear in the heading (the UKF) and holds nothing
    heading_cap = HEADING_LINEAR_MAX_VAR

    def _tilt_considered(self):
        """Return the consider mask (n,) of the tilt states (a lost heading, a real force).

        The velocity error ``(C(psi) - I) f_h`` of a heading error anywhere in the circle
        is one direction for as long as the force keeps it (a turn, a braking): the
        velocity process noise covers each epoch's share, but epoch after epoch the same
        drift reads as a tilt error (``g phi`` is one too). With RTK velocities the KF
        took it so: a skid-steer robot (robot:rtk, raw AHRS) had its tilt pulled 2.5-5 deg
        off under 0.6 deg within 10 s of the fine stage's start (3 of 5 runs silent-wrong).
        Over such intervals under way (the fix's velocity beyond 3 of its sigmas, see
        :meth:`~.navigation.IntegratedNavigation.measurement`; without GNSS velocity
        never) the tilt is a consider state (Schmidt): not corrected, its variance carried
        honestly; it is observed again once the force is gone or the heading found. Not
        from a seed.
        """
        mask = np.zeros(self.n, dtype=bool)
        mask[np.arange(self.n)[lc.I_PHI][:2]] = True
        return mask

    def _interval_ended_bound(self):
        """Hold a linear filter's heading variance within the model's range (module docstring)."""
        if self.heading_cap is None:
            return
        P = self.kf.P
        if P[2, 2] > self.heading_cap:
            s = np.ones(self.n)
            s[2] = math.sqrt(self.heading_cap / P[2, 2])
            self.kf.P = P * np.outer(s, s)
            self.n_heading_held += 1
            self.heading_lost = True

    def _reacquire_heading(self, fix):
        """Take the heading from the GNSS track of ``fix`` when it was lost (module docstring)."""
        if not self.heading_lost or fix is None or fix.v_n is None:
            return
        v = np.asarray(fix.v_n, dtype=float)
        if math.hypot(v[0], v[1]) < self.track_min_speed:
            return
        m = self.mech
        eul = dcm_to_euler(m.C_b_n)
        track = math.atan2(v[1], v[0])
        self.heading_lost = False
        var_track = self.track_heading_sigma ** 2
        var_psi = float(self.kf.P[2, 2])
        if var_psi < var_track and wrap_pi(track - eul[2]) ** 2 <= 9.0 * (var_psi + var_track):
            # the filter has since found a heading better than the track's, and the track
            # agrees with it (within crab and sway): keep the filter's
            return
        eul[2] = track
        m.C_b_n = euler_to_dcm(eul)
        P = self.kf.P.copy()
        P[2, :] = P[:, 2] = 0.0
        P[2, 2] = self.track_heading_sigma ** 2
        self.kf.P = P
        self.n_heading_reacquired += 1

    def _heading_taken(self):
        """Mark the heading found: an external heading was taken directly."""
        self.heading_lost = False

    def inflate(self, factor):
        """Inflate as every aided engine does, then hold the heading in the linear range."""
        super().inflate(factor)
        self._interval_ended_bound()

    def widen(self, var_phi, var_v):
        """Widen as every aided engine does, then hold the heading in the linear range."""
        super().widen(var_phi, var_v)
        self._interval_ended_bound()

    def attitude_cov(self):
        """Misalignment covariance about ENU (3, 3), rad^2; the heading unknown beyond the claim.

        While the filter's heading 1-sigma is above :data:`HEADING_CLAIM_MAX_DEG` the
        heading is published as an angle anywhere in the circle (variance pi^2/3, no
        cross terms; module docstring).
        """
        P = self.kf.P[self.i_phi, self.i_phi]
        if P[2, 2] > HEADING_CLAIM_MAX_VAR:
            P = P.copy()
            P[2, :2] = P[:2, 2] = 0.0
            P[2, 2] = ANGLE_UNKNOWN_VAR
        else:
            P = self._heading_floor(P)
        return P

    @property
    def heading_claimed(self):
        """Tell whether the heading is published with the filter's variance (not unknown)."""
        return bool(self.kf.P[2, 2] <= HEADING_CLAIM_MAX_VAR)

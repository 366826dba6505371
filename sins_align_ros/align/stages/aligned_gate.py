"""When a fine stage is ``aligned``: entered as soon as it is true, left only on a clear failure.

Issue 46. ``aligned`` tells a user (an autopilot, robot_localization's start-up) that the
attitude can be used. Waiting for the sigma to stop shrinking made it late (an aided
filter's heading sigma may keep falling for minutes), and leaving it at every test that
failed by a hair made it flicker (a MEMS car with RTK: 13 switches in 700 s, e.g. on
NIS/dof 1.68 against a bound of 1.66), so that anything waiting for it toggled too.

**Settled** (:class:`SettleTest`, every stage: the GNSS and heading updates of an aided
one, the zero-velocity epochs of a still-base one, whose convergence now only decides a
restage, :mod:`.convergence`). The attitude the filter's updates move is summed per ENU
axis, with its sign, over the last :data:`SETTLE_S` seconds and over the :data:`SETTLE_S`
seconds before; the estimate has settled once the stage has run twice :data:`SETTLE_S`
and the two sums differ by at most :data:`SETTLE_SIGMAS` times that axis's published
1-sigma. A filter still converging moves its attitude by less in each span than in the one
before; one that has converged moves it by noise, or at a steady rate where it compensates
an estimated drift at its epochs (seed 000's engine keeps the gyro drift in the filter, so
each update turns the attitude by the drift over the interval: on raw MEMS AHRS triads about
0.9 deg every 5 s, which a test on the sum itself never passed). Latched for the stage.

**Entered** at a filter epoch where the stage has settled and every condition holds: the
roll/pitch and heading 1-sigma within ``aligned_max_tilt_sigma_deg`` /
``aligned_max_heading_sigma_deg``, the last consistency test passed, no slow-error
finding (:meth:`~.fine_stage.FineStage._ready_reason`).

**Left** (:meth:`AlignedGate.leave_reason`):

* at once on a hard condition: the base moving without GNSS, a mounting doubt, the
  heading unobservable, a slow-error finding (the heading against the GNSS course); a
  divergence or a stopped input ends the stage itself;
* on a threshold only when the 1-sigma is above :data:`LEAVE_FACTOR` times it (a heading
  sigma that breathes between turns around the threshold does not toggle the phase; one
  that keeps growing on a long straight leg leaves 20 % later);
* on the consistency monitor only when its failure persists: two failed tests in a row,
  the second on the innovations after the first one's remedy
  (:attr:`~.consistency.ConsistencyMonitor.clearly_inconsistent`). A single failure has
  been answered by its remedy (the covariance or the measurement noise inflated) before
  the phase is decided, so the claim that stays ``aligned`` is the widened one.

Not from the seeds (they report convergence curves, not a phase).
"""
import bisect
import math

import numpy as np

from ..output import ANGLE_UNKNOWN_VAR

#: seconds of filter epochs over which the estimate must have settled
SETTLE_S = 5.0
#: the net correction over :data:`SETTLE_S` may reach this many published 1-sigma
SETTLE_SIGMAS = 1.0
#: ``aligned`` is left on a threshold only above this multiple of it
LEAVE_FACTOR = 1.2


def rotation_vector(C_before, C_after):
    """Return the small rotation (3,) rad about the navigation axes, ``C_before`` to ``C_after``.

    ``C_after = (I - [phi x]) C_before`` to first order: ``phi`` is the correction a filter
    update applied to the attitude (both (3, 3) body-to-navigation matrices).
    """
    D = np.asarray(C_before) @ np.asarray(C_after).T
    return 0.5 * np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0], D[1, 0] - D[0, 1]])


class SettleTest:
    """Whether a GNSS-aided stage's estimate has settled (module docstring)."""

    def __init__(self, t0, span_s=SETTLE_S, sigmas=SETTLE_SIGMAS):
        self.t0 = float(t0)
        self.span_s = float(span_s)
        self.sigmas = float(sigmas)
        # the stamps of the corrections and their running sums (3,) rad, and the sum of
        # those already forgotten: a span's net is a difference of two running sums
        self._t = []
        self._sums = []
        self._forgotten = np.zeros(3)

    def add(self, t, phi):
        """Record the correction ``phi`` (3,) rad an update applied at ``t``."""
        last = self._sums[-1] if self._sums else self._forgotten
        self._t.append(float(t))
        self._sums.append(last + np.asarray(phi, dtype=float))

    def _sum_to(self, t):
        k = bisect.bisect_right(self._t, t)
        return self._sums[k - 1] if k else self._forgotten

    def net(self, t):
        """Return the corrections (3,) rad of the :attr:`span_s` s up to ``t``, summed.

        (Stamps rise: corrections older than two spans before ``t`` are forgotten, in
        batches, their sum kept.)
        """
        k = bisect.bisect_right(self._t, t - 2.0 * self.span_s)
        if k > 256:
            self._forgotten = self._sums[k - 1]
            del self._t[:k], self._sums[:k]
        return self._sum_to(t) - self._sum_to(t - self.span_s)

    def settled(self, t, sigma):
        """Tell whether the estimate has settled by ``t``; ``sigma`` (3,) the published 1-sigma.

        An angle published as unknown (:data:`~..output.ANGLE_UNKNOWN_VAR`) is not tested.
        """
        if t - self.t0 < 2.0 * self.span_s:
            return False
        change = np.abs(self.net(t) - self.net(t - self.span_s))
        sigma = np.asarray(sigma, dtype=float)
        tested = sigma * sigma < ANGLE_UNKNOWN_VAR
        return bool(np.all(change[tested] <= self.sigmas * sigma[tested]))


class AlignedGate:
    """The user's thresholds with hysteresis (module docstring)."""

    def __init__(self, max_tilt, max_heading, leave_factor=LEAVE_FACTOR):
        self.max_tilt = float(max_tilt)
        self.max_heading = float(max_heading)
        self.leave_factor = float(leave_factor)
        #: aligned -> fine transitions of the stage
        self.n_left = 0

    def ready(self, tilt_sigma, heading_sigma):
        """Return ``(tilt_ready, heading_ready)``: the 1-sigma (rad) within the thresholds."""
        return tilt_sigma <= self.max_tilt, heading_sigma <= self.max_heading

    def leave_reason(self, tilt_sigma, heading_sigma, consistency):
        """Return why an ``aligned`` stage leaves it on its soft conditions ('' to stay).

        ``tilt_sigma``, ``heading_sigma`` (rad); ``consistency``: the stage's
        :class:`~.consistency.ConsistencyMonitor`.
        """
        why = []
        if consistency.clearly_inconsistent:
            why.append(f'innovations inconsistent (NIS/dof {consistency.ratio:.2f} > '
                       f'{consistency.bound:.2f}, {consistency.failed_in_row} test(s) in a '
                       f'row): {consistency.remedy}')
        f = self.leave_factor
        if tilt_sigma > f * self.max_tilt:
            why.append(f'tilt 1-sigma above {f:g} x {math.degrees(self.max_tilt):g} deg')
        if heading_sigma > f * self.max_heading:
            why.append(f'heading 1-sigma above {f:g} x {math.degrees(self.max_heading):g} deg')
        return ', '.join(why)

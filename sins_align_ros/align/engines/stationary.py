"""Stationary fine alignment (seed 002): zero-velocity Kalman filter with restaging.

The stationary mechanization with the model's equivalence operations (seed 002
Table 1) runs at IMU rate; every ``period`` seconds the zero-velocity Kalman filter
(:class:`~sins_align_ros.models.stationary.StationaryModel`: 12, 10 or 7 states) is
updated and its misalignment and velocity estimates are fed back into the
mechanization. When the heading uncertainty has converged the pipeline may
re-initialise the filter (:meth:`StationaryEngine.restage`): seed 002's closing
suggestion of staged re-initialisation, which removes the error that the first
transient leaves in the bias estimates.

We restage only where that error can matter (:func:`restage_helps`): the transient is
the linear model's neglect of the second-order terms of a large initial misalignment
(seed 002 sec. 4 starts from 10 deg). From a small one (a navigation-grade coarse
alignment leaves 0.5 deg) a restage only throws away the bias/heading correlation the
first stage learnt: the 10/12-state heading sigma went back from 3.4' to 29' at 270 s
on a still navigation-grade IMU (error 0.1-2'), and ``aligned`` came at 480 s instead
of 300 s.

Each zero-velocity epoch is gated: one whose innovation is beyond any still base's
(:data:`~.still_watch.P_FALSE`) is refused, so an acceleration is not turned into tilt;
the fine stage decides from the refusals and the innovations whether the base moves
(:mod:`.still_watch`) and may then make the engine coast (:mod:`.still_coast`: free gyro
integration with a growing covariance, the last seconds' feedbacks undone) until the base
has shown rest again.
"""
from collections import deque

import numpy as np

from ...filters import kf
from ...filters.chi2 import chi2_quantile
from .gnss_gate import GnssGate
from ..inputs.heading import (LINEAR_MAX, heading_update, take_heading, wrap, yaw_of,
                              yaw_row)
from .heading_update import gated_yaw_update
from .still_coast import StillCoast
from .still_watch import P_FALSE, ROLLBACK_S
from ...models.stationary import unobservable_variance
from ...nav import earth
from ...nav.frames import dcm_to_rotvec, rotvec_to_dcm
from ...nav.mechanization import StationaryStrapdown

#: the filter period is reached when the accumulated time is within this of it, s
_EPS_T = 1e-9
#: the smallest initial velocity 1-sigma (m/s) of the still-base filters
V0_SIGMA = 0.01
#: the initial misalignment counted, in sigmas, when judging the first stage's nonlinearity
_K_NONLINEAR = 3.0


def restage_helps(sigma_phi, lat, noise):
    """Whether re-initialising after the first stage can remove an error it leaves.

    The first stage's linear model neglects terms of order ``phi^2 / 2`` of the initial
    misalignment ``phi``; they go into the bias estimates. Counting ``phi`` at 3 sigma
    (``sigma_phi`` (3,), rad), a restage helps when that term exceeds the heading's own
    limit at rest, the 1-sigma the gyro bias leaves (``eps_E / (W cos L)``,
    :func:`~sins_align_ros.models.stationary.unobservable_variance` at latitude ``lat``
    for the :class:`NoiseSpec` ``noise``).
    """
    worst = _K_NONLINEAR * float(np.max(sigma_phi))
    return 0.5 * worst ** 2 > float(np.sqrt(unobservable_variance(lat, noise)[2]))


class StationaryEngine(StillCoast):
    """Mechanization + seed 002 filter on a still base; see the module docstring.

    It satisfies :class:`~.base.StillEngine`, the contract the fine stage steps it by.

    Parameters
    ----------
    model : StationaryModel
    noise : NoiseSpec
    C_b_n : ndarray (3, 3)
        Initial attitude, body FLU -> ENU.
    sigma_phi : ndarray (3,)
        Initial misalignment sigma, rad.
    position : ndarray (3,)
        Latitude, longitude (rad), height (m).
    zero_velocity_sigma : float or sequence (3,)
        Sigma of the zero-velocity measurement, m/s: one for every axis, or east, north,
        up (the vertical one is used by models that measure it).
    period : float
        Filter period, s.
    sigma_linear : ndarray (3,) or None
        The error the initial attitude may carry, rad, where it is smaller than
        ``sigma_phi`` (a coarse sigma without its floors, a reprocessing prior wider than
        the coarse attitude's error): it decides whether a restage helps. None:
        ``sigma_phi``.
    """

    navigates = False
    #: the pipeline may re-initialise this filter when it has converged
    restages = True

    def __init__(self, model, noise, C_b_n, sigma_phi, position, zero_velocity_sigma, period,
                 sigma_linear=None):
        lat, lon, h = position
        m = self.model = model
        self.noise = noise
        self.lat = lat
        self.mech = StationaryStrapdown(C_b_n, lat, lon, h, coriolis=m.mech.coriolis,
                                        hold_vertical=m.mech.hold_vertical)
        self.g = earth.gravity(lat, h)
        self.x = np.zeros(m.n)
        zv = np.broadcast_to(np.asarray(zero_velocity_sigma, dtype=float), (3,))
        #: the initial velocity's 1-sigma per measured axis (m/s): the base's own velocity
        #: at rest, the zero-velocity sigma, never below :data:`V0_SIGMA` (a heaving ship is
        #: anywhere in its heave's velocity when the stage starts; a 0.01 m/s claim there
        #: held the offset for tens of seconds, NIS 9 per epoch on ship_sway's heave)
        self.v0_sigma = np.maximum(V0_SIGMA, zv[m.meas])
        self.P = m.P0(self.v0_sigma, sigma_phi, noise)
        self.H = m.H()
        self.R = np.diag(zv[m.meas] ** 2)
        #: variances (3,) the model cannot see, added to the attitude covariance at output
        self.floor = m.attitude_floor(lat, noise)
        #: variances (3,) below which the 10/12-state misalignment is never reported
        self.bound = np.zeros(3) if m.name == 'reduced7' else unobservable_variance(lat, noise)
        self.period = float(period)
        #: the fine stage may restage this filter (a large initial misalignment)
        self.restage_helps = restage_helps(sigma_phi if sigma_linear is None else sigma_linear,
                                           lat, noise)
        self.since_update = 0.0
        #: the external heading's innovation gate (the factory sets the GNSS gate's figures)
        self.heading_gate = GnssGate(0.9999, sizes=(1,), name='heading')
        self.n_updates = 0
        self.last_nis = float('nan')
        self._disc_cache = {}
        #: a zero-velocity epoch with an NIS above this is refused (:mod:`.still_watch`)
        self.zv_gate = chi2_quantile(1.0 - P_FALSE, len(m.meas))
        #: the last epoch was refused; refused epochs so far
        self.last_gated = False
        self.n_gated = 0
        #: the misalignment (3,) rad the last epoch fed back (zero if it updated nothing):
        #: ``C = exp([phi x]) C~``, what the settle test sums (:mod:`...stages.aligned_gate`)
        self.last_correction = np.zeros(3)
        #: the covariance after each of the last epochs and the attitude correction it fed
        #: back (a rollback when the base is found moving), the start first
        self._recent = deque([(self.P, np.zeros(3), np.zeros(3))],
                             maxlen=int(np.ceil(ROLLBACK_S / self.period)) + 1)
        #: live gyrocompass segments (:class:`~.gyrocompass.GyroSegments`) or None, and
        #: the NIS above which a segment's heading is dropped (a rest-watch false alarm's)
        self.gyro_segments = None
        self.gyro_gate = chi2_quantile(1.0 - P_FALSE, 1)

    # -- stepping --------------------------------------------------------------------------
    def run_block(self, t, dtheta, dv, i, t_last):
        """Mechanize samples ``i..`` up to the next filter epoch (which it runs).

        Returns ``(j, C (j - i, 3, 3), epoch)``: the end index, the attitudes after each
        sample (the last one corrected when the epoch ran) and whether it ran.
        """
        n = len(t)
        # the epoch's sample: the accumulated time (summed in order, as one sample at a time
        # would) reaches the period; looked for among the samples up to the stamp where it
        # falls, a few more, then all (a clock that runs slow)
        need = self.period - _EPS_T
        k = int(np.searchsorted(t, t_last + need - self.since_update, side='right')) + 2
        for end in (min(max(k, i + 1), n), n):
            dts = np.diff(np.concatenate([[t_last], t[i:end]]))
            acc = np.cumsum(np.concatenate([[self.since_update], dts]))[1:]
            hit = np.flatnonzero(acc >= need)
            if len(hit) or end == n:
                break
        j = i + (int(hit[0]) + 1 if len(hit) else len(dts))
        dts, acc = dts[:j - i], float(acc[j - i - 1]) if j > i else self.since_update
        C = self.mech.run(dtheta[i:j], dv[i:j], dts)['C_b_n']
        if self.gyro_segments is not None:
            self.gyro_segments.add(dtheta[i:j], dv[i:j], dts)
        self.since_update = acc
        epoch = acc >= self.period - _EPS_T
        if epoch:
            self._epoch(acc)
            C[-1] = self.mech.C_b_n
        return j, C, epoch

    def step(self, dtheta, dv, dt):
        """Mechanize one sample (scalar path); returns ``(C_b_n, epoch)``."""
        C = self.mech.step(dtheta, dv, dt)
        if self.gyro_segments is not None:
            self.gyro_segments.add(dtheta[None], dv[None], dt)
        self.since_update += dt
        if self.since_update >= self.period - _EPS_T:
            self._epoch(self.since_update)
            return self.mech.C_b_n, True
        return C, False

    def _epoch(self, dt):
        """Predict over ``dt``, update with zero velocity, feed back (seed 002 eq. 3).

        An epoch whose innovation is beyond :attr:`zv_gate` is refused (predicted only);
        while coasting the covariance grows instead (:class:`~.still_watch.Coast`).
        """
        self.since_update = 0.0
        self.last_correction = np.zeros(3)
        if self.coast is not None:
            self.coast.advance(dt, float(np.hypot(*self.mech.v_n[:2])))
            if self.gyro_segments is not None:
                self.gyro_segments.spoil()
            return
        m = self.model
        Phi, Qd = self._discretize(dt)
        x, P = kf.predict(self.x, self.P, Phi, Qd)
        z = self.mech.v_n[m.meas]
        y = z - self.H @ x
        S = self.H @ P @ self.H.T + self.R
        self.last_nis = kf.nis(y, S)
        self.last_gated = self.last_nis > self.zv_gate
        if self.last_gated:
            self.x, self.P = x, P
            self.n_gated += 1
            self._recent.append((P, np.zeros(3), np.zeros(3)))
            if self.gyro_segments is not None:
                self.gyro_segments.spoil()
            return
        self.x, self.P, y, S = kf.update(x, P, z, self.H, self.R)
        self.n_updates += 1
        dvel = np.zeros(3)
        dvel[m.meas] = self.x[m.i_v]
        self.last_correction = self.x[m.i_phi].copy()
        self._feed_back()
        self._gyro_epoch()
        self._recent.append((self.P, self.last_correction, dvel))

    def _gyro_epoch(self):
        """Take a full live gyrocompass segment's heading (:mod:`.gyrocompass`), if one is due.

        Its correction is added to :attr:`last_correction` (the settle test sums what each
        epoch changed). A heading beyond :attr:`gyro_gate` from the filter's (a base that
        turned in a way the rest watch did not see) is dropped, not taken.
        """
        seg = self.gyro_segments
        if seg is None:
            return
        fix = seg.take()
        if fix is not None:
            C0 = self.mech.C_b_n
            if self.gyrocompass_update(*fix, max_nis=self.gyro_gate)[2]:
                self.last_correction = (self.last_correction
                                        + dcm_to_rotvec(self.mech.C_b_n @ C0.T))
            else:
                seg.n_taken, seg.n_dropped = seg.n_taken - 1, seg.n_dropped + 1
        if seg.done:
            self.gyro_segments = None

    def _feed_back(self):
        """Feedback: ``C = exp([phi x]) C~`` (seed 002 eq. 3), velocity error removed."""
        m = self.model
        self.mech.C_b_n = rotvec_to_dcm(self.x[m.i_phi]) @ self.mech.C_b_n
        dvel = np.zeros(3)
        dvel[m.meas] = self.x[m.i_v]
        self.mech.correct_velocity(dvel)
        self.x[m.i_phi] = 0.0
        self.x[m.i_v] = 0.0

    def update_heading(self, fix, t_now, w_up=0.0):
        """Take an external heading ``fix`` (:class:`~.heading.HeadingFix`) at ``t_now``.

        A filter epoch (zero velocity) over the time since the last one first, then the yaw
        update (:func:`~.heading.yaw_update`; directly above :data:`~.heading.LINEAR_MAX`)
        and the feedback. Measured, the heading no longer rests on the gyro bias: the 10/12
        models, whose bias states the measured heading separates, drop their heading
        :attr:`bound`. (``reduced7`` has no bias states: the gyrocompass keeps pulling it
        towards ``eps_E / (W cos L)``, and its output floor stays; docs/filters.md.)
        Returns ``'used'``, ``'taken'`` or ``'rejected'``.
        """
        if self.since_update > 1e-6:
            self._epoch(self.since_update)
        m = self.model
        yaw = fix.yaw + w_up * (t_now - fix.t)
        if self.coast is not None:
            return self._coast_heading(fix, yaw)
        k_up = np.arange(m.n)[m.i_phi][2]
        if self.P[k_up, k_up] > LINEAR_MAX ** 2:
            self.mech.C_b_n, self.P = take_heading(self.mech.C_b_n, self.P, k_up, yaw, fix.var)
            self.x[k_up] = 0.0
            result = 'taken'
        else:
            upd = gated_yaw_update(self.heading_gate, self, self.x, self.P, m.i_phi,
                                   self.mech.C_b_n, fix, yaw)
            if upd is None:
                return 'rejected'
            self.x, self.P = upd
            self._feed_back()
            result = 'used'
        self.heading_measured()
        return result

    def gyrocompass_update(self, yaw, var, max_nis=None):
        """Update with the heading ``yaw`` (rad) the averaged gyros give; (y, sigma, used).

        ``var`` (rad^2): that heading's white-noise variance. The analytic (gyrocompass)
        attitude of a still base is the one at which this model sees no drift, so it
        carries the biases the model cannot tell from the misalignment at rest (seed 002
        eq. 15) and the measurement row takes the bias states too: ``phi_a = M b``, the
        misalignment that zeroes the horizontal velocity drift and the east tilt drift of
        :meth:`~sins_align_ros.models.stationary.StationaryModel.F` for biases ``b``, is
        the analytic attitude's own error, so ``yaw_a = yaw(C~) + h (phi - M b) + noise``
        with ``h`` the yaw row (:func:`~..inputs.heading.yaw_row`). The update narrows the
        heading along what the gyros saw and leaves the heading's :attr:`bound` (the
        biases) as it was. Returns the innovation (rad), its predicted 1-sigma and whether
        it was used (not when its NIS exceeds ``max_nis``; None: no gate).
        """
        m = self.model
        C = self.mech.C_b_n
        F = m.F(C, self.lat, self.g)
        ip = m.i_phi
        ib = np.setdiff1d(np.arange(m.n), np.concatenate([m.i_v, ip]))
        rows = np.concatenate([m.i_v[:2], ip[:1]])
        M = -np.linalg.solve(F[np.ix_(rows, ip)], F[np.ix_(rows, ib)])
        h = yaw_row(C)
        H = np.zeros(m.n)
        H[ip] = h
        H[ib] = -h @ M
        y = wrap(yaw - yaw_of(C) - float(H @ self.x))
        x, P, y, S, used = heading_update(self.x, self.P, H, y, var, max_nis)
        if used:
            self.x, self.P = x, P
            self._feed_back()
        return y, float(np.sqrt(S)), used

    def heading_measured(self):
        """Drop the heading's :attr:`bound`: an external heading, not the gyro bias, sets it."""
        self.bound = np.array([self.bound[0], self.bound[1], 0.0])

    def _discretize(self, dt):
        m = self.model
        key = round(dt, 9)
        if m.name == 'reduced7' and key in self._disc_cache:
            return self._disc_cache[key]
        F = m.F(self.mech.C_b_n, self.lat, self.g)
        G, Qc = m.G_Qc(self.mech.C_b_n, self.noise)
        res = kf.discretize(F, G, Qc, dt)
        if m.name == 'reduced7':
            self._disc_cache[key] = res
        return res

    def restage(self):
        """Seed 002 sec. 4: re-initialise the filter from the corrected attitude.

        The bias states, which absorbed the transient of the first stage (the
        nonlinear effect of a large initial misalignment), restart from their
        prior, uncorrelated with the misalignment.

        * reduced7: the misalignment keeps its current variance. Its unobservable
          part is not in P but added at the output (attitude floor), so nothing
          is counted twice; keeping the variance keeps the averaging already done
          on the heading (a widened restart let it wander outside the limit band).
        * stationary10/12: their P holds the bias/misalignment ambiguity itself;
          a fresh bias prior next to the old misalignment variance would count
          that information twice (Monte Carlo: 92% inside 3 sigma, NEES 6.9), so
          the misalignment restarts from three times its current sigma.
        """
        m = self.model
        ip = m.i_phi
        widen = 1.0 if m.name == 'reduced7' else 3.0
        P_phi = np.diag(np.diag(self.P)[ip]) * widen ** 2
        self.x, P = m.reset_biases(self.x, self.P, self.noise)
        other = np.setdiff1d(np.arange(m.n), ip)
        P[np.ix_(ip, ip)] = P_phi
        P[np.ix_(ip, other)] = 0.0
        P[np.ix_(other, ip)] = 0.0
        self.P = P

    # -- output ------------------------------------------------------------------------------
    def attitude_cov(self):
        """Misalignment covariance about ENU (3, 3) the filter holds (without the floor).

        For the 10/12-state models each variance is raised to at least what the
        biases they cannot separate from it at rest leave (seed 002 eq. 15: tilt
        ``a/g``, heading ``eps_E/(W cos L)``, :attr:`bound`). Their own covariance should
        hold that, but its linear model, restaged and with a MEMS heading that is
        anything but small, was measured to shrink the tilt sigma to a third of the
        bound (static MEMS IMU, stationary12: 0.06 deg against an accelerometer bias
        of 0.27 deg, 7 % of the samples beyond 3 sigma). Raising diagonal entries keeps
        the matrix positive semi-definite.
        """
        if self.coast is not None:
            return self.coast.P
        P = self._attitude_cov(self.P)
        if self.cruise_floor is not None:
            P = P + np.diag(self.cruise_floor)
        return P

    def _attitude_cov(self, P_full):
        ip = self.model.i_phi
        P = P_full[np.ix_(ip, ip)]
        d = np.diag(P)
        if np.any(d < self.bound):
            P = P + np.diag(np.maximum(self.bound - d, 0.0))
        return P

    def widen(self, var_phi, var_v):
        """Add ``var_phi`` (rad^2) to each misalignment and ``var_v`` to each velocity variance."""
        if self.coast is not None:
            self.coast.P[np.diag_indices(3)] += var_phi
            return
        m = self.model
        P = self.P.copy()
        P[m.i_phi, m.i_phi] += var_phi
        P[m.i_v, m.i_v] += var_v
        self.P = P

    def tilt_floor(self):
        """Return zeros (3,): the unseen variances are the fixed :attr:`floor` (make_engine's)."""
        return np.zeros(3)

    def nav_cov(self):
        """Return None: the still-base engine does not navigate."""
        return None

    def status(self):
        """Filter internals for diagnostics."""
        s = {'filter_updates': self.n_updates, 'innovation_nis': self.last_nis,
             'zero_velocity_refused': self.n_gated, 'coasting': self.coast is not None}
        if self.heading_gate.n_rejected or self.bound[2] == 0.0:
            s.update(self.heading_gate.status())
        return s

"""The measurement noise of a GNSS epoch, shared by every GNSS-aided engine.

A mixin of :class:`~.aided.GnssAidedEngine`. The filters that take R from the engine
get, each epoch, the nominal R with the receiver's reported variances where they are
used, the consistency monitor's factors (``R_scale``) and a lever arm's variance
(``GnssFix.arm_var``: what the attitude's uncertainty leaves in moving the fix from the
antenna to the IMU, :mod:`.installation`). The velocity rows get the IMU's velocity jitter too
(``velocity_jitter_var``: a vibrating chassis's bounded velocity error, which the
mechanized velocity carries at every epoch; :mod:`.self_check` measures it). A Sage-Husa
filter, whose R is its own estimate, is lent the arm's and the jitter's part for the
epoch instead; the variational-Bayes filters learn them in their posterior.

The receiver's time-correlated position error (:mod:`.gnss_markov`) is taken here too,
for every aided filter: by default as a white-equivalent share of each position row's R
where the engine sets R, else (and with the ``process`` method) as a random walk of the
measured position states (their variance raised before the update,
:meth:`EpochNoise._take_markov`).
"""
import numpy as np

from .gnss_markov import GnssMarkov, position_rows


class EpochNoise:
    """R of each GNSS epoch (a mixin; module docstring).

    Uses the engine's ``kf``, ``R_nominal``, ``R_scale``, ``sets_R``, ``use_reported_cov``,
    ``use_velocity``, ``rows`` and ``MEAS_ENU``.
    """

    #: the receiver's Gauss-Markov position error the engine assumes (:mod:`.gnss_markov`)
    gnss_markov = None
    #: variance ((m/s)^2) per axis of the IMU's velocity jitter (``imu_velocity_jitter_mps``:
    #: a vibrating chassis's bounded velocity error, :mod:`.self_check`), added to the noise
    #: of the velocity rows
    velocity_jitter_var = 0.0

    def _velocity_rows(self):
        """Rows of R (indices) that measure a velocity; none without GNSS velocity."""
        if not self.use_velocity:
            return np.zeros(0, dtype=int)
        return np.flatnonzero(self.MEAS_ENU[:len(self.R_nominal)] >= 3)

    def receiver_velocity_var(self):
        """Return the GNSS velocity noise variance ((m/s)^2) the filter takes, jitter apart.

        None without velocity rows. The smallest of the velocity rows': the adaptive
        filter's estimate, the last epoch's R less the jitter where the engine sets R (the
        reported variances, the consistency monitor's factors), else the nominal R.
        """
        k = self._velocity_rows()
        if not len(k):
            return None
        R = self.R_nominal if getattr(self.kf, 'R', None) is None else self.kf.R
        if len(R) != len(self.R_nominal):
            R = self.R_nominal
        var = float(np.min(R.diagonal()[k]))
        if self.sets_R or self.use_reported_cov:
            var -= self.velocity_jitter_var     # the last epoch's R has it (_set_epoch_noise)
        return max(var, 0.0)

    def set_gnss_markov(self, sigma, tau, method=None):
        """Assume a Gauss-Markov position error of ``sigma`` m per axis, ``tau`` s.

        Sigma 0 assumes none until the consistency monitor's long-horizon test finds one
        (:meth:`widen_gnss_noise`); ``tau`` is then the correlation time it assumes.
        ``method`` None: the engine's (:meth:`_markov_method`).
        """
        self.gnss_markov = GnssMarkov(sigma, tau, method or self._markov_method())

    def _markov_method(self):
        """Return the form the engine takes the error in: states where it can carry them.

        ``state`` (:mod:`.gnss_markov_states`) for an engine that has them and sets R,
        else ``measurement`` (:mod:`.gnss_markov`; a filter that estimates R takes the
        ``process`` form of it, :meth:`_markov_in_R`).
        """
        return 'state' if getattr(self, 'markov_states', False) and self.sets_R else 'measurement'

    def _markov(self):
        if self.gnss_markov is None:
            self.gnss_markov = GnssMarkov(method=self._markov_method())
        return self.gnss_markov

    def _markov_in_R(self):
        """Tell whether the Gauss-Markov error goes into R (else into P, :meth:`_take_markov`)."""
        return self.gnss_markov.method == 'measurement' and self.sets_R

    def _take_markov(self, fix):
        """Before ``fix``'s update: the interval since the last fix; the random walk.

        Unless the error goes into R (:meth:`_markov_in_R`) or is states of its own
        (``state``, :mod:`.gnss_markov_states`), raises the measured position
        states' variance by ``q dt`` (:meth:`~.gnss_markov.GnssMarkov.process_var`); a
        filter's P setter keeps its own form (a square-root factor is refactored).
        """
        gm = self._markov()
        if gm.from_fixes:
            gm.assume(self._fix_sigma_h(fix))
        dt = gm.epoch(fix.t)
        in_P = not (self._markov_in_R() or gm.method == 'state')
        var = gm.process_var(dt) if in_P else 0.0
        if var <= 0.0:
            return
        k = np.asarray(self.rows)[position_rows(self.MEAS_ENU)]
        P = self.kf.P.copy()
        P[k, k] += var
        self.kf.P = P

    def _fix_sigma_h(self, fix):
        """Horizontal position 1-sigma (m) of ``fix``: reported where used, else configured."""
        if self.use_reported_cov and fix.pos_var is not None:
            return float(np.sqrt(np.max(np.asarray(fix.pos_var, dtype=float)[:2])))
        k = position_rows(self.MEAS_ENU)[:2]
        return float(np.sqrt(np.max(self.R_nominal.diagonal()[k])))

    @property
    def measures_position(self):
        """Tell whether the engine's measurement has position rows."""
        return len(position_rows(self.MEAS_ENU)) > 0

    def _set_epoch_noise(self, fix):
        """Set ``kf.R`` for ``fix`` where the engine sets it (never for an adaptive filter).

        Takes the Gauss-Markov position error first (:meth:`_take_markov`), for every filter.
        """
        self._take_markov(fix)
        if not (self.sets_R or self.use_reported_cov):
            return
        R = self.R_nominal.copy()
        if self.use_reported_cov:
            self._take_reported(R, fix)
        if self.sets_R:
            s = np.sqrt(self.R_scale)
            R = R * np.outer(s, s)
        gm = self.gnss_markov
        extra = gm.measurement_var(gm.dt) if self._markov_in_R() else 0.0
        if extra > 0.0:
            k = position_rows(self.MEAS_ENU)
            R[k, k] += extra
        if fix.arm_var is not None:
            R[np.diag_indices(len(R))] += fix.arm_var[self.MEAS_ENU]
        if self.velocity_jitter_var > 0.0:
            k = self._velocity_rows()
            R[k, k] += self.velocity_jitter_var
        self.kf.R = R

    def _take_reported(self, R, fix):
        """Put ``fix``'s reported east/north variances on R's diagonal (in place).

        Row ``r`` of the measurement vector measures ENU axis ``MEAS_ENU[r]``: the rows of
        east and north position (axes 0, 1) take ``fix.pos_var``, those of east and north
        velocity (3, 4) ``fix.vel_var`` when the engine measures velocity; the height and
        vertical velocity keep R's (a NavSatFix's horizontal covariance is what
        ``GnssFix`` carries). Seed 000's rows are E, N position then E, N velocity, the
        navigation filters' position E, N, U then velocity E, N, U.
        """
        for r, axis in enumerate(self.MEAS_ENU[:len(R)]):
            if axis < 2 and fix.pos_var is not None:
                R[r, r] = fix.pos_var[axis]
            elif 3 <= axis < 5 and self.use_velocity and fix.vel_var is not None:
                R[r, r] = fix.vel_var[axis - 3]

    def widen_gnss_noise(self, excess, block_s):
        """Apply the long-horizon test's ``excess``: row -> (variance m^2 or (m/s)^2, factor).

        Position rows widen the Gauss-Markov model by the largest excess variance of
        ``block_s``-second means (:meth:`~.gnss_markov.GnssMarkov.widen`); velocity rows
        have their noise inflated by the factor (filters that set R). Returns ``(old,
        new)`` Gauss-Markov sigma (m) and the velocity rows' factors applied (dict).
        """
        pos = set(position_rows(self.MEAS_ENU).tolist())
        gm = self._markov()
        var = max([v for r, (v, _) in excess.items() if r in pos], default=0.0)
        old, new = gm.widen(var, block_s)
        vel = {r: f for r, (_, f) in excess.items() if r not in pos and f > 1.0}
        if vel and self.sets_R:
            self.inflate_noise(vel)
        else:
            vel = {}
        return old, new, vel

    def _lend_arm_noise(self, fix):
        """Lend a lever arm's and the velocity jitter's variance to an adaptive filter's R.

        For one epoch; returns what was lent (len(R),) or None. The filters that set R take
        ``fix.arm_var`` and :attr:`velocity_jitter_var` into it (:meth:`_set_epoch_noise`);
        a Sage-Husa filter's R is its estimate, so the known part is lent (``kf.R_lent``):
        the update uses it on top of the estimate, the estimator takes it out of the
        innovations and does not count it as the receiver's noise, and
        :meth:`_return_arm_noise` ends the loan. The estimator learns R only on epochs
        where R dominates the innovation covariance (``filters/adaptive.py``): a vibrating
        robot's velocity jitter above its RTK velocity noise (0.05 against 0.02 m/s,
        robot:rtk) was never learnt, the consistency monitor inflated the state instead
        and the ASCKF's tilt went 1-5 deg off under a 1-deg sigma (10 of 10 runs told the
        right model silent-wrong). (The variational-Bayes filters' R is their posterior;
        they learn both.)
        """
        if self.sets_R or self.use_reported_cov or getattr(self.kf, 'estimates_R', False):
            return None
        if fix.arm_var is None and not self.velocity_jitter_var > 0.0:
            return None
        lent = np.zeros(len(self.R_nominal))
        if fix.arm_var is not None:
            lent += fix.arm_var[self.MEAS_ENU[:len(lent)]]
        lent[self._velocity_rows()] += self.velocity_jitter_var
        self.kf.R_lent = lent
        return lent

    def _return_arm_noise(self):
        """End the loan of :meth:`_lend_arm_noise`."""
        self.kf.R_lent = None

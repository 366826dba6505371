"""The measurement noise of a GNSS epoch, shared by every GNSS-aided engine.

A mixin of :class:`~.aided.GnssAidedEngine`. The filters that take R from the engine
get, each epoch, the nominal R with the receiver's reported variances where they are
used, the consistency monitor's factors (``R_scale``) and a lever arm's variance
(``GnssFix.arm_var``: what the attitude's uncertainty leaves in moving the fix from the
antenna to the IMU, :mod:`.installation`). A Sage-Husa filter, whose R is its own
estimate, is lent the arm's part for the epoch instead; the variational-Bayes filters
learn it in their posterior.
"""
import numpy as np


class EpochNoise:
    """R of each GNSS epoch (a mixin; module docstring).

    Uses the engine's ``kf``, ``R_nominal``, ``R_scale``, ``sets_R``, ``use_reported_cov``,
    ``use_velocity`` and ``MEAS_ENU``.
    """

    def _set_epoch_noise(self, fix):
        """Set ``kf.R`` for ``fix`` where the engine sets it (never for an adaptive filter)."""
        if not (self.sets_R or self.use_reported_cov):
            return
        R = self.R_nominal.copy()
        if self.use_reported_cov:
            if fix.pos_var is not None:
                R[0, 0], R[1, 1] = fix.pos_var
            if self.use_velocity and fix.vel_var is not None:
                R[2, 2], R[3, 3] = fix.vel_var
        if self.sets_R:
            s = np.sqrt(self.R_scale)
            R = R * np.outer(s, s)
        if fix.arm_var is not None:
            R[np.diag_indices(len(R))] += fix.arm_var[self.MEAS_ENU]
        self.kf.R = R

    def _lend_arm_noise(self, fix):
        """Lend a lever arm's variance to an adaptive filter's R for one epoch (or None).

        The filters that set R take ``fix.arm_var`` into it (:meth:`_set_epoch_noise`); a
        Sage-Husa filter's R is its estimate, so the known part is lent (``kf.R_lent``):
        the update uses it on top of the estimate, the estimator takes it out of the
        innovations and does not count it as the receiver's noise, and
        :meth:`_return_arm_noise` ends the loan. (The variational-Bayes filters' R is their
        posterior; they learn the arm's noise.)
        """
        if fix.arm_var is None or self.sets_R or self.use_reported_cov or getattr(
                self.kf, 'estimates_R', False):
            return None
        arm = fix.arm_var[self.MEAS_ENU]
        self.kf.R_lent = arm
        return arm

    def _return_arm_noise(self):
        """End the loan of :meth:`_lend_arm_noise`."""
        self.kf.R_lent = None

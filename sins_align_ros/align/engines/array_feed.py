"""Offline runs of a GNSS-aided engine over whole arrays (tests and studies, not the stages).

A mixin of :class:`~.aided.GnssAidedEngine` (:class:`ArrayFeed`): IMU samples and GNSS
epochs given as arrays are run in stamp order, each epoch at the first sample at or past
its stamp, as the fine stage's sample-by-sample path applies them (without its monitors).
"""
from ..inputs.gnss_fix import GnssFix


class ArrayFeed:
    """Run an aided engine over arrays (a mixin; uses ``step_imu`` and ``update``)."""

    def feed(self, imu, gnss, t0):
        """Run samples 1..N-1 of ``imu`` (``t``, ``dtheta``, ``dv``) from stamp ``t0 = imu.t[0]``.

        GNSS epochs of ``gnss`` (``t``, ``lat``, ``lon``, ``h``; rad, rad, m; with
        ``v_n`` and ``fix`` when the arrays have them) after ``t0`` are applied at the
        first sample at or past their stamp. Raises :class:`FilterDiverged` as
        :meth:`update` does.
        """
        gi, t_prev = 0, t0
        for k in range(1, len(imu.t)):
            t = imu.t[k]
            self.step_imu(imu.dtheta[k], imu.dv[k], t - t_prev)
            t_prev = t
            while gi < len(gnss.t) and gnss.t[gi] <= t + 1e-9:
                fix = self._gnss_fix(gnss, gi) if gnss.t[gi] > t0 else None
                if fix is not None:
                    self.update(fix, t)
                gi += 1

    @staticmethod
    def _gnss_fix(gnss, i):
        """Epoch ``i`` of the arrays given to :meth:`feed` as a :class:`GnssFix` (or None)."""
        if hasattr(gnss, 'fix') and not gnss.fix[i]:
            return None
        v = gnss.v_n[i] if hasattr(gnss, 'v_n') else None
        return GnssFix(gnss.t[i], gnss.lat[i], gnss.lon[i], gnss.h[i], v)

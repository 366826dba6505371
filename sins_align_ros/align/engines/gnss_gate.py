"""The GNSS innovation gate of the GNSS-aided engines (not in the seeds).

An epoch whose normalised innovation squared exceeds the chi-square quantile of
``probability`` (m degrees of freedom) is rejected as an outlier. After
``max_rejects`` rejected epochs in a row the next one is accepted with the
measured states' variances widened by the last rejected innovation squared (a
position jump, or the filter lagging behind a true change, then re-anchors to
GNSS instead of being rejected for ever); if that happens :data:`MAX_FORCED`
times without ``max_rejects`` accepted epochs in between, the inertial solution
and GNSS disagree for good and :meth:`GnssGate.threshold` raises
:class:`FilterDiverged`.
"""
from ...filters.chi2 import chi2_quantile

#: forced acceptances (after ``max_rejects`` rejections each) in a row after which the
#: inertial solution and GNSS are taken to disagree for good: the caller restarts alignment
MAX_FORCED = 3


class FilterDiverged(RuntimeError):
    """The filter's numbers became non-finite or singular; the caller restarts alignment."""


class GnssGate:
    """Gate state and counts; ``probability`` None switches the gate off.

    ``sizes``: the measurement sizes whose thresholds the status reports; ``name`` the
    source in messages and status keys (the external heading has a gate of its own).
    """

    def __init__(self, probability=None, max_rejects=10, sizes=(), name='gnss'):
        self.name = name
        self.probability = probability
        self.max_rejects = int(max_rejects)
        self.sizes = tuple(sizes)
        self.n_rejected = self.n_forced = 0
        self.consecutive_rejects = self._accepted_run = self._forced_run = 0
        self._y_rejected = None
        #: (t, NIS, threshold) of the last rejected epoch
        self.last_rejection = None

    def quantile(self, m):
        """Chi-square quantile of ``probability`` for ``m`` measurements."""
        return chi2_quantile(self.probability, m)

    def threshold(self, m, kf):
        """NIS threshold of this epoch, or None (gate off, or a forced acceptance).

        A forced acceptance first widens the variances of ``kf``'s measured states
        by the last rejected innovation squared.
        """
        if self.probability is None:
            return None
        if self.consecutive_rejects < self.max_rejects:
            return self.quantile(m)
        self._forced_run += 1
        if self._forced_run >= MAX_FORCED:
            raise FilterDiverged(
                f'{self._label} rejected by the innovation gate {self.max_rejects} epochs in '
                f'a row, {MAX_FORCED} times without recovering: the inertial solution and '
                f'{self._label} disagree')
        r_rej, y_rej = self._y_rejected
        P = kf.P
        P[r_rej, r_rej] += y_rej ** 2
        kf.P = P
        self.n_forced += 1
        self.consecutive_rejects = 0
        return None

    def rejected(self, t, nis, threshold, rows, y):
        """Count a rejected epoch at ``t`` (its innovation ``y`` on state ``rows``)."""
        self.n_rejected += 1
        self.consecutive_rejects += 1
        self._accepted_run = 0
        self._y_rejected = (rows, y.copy())
        self.last_rejection = (t, nis, threshold)

    def accepted(self):
        """Count an accepted epoch."""
        self.consecutive_rejects = 0
        self._accepted_run += 1
        if self._accepted_run >= self.max_rejects:
            self._forced_run = 0

    def status(self):
        """Gate figures for diagnostics (empty with the gate off)."""
        if self.probability is None:
            return {}
        k = self.name
        return {f'{k}_gate_probability': self.probability,
                f'{k}_gate_threshold': [self.quantile(m) for m in self.sizes],
                f'{k}_rejected': self.n_rejected, f'{k}_forced': self.n_forced,
                f'{k}_consecutive_rejects': self.consecutive_rejects}

    @property
    def _label(self):
        return 'GNSS' if self.name == 'gnss' else f'the {self.name}'

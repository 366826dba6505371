"""Consistency monitor: whether the filter's innovations agree with its own covariance.

A filter whose model is too optimistic (a MEMS IMU with navigation-grade defaults, a
wrong noise parameter, a manoeuvre the model lacks) makes innovations larger than its
innovation covariance predicts, and its published sigma is then too small. The
monitor keeps the normalised innovation squared (NIS) of the last ``window`` GNSS
epochs; their sum is chi-square with the summed measurement sizes as degrees of
freedom when the filter is consistent. When the sum exceeds the ``probability``
quantile the filter is inconsistent: the monitor asks for the covariance to be
inflated by the median ratio of the observed to the expected NIS over the window
(capped at :data:`MAX_INFLATION`; the median, so that one outlier does not set it), the
window restarts, and the fine stage leaves ``aligned`` with the reason until the test passes
again. Each NIS is winsorised at the 0.9999 quantile of its own size first, so that
single GNSS outliers (the innovation gate's and the robust filters' business) do not
trigger it; a lasting model error does. Epochs the innovation gate refused are left
out while they are rare, at most :data:`OUTLIER_SHARE` of the last :data:`HISTORY`
epochs: receivers' occasional outliers are the gate's business, while a model error or
a noisier receiver makes the gate refuse many epochs (then they all count). Counted,
two outliers in one window failed the test (at 5 % outliers, one window in eleven; at
a 5 Hz receiver every few seconds), and each failure inflated the state or, for white
innovations, the measurement noise, which then let the next outliers through the gate
(seed 004's USV with a 5 Hz receiver and default parameters: R inflated twice, a
2.7 m/s velocity outlier accepted, the heading taken from its track 48 deg off).

Which covariance is too small, the state's or the measurement's? Given each epoch's
innovations normalised row by row (``u = y / sqrt(diag S)``) and their measurement rows,
the monitor tells the two apart by the innovations' serial correlation (Mehra's
whiteness test, one lag): a model error (a drift, a bias the model lacks) makes
innovations that persist from epoch to epoch (lag-1 correlation near +1), while a
measurement noise larger than configured makes white ones, or negatively correlated
ones when the filter follows the noisy fixes. When every row that fails its own
chi-square test has a lag-1 correlation below :data:`MODEL_LAG1` over its last
:data:`HISTORY` epochs, the remedy is to inflate those rows' measurement noise
(:attr:`ConsistencyMonitor.r_factors`) and the state covariance is left alone; otherwise
the state covariance is inflated as above (also when no row fails alone). For a filter
whose R is its own variational posterior (the VB family: ``add``'s ``noise_remedy``
False) a white failure inflates nothing, also one with no row failing alone (a moderate
excess spread over white rows): its R estimate is the remedy, and a state inflation
would widen for good the directions a still base cannot observe (seed 002's tilt /
accelerometer-bias split; VBCKF on a still tactical IMU, where NIS/dof averaged 1.08 but
windows failed about once a run, ended with a tilt sigma 1.5x CKF's); the test still
fails (``aligned`` waits) and it is counted (``consistency_white_failures``). ASCKF's
Sage-Husa R learns only on epochs where R dominates the innovation covariance, too
slowly to answer a spell of white excess: its failures all inflate the state (on
ship_underway, 10 seeds, leaving them to its R cost one run its end inside 3 sigma and
made one silent-wrong).

After every window of consecutive passing tests the raised process noise is halved back
towards the model's (:attr:`relax`): an inflation answers a manoeuvre or a spell of bad
data, not the rest of the run (kept up, it made MVBAKF's inverse-Wishart prior, and the
KF's heading, grow without bound). Inflating the state for a GNSS noise mismatch (a
default height sigma of 2 m against a 5 m receiver) would let every epoch pull the
attitude, and repeated, destroys it.

Not in the seeds (their filters adapt R or Q, or fade, each in its own way); this is
the one check every GNSS-aided filter shares, so that a published sigma stays a claim.

Errors correlated over tens of seconds (a consumer receiver's Gauss-Markov position
error, :mod:`.gnss_markov`) pass the window: ten epochs at 5 Hz see two seconds of an
error that changes over a minute, and the filter half follows it, so the NIS stays near
its degrees of freedom while the filter over-trusts every difference of positions.
:class:`LongHorizonTest` looks at the innovations averaged over :data:`LONG_BLOCK_S`-second
blocks instead: for white innovations with the predicted covariance, ``N mean(u)^2`` of a
block of N normalised innovations is chi-square with one degree of freedom whatever N,
while a correlated error adds to it in proportion to N (the variance-ratio idea of
Mehra's whiteness test, taken to long lags). When a row's sum over the last
:data:`LONG_BLOCKS` blocks exceeds the :data:`LONG_PROBABILITY` quantile, its excess
variance (the block means' squares less what white noise predicts, in m^2 or (m/s)^2)
widens the GNSS model: the Gauss-Markov position error for the position rows, the noise
for the velocity rows (:meth:`~.epoch_noise.EpochNoise.widen_gnss_noise`). It only widens;
its histories restart after a widening, so the next verdict is on the widened filter.
"""
import math
from collections import deque

import numpy as np

from ...filters.chi2 import chi2_quantile

#: epochs in the window
WINDOW = 10
#: probability of the chi-square test on the window's NIS sum
PROBABILITY = 0.999
#: an epoch's NIS counts at most the chi-square quantile of this probability
WINSOR = 0.9999
#: largest covariance inflation at one time
MAX_INFLATION = 10.0
#: epochs of normalised innovations kept per measurement row for the whiteness test
HISTORY = 30
#: a failing row whose lag-1 correlation reaches this is a model error, not noise
MODEL_LAG1 = 0.3
#: refused epochs up to this share of the last HISTORY are outliers, left out of the test
OUTLIER_SHARE = 0.1
#: seconds of innovations averaged per block of the long-horizon test
LONG_BLOCK_S = 20.0
#: blocks per verdict of the long-horizon test (its horizon: LONG_BLOCKS x LONG_BLOCK_S)
LONG_BLOCKS = 4
#: probability of its chi-square test (a verdict per row and block: few false widenings)
LONG_PROBABILITY = 0.99999
#: fewest epochs in a block for its mean to count
LONG_MIN_EPOCHS = 10


class ConsistencyMonitor:
    """Windowed NIS test; see the module docstring."""

    def __init__(self, window=WINDOW, probability=PROBABILITY):
        self.window = int(window)
        self.probability = float(probability)
        self._nis = deque(maxlen=self.window)
        self._dof = deque(maxlen=self.window)
        self._raw = deque(maxlen=self.window)
        #: the last test passed (True until the window has filled)
        self.consistent = True
        #: NIS sum over degrees of freedom, and the test's bound on it, of the last test
        self.ratio = float('nan')
        self.bound = float('nan')
        #: failed tests since the last one that passed (two: a clear failure,
        #: :mod:`.aligned_gate`)
        self.failed_in_row = 0
        self.n_inflations = 0
        self.n_r_inflations = 0
        #: measurement row -> factor for its noise variance, set when a failed test is
        #: put down to the measurement noise (empty otherwise)
        self.r_factors = {}
        #: what the last failed test did, for the reason the phase gives
        self.remedy = ''
        #: the last call ended a window of consecutive passing tests (relax the remedy)
        self.relax = False
        self._passes = 0
        self._u = {}
        #: whether each of the last HISTORY epochs was refused by the gate
        self._refused = deque(maxlen=HISTORY)
        #: refused epochs left out as outliers
        self.n_outliers = 0
        #: failed tests with white innovations left to a filter that estimates R itself
        self.n_white = 0
        #: errors correlated over tens of seconds (:class:`LongHorizonTest`)
        self.long = LongHorizonTest()
        #: what the long-horizon test's widenings did, for the warnings (popped)
        self.notes = []

    def add(self, nis, dof, u=None, rows=None, rejected=False, noise_remedy=True):
        """Record one epoch's NIS with ``dof`` measurements; return an inflation factor or None.

        ``u`` (dof,): the innovations normalised row by row, ``rows`` (dof,) their
        measurement rows (optional; without them every failure inflates the state).
        ``rejected``: the innovation gate refused the epoch (left out while refusals
        are rare, module docstring). ``noise_remedy`` False: the filter estimates its
        measurement noise itself, and a failure with white innovations inflates nothing.
        The factor (> 1) for the state covariance is returned when the window's test
        fails and the failure is the model's; when it is the measurement noise's,
        None is returned and :attr:`r_factors` says which rows' noise to inflate. The
        window then restarts, so the next verdict uses innovations of the inflated filter.
        """
        self.r_factors = {}
        self.relax = False
        if not (dof > 0 and math.isfinite(nis)):
            return None
        self._refused.append(bool(rejected))
        if rejected and sum(self._refused) <= OUTLIER_SHARE * HISTORY:
            self.n_outliers += 1
            return None
        if u is not None and rows is not None:
            for r, v in zip(np.asarray(rows).tolist(), np.asarray(u, dtype=float)):
                self._u.setdefault(r, deque(maxlen=HISTORY)).append(float(v))
        self._nis.append(min(nis, chi2_quantile(WINSOR, dof)))
        self._dof.append(dof)
        self._raw.append(nis / dof)
        if len(self._nis) < self.window:
            return None
        s, m = sum(self._nis), sum(self._dof)
        self.ratio = s / m
        self.bound = chi2_quantile(self.probability, m) / m
        self.consistent = self.ratio <= self.bound
        if self.consistent:
            self.failed_in_row = 0
            self._passes += 1
            # a whole window of passing tests since the last relaxation: the process
            # noise raised by earlier inflations may come back down
            self.relax = self._passes % self.window == 0
            return None
        self._passes = 0
        self.failed_in_row += 1
        factor = min(max(float(np.median(self._raw)), self.ratio), MAX_INFLATION)
        self._nis.clear()
        self._dof.clear()
        self._raw.clear()
        if not noise_remedy and self._white_failure():
            self.remedy = 'white innovations, left to the filter\'s noise estimate'
            self.n_white += 1
            return None
        self.r_factors = self._noise_rows() if noise_remedy else {}
        if self.r_factors:
            self.remedy = 'measurement noise inflated (white innovations)'
            self.n_r_inflations += 1
            for r in self.r_factors:
                self._u[r].clear()
            return None
        self.remedy = 'covariance and process noise inflated'
        self.n_inflations += 1
        return factor

    @property
    def clearly_inconsistent(self):
        """Tell whether the failure is clear: the test failed again after the first's remedy.

        (:mod:`.aligned_gate`: a single failure, answered by its remedy, keeps ``aligned``.
        After a failure the window restarts, so the second test is on the innovations of the
        remedied filter. A single failure is always marginal once the window slides: the
        test runs at every epoch, so it fails at the first that tips the sum over.)
        """
        return not self.consistent and self.failed_in_row >= 2

    def _row_stats(self):
        """``(row, mean square over the window, lag-1 correlation)`` of rows with a window."""
        for r, hist in self._u.items():
            u = np.array(hist)
            if len(u) >= self.window:
                yield (r, float(np.mean(u[-self.window:] ** 2)),
                       float(np.sum(u[1:] * u[:-1]) / max(float(np.sum(u * u)), 1e-300)))

    def _noise_rows(self):
        """Rows to inflate the measurement noise of, with factors; empty for a model error."""
        failing = {}
        for r, ms, lag1 in self._row_stats():
            if ms <= chi2_quantile(self.probability, self.window) / self.window:
                continue
            if lag1 >= MODEL_LAG1:
                return {}
            failing[r] = min(ms, MAX_INFLATION)
        return failing

    def _white_failure(self):
        """Whether the rows failing alone are all white, or, none failing, every row is."""
        if self._noise_rows():
            return True
        stats = list(self._row_stats())
        return bool(stats) and all(lag1 < MODEL_LAG1 for _, _, lag1 in stats)

    def add_long(self, t, y, s, rows, rejected=False):
        """Give the long-horizon test an epoch (refused ones are left out); its findings.

        Returns :attr:`LongHorizonTest.excess` (row -> (excess variance, ratio)), empty
        unless a row failed at this epoch.
        """
        if rejected or y is None:
            self.long.excess = {}
            return {}
        self.long.add(t, y, s, rows)
        return self.long.excess

    def note_widening(self, excess, old, new, vel):
        """Say what a long-horizon widening did (``excess`` as :meth:`add_long` gave it)."""
        ratio = max(r for _, r in excess.values())
        what = []
        if new > old:
            what.append(f'GNSS Gauss-Markov position sigma widened {old:.2f} -> {new:.2f} m')
        if vel:
            what.append('GNSS velocity noise inflated x' + '/'.join(
                f'{f:.3g}' for f in vel.values()))
        if what:
            self.notes.append(
                f'GNSS errors correlated over tens of seconds: innovations averaged over '
                f'{self.long.block_s:.0f} s are {ratio:.1f}x the variance white noise '
                f'predicts (bound {self.long.bound:.1f}): ' + ', '.join(what))

    def pop_notes(self):
        """Return and clear the widening notes."""
        out, self.notes = self.notes, []
        return out

    def status(self):
        """Figures for diagnostics."""
        return {**self.long.status(),
                'consistency_ok': self.consistent, 'consistency_nis_ratio': self.ratio,
                'consistency_bound': self.bound, 'consistency_inflations': self.n_inflations,
                'consistency_noise_inflations': self.n_r_inflations,
                'consistency_outliers_left_out': self.n_outliers,
                'consistency_white_failures': self.n_white}


class LongHorizonTest:
    """Innovations averaged over tens of seconds against white noise; module docstring.

    :meth:`add` takes each accepted epoch's stamp, innovations ``y`` and their predicted
    variances ``s`` (diag S) with their measurement rows; :attr:`excess` is set, at the
    end of a block whose row fails, to ``row -> (excess variance, ratio)``: the mean of
    the block means' squares less the mean of ``s / N`` (m^2, (m/s)^2), and the test
    statistic over its degrees of freedom. The caller widens the model with it.
    """

    def __init__(self, block_s=LONG_BLOCK_S, blocks=LONG_BLOCKS, probability=LONG_PROBABILITY):
        self.block_s = float(block_s)
        self.blocks = int(blocks)
        self.bound = chi2_quantile(probability, self.blocks) / self.blocks
        #: row -> [t0 of the open block, n, sum u, sum y, sum s]
        self._open = {}
        #: row -> deque of closed blocks (n, mean u, mean y, mean s)
        self._closed = {}
        #: the last verdict's largest ratio (statistic / dof) over the rows, NaN before one
        self.ratio = float('nan')
        #: row -> (excess variance, ratio) of the rows failing at the last call, else empty
        self.excess = {}
        self.n_failures = 0
        self._ratios = []

    def add(self, t, y, s, rows):
        """Record one epoch (innovations ``y`` (m,), variances ``s`` (m,), ``rows`` (m,))."""
        self.excess = {}
        self._ratios = []
        y, s = np.asarray(y, dtype=float), np.asarray(s, dtype=float)
        for r, yi, si in zip(np.asarray(rows).tolist(), y.tolist(), s.tolist()):
            if not (si > 0.0 and math.isfinite(yi) and math.isfinite(si)):
                continue
            b = self._open.get(r)
            if b is None or t - b[0] >= self.block_s:
                if b is not None:
                    self._close(r, b)
                b = self._open[r] = [t, 0, 0.0, 0.0, 0.0]
            b[1] += 1
            b[2] += yi / math.sqrt(si)
            b[3] += yi
            b[4] += si
        if self._ratios:
            self.ratio = max(self._ratios)
        if self.excess:
            self.n_failures += 1
            self.restart()

    def _close(self, r, b):
        """Close row ``r``'s block ``b``; judge the row when it has its blocks."""
        n = b[1]
        if n < LONG_MIN_EPOCHS:
            return
        q = self._closed.setdefault(r, deque(maxlen=self.blocks))
        q.append((n, b[2] / n, b[3] / n, b[4] / n))
        if len(q) < self.blocks:
            return
        ratio = sum(n * mu * mu for n, mu, _, _ in q) / self.blocks
        self._ratios.append(ratio)
        if ratio > self.bound:
            excess = sum(my * my - ms / n for n, _, my, ms in q) / self.blocks
            self.excess[r] = (max(excess, 0.0), ratio)

    def restart(self):
        """Forget the blocks (after a widening: the next verdict is the widened filter's)."""
        self._open.clear()
        self._closed.clear()

    def status(self):
        """Figures for diagnostics."""
        return {'consistency_long_ratio': self.ratio, 'consistency_long_bound': self.bound,
                'consistency_long_widenings': self.n_failures}

"""An external heading (GNSS compass, gyrocompass): its input, its queue and its measurement.

The source's yaw (REP-103: of its x axis from east, counter-clockwise, rad) is turned into
the vehicle's with ``heading_offset_deg`` (the direction of the source's x axis, e.g. a
dual-antenna baseline, in the vehicle frame: ``yaw_vehicle = yaw_source - offset``).
Every accepted epoch is remembered for the coarse stage and, while a fine filter runs,
queued until the IMU stream passes its stamp, as GNSS epochs are
(:mod:`.gnss_buffer`). Counts by reason (:attr:`HeadingBuffer.counts`): ``used``,
``rejected`` (the innovation gate), ``taken`` (taken directly: the filter's heading
was beyond its linear range), ``late``, ``before_start``, ``ahead_of_imu``,
``queue_full``.

The measurement: every engine's attitude correction is, to first order, a rotation of
the computed navigation frame, ``C_b_n <- (I + [phi x]) C_b_n`` (seed 000's large-
misalignment ``C_n^n'^T`` and the rotation vector of seeds 001/002 alike), so the yaw
``atan2(C_10, C_00)`` moves by ``H phi`` with :func:`yaw_row`. That makes the external
heading a scalar linear measurement of the misalignment for every filter (an EKF update
of ``x`` and ``P``, whatever the filter's own update; :func:`yaw_update`). A filter whose
heading sigma is above :data:`LINEAR_MAX` (an unknown MEMS heading at rest, a capped
cubature prior) takes the heading directly instead (:func:`take_heading`): the linear
update of a 90 deg error would not be right. Not in the seeds: none of them uses a
heading sensor.
"""
import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from ...nav.frames import dcm_to_euler, wrap_pi

#: a heading epoch stamped this far ahead of the IMU clock is dropped, s (as GNSS)
MAX_LEAD_S = 10.0
#: a queued epoch older than this against the IMU stamps is dropped, s
MAX_LAG_S = 1.0
#: epochs that may wait for the IMU stream
QUEUE = 100
#: history kept for the coarse stage, s
KEEP_S = 120.0
#: the coarse stage takes the last heading if it is at most this old at the window end, s
COARSE_MAX_AGE_S = 2.0
#: above this heading 1-sigma the filter takes the heading directly (no linear update), rad
LINEAR_MAX = math.radians(10.0)


@dataclass
class HeadingFix:
    """One heading epoch: stamp (s), vehicle yaw (rad, REP-103, ENU) and its variance (rad^2)."""

    t: float
    yaw: float
    var: float


def wrap(a):
    """Angle ``a`` (rad) wrapped into (-pi, pi], as a float (:func:`~..nav.frames.wrap_pi`)."""
    return float(wrap_pi(a))


def yaw_of(C_b_n):
    """REP-103 yaw (rad) of ``C_b_n`` (3, 3) (:func:`~..nav.frames.dcm_to_euler`)."""
    return float(dcm_to_euler(C_b_n)[2])


def yaw_row(C_b_n):
    """``d yaw / d phi`` (3,) for ``C_b_n <- (I + [phi x]) C_b_n``, phi about E, N, U.

    ``yaw = atan2(C_10, C_00)``; ``dC = [phi x] C`` gives ``dC_10 = phi_U C_00 - phi_E
    C_20`` and ``dC_00 = -phi_U C_10 + phi_N C_20``, so ``d yaw = phi_U - C_20 (C_00 phi_E
    + C_10 phi_N) / (C_00^2 + C_10^2)``: the up axis, plus the tilts' share when the body
    is pitched.
    """
    c00, c10, c20 = C_b_n[0, 0], C_b_n[1, 0], C_b_n[2, 0]
    h2 = max(c00 * c00 + c10 * c10, 1e-12)
    return np.array([-c20 * c00 / h2, -c20 * c10 / h2, 1.0])


def yaw_update(x, P, i_phi, C_b_n, yaw, var, max_nis=None):
    """EKF update of ``x`` (n,), ``P`` (n, n) with a measured vehicle ``yaw`` (rad).

    ``i_phi``: the misalignment slice of the state (E, N, U, rad), which corrects ``C_b_n``
    as :func:`yaw_row` says; ``var`` the measurement variance (rad^2); ``max_nis`` the gate
    (None: off). Returns ``(x, P, y, S, accepted)``: the innovation ``y`` and its variance
    ``S``; a rejected epoch returns ``x``, ``P`` unchanged. Joseph form.
    """
    n = len(x)
    H = np.zeros(n)
    H[np.arange(n)[i_phi]] = yaw_row(C_b_n)
    return heading_update(x, P, H, wrap(yaw - yaw_of(C_b_n) - float(H @ x)), var, max_nis)


def heading_update(x, P, H, y, var, max_nis=None):
    """Scalar EKF update of ``x`` (n,), ``P`` (n, n): row ``H`` (n,), innovation ``y`` (rad).

    ``var``: the measurement variance (rad^2); ``max_nis``: the gate (None: off). Returns
    ``(x, P, y, S, accepted)``; a rejected epoch returns ``x``, ``P`` unchanged. Joseph form.
    """
    PHt = P @ H
    S = float(H @ PHt) + var
    if max_nis is not None and y * y / S > max_nis:
        return x, P, y, S, False
    K = PHt / S
    A = np.eye(len(x)) - np.outer(K, H)
    P = A @ P @ A.T + var * np.outer(K, K)
    return x + K * y, 0.5 * (P + P.T), y, S, True


def take_heading(C_b_n, P, k_up, yaw, var):
    """Take a measured ``yaw`` directly: ``(C_b_n', P')`` with the heading row reset.

    ``C_b_n`` is turned about the up axis by the yaw difference (its yaw becomes ``yaw``,
    roll and pitch kept); ``P``'s heading row and column ``k_up`` are cleared and its
    variance set to ``var``: the filter's own heading was beyond its linear range.
    """
    d = wrap(yaw - yaw_of(C_b_n))
    c, s = math.cos(d), math.sin(d)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    P = np.array(P, dtype=float)
    P[k_up, :] = P[:, k_up] = 0.0
    P[k_up, k_up] = var
    return Rz @ C_b_n, P


class HeadingBuffer:
    """History and pending queue of the accepted heading epochs (module docstring)."""

    def __init__(self, offset_rad=0.0):
        self.offset = float(offset_rad)
        self.reset()

    def reset(self):
        """Forget every epoch and count."""
        self.history = deque()
        self.pending = deque(maxlen=QUEUE)
        self.counts = {'used': 0, 'taken': 0, 'rejected': 0, 'late': 0, 'before_start': 0,
                       'ahead_of_imu': 0, 'queue_full': 0}
        #: the innovation (rad) and its sigma of the last epoch given to the filter
        self.last_innovation = None

    @property
    def active(self):
        """Tell whether any heading epoch has arrived."""
        return bool(self.history)

    def add(self, t, yaw_source, var, t_imu, queue):
        """Record a source yaw (rad) with variance ``var`` (rad^2); ``queue``: a filter runs."""
        t = float(t)
        if t_imu is not None and t > t_imu + MAX_LEAD_S:
            self.counts['ahead_of_imu'] += 1
            return
        fix = HeadingFix(t, wrap(float(yaw_source) - self.offset), float(var))
        self.history.append(fix)
        while self.history and self.history[0].t < t - KEEP_S:
            self.history.popleft()
        if queue:
            if len(self.pending) == self.pending.maxlen:
                self.counts['queue_full'] += 1
            self.pending.append(fix)

    def latest(self, t_end):
        """Return the last epoch at most :data:`COARSE_MAX_AGE_S` before ``t_end``, or None."""
        for fix in reversed(self.history):
            if fix.t <= t_end + 1e-9:
                return fix if fix.t >= t_end - COARSE_MAX_AGE_S else None
        return None

    def requeue(self, t0, t1):
        """Queue again the epochs stamped in (``t0``, ``t1``]: a stage reprocesses that span.

        They go before those still queued (stamped after ``t1``), in stamp order; the
        queue grows to hold them and shrinks back to :data:`QUEUE` as they are taken.
        """
        again = [fix for fix in self.history if t0 < fix.t <= t1 + 1e-9]
        later = [fix for fix in self.pending if fix.t > t1 + 1e-9]
        self.pending = deque(again + later, maxlen=max(QUEUE, len(again) + len(later)))

    def drop_pending(self, t):
        """Forget the queued epochs stamped at or before ``t`` (coarse alignment's history)."""
        while self.pending and self.pending[0].t <= t + 1e-9:
            self.pending.popleft()

    def due(self, t):
        """Tell whether a queued epoch is stamped at or before ``t``."""
        return bool(self.pending) and self.pending[0].t <= t + 1e-9

    def next_due_index(self, t, k):
        """Index of the first stamp of ``t`` (from ``k``) a queued epoch is due at, or None."""
        if not self.pending:
            return None
        i = k + int(np.searchsorted(t[k:], self.pending[0].t - 1e-9, side='left'))
        return i if i < len(t) else None

    def pop_due(self, t_now, t_start):
        """Return the next usable queued epoch up to ``t_now`` (or None); stale ones counted."""
        while self.due(t_now):
            fix = self.pending.popleft()
            if self.pending.maxlen > QUEUE >= len(self.pending):   # the requeued are taken
                self.pending = deque(self.pending, maxlen=QUEUE)
            if fix.t <= t_start:
                self.counts['before_start'] += 1
            elif t_now - fix.t > MAX_LAG_S:
                self.counts['late'] += 1
            else:
                return fix
        return None


def coarse_heading(C_b_n, sigma, yaw, var):
    """Put an external heading into a coarse attitude: ``(C_b_n', sigma')``.

    The coarse tilt is kept, the yaw becomes ``yaw`` (rad) and the heading 1-sigma that of
    the source (``var`` rad^2; ``sigma`` (3,) rad).
    """
    C, _ = take_heading(C_b_n, np.eye(3), 2, yaw, var)
    sigma = np.array(sigma, dtype=float)
    sigma[2] = math.sqrt(var)
    return C, sigma

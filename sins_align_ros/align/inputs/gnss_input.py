"""Checks of GNSS fixes and velocities, shared by the node and the replay tool.

Rules, each counted by reason (keys of :attr:`GnssInput.counts`); a rejected
message is not given to the pipeline:

* ``no_fix``: status ``STATUS_NO_FIX`` (-1); ``status_unknown``: ``STATUS_UNKNOWN``
  (-2) or any other value below ``STATUS_FIX``;
* ``nan``: a non-finite stamp, position or velocity;
* ``out_of_range``: latitude outside +-90 deg, longitude outside +-180 deg, height
  outside -1 km..100 km, or a speed above 500 m/s;
* ``stamp_not_increasing``: a stamp equal to or before the previous message of the
  same kind (a repeated or out-of-order message; applying it would count the
  same epoch twice), unless more than :data:`CLOCK_JUMP_S` earlier: then the
  clock jumped back (``clock_jump_back``) and the message is accepted;
* ``covariance_too_large``: a reported horizontal sigma above 1 km (position) or
  100 m/s (velocity): the receiver says the solution is useless;
* heading/in (an external heading): ``nan`` (a non-finite stamp or yaw), ``no_orientation``
  (the message says it has none: ``orientation_covariance[0] = -1``);
  ``stamp_not_increasing`` / ``clock_jump_back`` as for the others; a yaw variance that is
  not finite or not in (1e-10, (pi/2)^2] rad^2 is ``covariance_implausible`` (the
  configured ``heading_sigma_deg`` is used);
* ``covariance_implausible`` (accepted): a reported variance that is not finite,
  zero or negative, or below (1 mm)^2 or (1 mm/s)^2: ignored, the configured sigma
  is used instead. (A velocity covariance that is all zero means unknown, as
  TwistWithCovariance has no covariance type; NavSatFix says unknown by its type.)

Position jumps and outliers of an otherwise valid fix are the filter's to judge
(the innovation gate of the moving-base filters; the median of the recent fixes
for the stationary models).
"""
import math
from collections import Counter, deque

import numpy as np

STATUS_FIX = 0
STATUS_NO_FIX = -1
#: a GNSS stamp this much before the previous one is a clock jump, not disorder, s
CLOCK_JUMP_S = 5.0
#: plausible reported variances: position m^2, velocity (m/s)^2
POS_VAR_RANGE = (1e-6, 1e6)
VEL_VAR_RANGE = (1e-6, 1e4)
#: plausible reported yaw variances, rad^2
YAW_VAR_RANGE = (1e-10, (np.pi / 2.0) ** 2)


def reported_variances(var, lo=0.0):
    """East/north variances (2,) as reported, or None unless both are finite and > ``lo``."""
    if var is None:
        return None
    return _plausible(np.asarray(var, dtype=float)[:2], lo)


def _plausible(v, lo):
    """Return ``v`` (the first two reported variances) if both are finite and > ``lo``, else None.

    Two floats compared in Python (a message's check, thousands of times in a replay):
    ``lo < x < inf`` is false for NaN and infinities, as the finiteness test is.
    """
    if len(v) != 2:
        return None
    a, b = v.tolist()
    return v if lo < a < math.inf and lo < b < math.inf else None


class GnssInput:
    """Stateful checker; see the module docstring."""

    def __init__(self):
        self.counts = Counter()
        self.notices = deque(maxlen=100)
        self.last_reason = ''
        self._t_last = {'fix': None, 'vel': None, 'heading': None}

    def pop_notices(self):
        """Return and clear the queued ``(key, text)`` notices."""
        out = list(self.notices)
        self.notices.clear()
        return out

    def _note(self, key, text):
        self.counts[key] += 1
        self.last_reason = text
        self.notices.append((key, text))

    def _stamp_ok(self, kind, t):
        last = self._t_last[kind]
        if last is not None and t <= last:
            if t < last - CLOCK_JUMP_S:
                self._note('clock_jump_back', f'gnss {kind} stamp jumped back by '
                                              f'{last - t:.1f} s')
            else:
                self._note('stamp_not_increasing', f'gnss {kind} stamp not increasing '
                                                   f'(dt = {(t - last) * 1e3:.1f} ms): skipped')
                return False
        self._t_last[kind] = t
        return True

    def _variances(self, kind, var, rng):
        if var is None:
            return None
        v = np.asarray(var, dtype=float)[:2]
        if kind == 'vel' and not any(v.tolist()):
            return None               # TwistWithCovariance has no type: all zero is unknown
        v = _plausible(v, rng[0])
        if v is None:
            self._note('covariance_implausible', f'gnss {kind} covariance {list(var)[:2]} is '
                                                 'not plausible: configured sigma used')
            return None
        if max(v.tolist()) > rng[1]:
            self._note('covariance_too_large', f'gnss {kind} reported sigma '
                                               f'{np.sqrt(v.max()):.3g} is too large: skipped')
            return False
        return v

    def fix(self, t, status, lat_deg, lon_deg, h, pos_var=None):
        """Check a NavSatFix; returns ``pos_var`` to use (None: the configured sigma), or False."""
        if status < STATUS_FIX:
            if status == STATUS_NO_FIX:
                self._note('no_fix', 'gnss/fix status NO_FIX: skipped')
            else:
                self._note('status_unknown', f'gnss/fix status {status} (unknown): skipped')
            return False
        if not (math.isfinite(t) and math.isfinite(lat_deg) and math.isfinite(lon_deg)
                and math.isfinite(h)):
            self._note('nan', 'non-finite value in gnss/fix: skipped')
            return False
        if abs(lat_deg) > 90.0 or abs(lon_deg) > 180.0 or not -1e3 <= h <= 1e5:
            self._note('out_of_range', f'gnss/fix position {lat_deg:.6g}, {lon_deg:.6g} deg, '
                                       f'{h:.6g} m is out of range: skipped')
            return False
        return self._accept('fix', t, pos_var, POS_VAR_RANGE)

    def velocity(self, t, v_n, vel_var=None):
        """Check an ENU velocity; returns ``vel_var`` to use (None: configured), or False."""
        v = np.asarray(v_n, dtype=float).ravel().tolist()
        speed_sq = sum(x * x for x in v)    # inf when it overflows (no numpy warning)
        if not (math.isfinite(t) and all(map(math.isfinite, v))):
            self._note('nan', 'non-finite value in gnss/vel: skipped')
            return False
        if math.sqrt(speed_sq) > 500.0:     # np.linalg.norm's arithmetic
            self._note('out_of_range', f'gnss/vel speed {math.sqrt(speed_sq):.4g} m/s is out '
                                       'of range: skipped')
            return False
        return self._accept('vel', t, vel_var, VEL_VAR_RANGE)

    def heading(self, t, yaw, yaw_var, has_orientation=True):
        """Check an external yaw (rad): return its variance, None (configured) or False."""
        if not has_orientation:
            self._note('no_orientation', 'heading/in carries no orientation '
                                         '(orientation_covariance[0] = -1): skipped')
            return False
        if not (np.isfinite(t) and np.isfinite(yaw)):
            self._note('nan', 'non-finite value in heading/in: skipped')
            return False
        if yaw_var is not None and not (np.isfinite(yaw_var)
                                        and YAW_VAR_RANGE[0] < yaw_var <= YAW_VAR_RANGE[1]):
            self._note('covariance_implausible', f'heading/in yaw variance {yaw_var:.3g} is '
                                                 'not plausible: heading_sigma_deg used')
            yaw_var = None
        if not self._stamp_ok('heading', t):
            return False
        self.counts['accepted_heading'] += 1
        return yaw_var

    def _accept(self, kind, t, var, rng):
        """Check what fixes and velocities share: the reported variances, then the stamp."""
        v = self._variances(kind, var, rng)
        if v is False or not self._stamp_ok(kind, t):
            return False
        self.counts[f'accepted_{kind}'] += 1
        return v

    @property
    def rejected(self):
        """Number of GNSS messages skipped."""
        return sum(v for k, v in self.counts.items()
                   if k not in ('accepted_fix', 'accepted_vel', 'accepted_heading',
                                'clock_jump_back',
                                'covariance_implausible'))

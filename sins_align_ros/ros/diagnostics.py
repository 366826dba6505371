"""The alignment node's /diagnostics status and its rate-limited input-fault log.

Follows diagnostic_updater's conventions (not available as a Python package here):
one DiagnosticStatus named ``<node>: alignment`` per period, its level the worst of
the period, its message the conditions joined by ``'; '``, its values the pipeline's
key figures and the input counts as KeyValues.
"""
import time
from collections import Counter

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

#: each input-fault reason is logged at most once per this many seconds (wall time)
LOG_PERIOD_S = 5.0


class FaultLog:
    """Input faults of the current diagnostic period; each reason logged once per period."""

    def __init__(self, logger):
        self.logger = logger
        self.counts = Counter()       # (source, key) -> occurrences in this period
        self.text = {}                # (source, key) -> last text
        self._logged = {}             # (source, key) -> (wall time of last line, count since)

    def add(self, source, key, text):
        """Count a fault; log it at most once per :data:`LOG_PERIOD_S` with the repeat count."""
        key = (source, key)
        self.counts[key] += 1
        self.text[key] = text
        now = time.monotonic()
        last, n = self._logged.get(key, (None, 0))
        if last is None or now - last >= LOG_PERIOD_S:
            more = f' ({n + 1} times in {now - last:.0f} s)' if last is not None and n else ''
            self.logger.warn(f'{source}: {text}{more}')
            self._logged[key] = (now, 0)
        else:
            self._logged[key] = (last, n + 1)

    def lines(self):
        """Return the period's faults as text lines and forget them."""
        out = [f'{k[0]}: {n} x {self.text[k]}' for k, n in self.counts.items()]
        self.counts.clear()
        return out


def alignment_status(name, hardware_id, s, period, coarse_duration, imu_age, imu_period,
                     faults, conditions, events, values):
    """Build the DiagnosticStatus.

    ``s`` the pipeline status; ``imu_age`` seconds since the last IMU message (None
    before the first); ``imu_period`` (received, accepted) IMU messages of the period;
    ``faults`` text lines; ``conditions`` ``[(level, text)]`` (1 warn, 2 error);
    ``events`` the period's restarts (the last is shown); ``values`` extra KeyValues.
    """
    st = DiagnosticStatus(name=name, hardware_id=hardware_id)
    phase = s['phase']
    level, msgs = DiagnosticStatus.OK, []
    if phase == 'waiting':
        level = DiagnosticStatus.WARN
        msgs.append('waiting for IMU data on imu/data_raw')
    elif phase == 'coarse':
        msgs.append(f"coarse alignment {s['elapsed_s']:.0f}/{coarse_duration:.0f} s")
    else:
        msgs.append(f"{phase}: 1-sigma roll {s['sigma_roll_deg'] * 60:.2f}', pitch "
                    f"{s['sigma_pitch_deg'] * 60:.2f}', yaw {s['sigma_yaw_deg'] * 60:.2f}'")
    if imu_age is not None and imu_age > max(2.0, 3 * period):
        level = DiagnosticStatus.ERROR
        msgs.insert(0, f'no IMU data for {imu_age:.1f} s')
    received, accepted = imu_period
    if received and not accepted:
        level = DiagnosticStatus.ERROR
        msgs.insert(0, f'none of the {received} IMU messages of the last {period:g} s was usable')
    for line in faults:
        level = max(level, DiagnosticStatus.WARN)
        msgs.append(line)
    for lvl, text in conditions:
        level = max(level, DiagnosticStatus.ERROR if lvl >= 2 else DiagnosticStatus.WARN)
        msgs.append(text)
    if events:
        level = max(level, DiagnosticStatus.WARN)
        msgs.append(events[-1])
    st.level = level
    st.message = '; '.join(msgs)
    all_values = dict(s)
    all_values.update(values)
    st.values = [KeyValue(key=k, value=_fmt(v)) for k, v in all_values.items()]
    return st


def _fmt(v):
    if isinstance(v, float):
        return f'{v:.6g}'
    if isinstance(v, (list, tuple, np.ndarray)):
        return ' '.join(_fmt(float(x)) for x in v)
    return str(v)

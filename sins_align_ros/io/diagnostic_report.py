"""What the alignment node says on /diagnostics, as plain values (no rclpy).

Follows diagnostic_updater's conventions (not available as a Python package here):
one DiagnosticStatus named ``<node's fully qualified name>: alignment`` per period
(``/robot1/alignment_node: alignment``), its level the worst of the period, its message
the conditions joined by ``'; '`` and cut to :data:`MESSAGE_MAX` characters (angles in
degrees), its values the pipeline's key figures, the input counts and the message's
untruncated items (``details``) as KeyValues. A pipeline note or a restart is in the
message for :data:`NOTE_HOLD_S` after it happened (:class:`RecentNotes`), then only in
the values (``notes``, ``last_restart``).

A report is a :class:`StatusReport` (level, message, KeyValue pairs): the node turns it
into a ``diagnostic_msgs/DiagnosticStatus`` (:mod:`sins_align_ros.ros.diagnostics`), the
replay's result bag into the same message with its own type store
(:mod:`.result_bag`). Wall times come from a ``clock`` (``time.monotonic`` in the node;
the data's time in a replay).
"""
import math
import time
from collections import Counter, namedtuple

import numpy as np

from ..units import DEG
from .node_status import NO_IMU, imu_stopped

#: the levels of ``diagnostic_msgs/DiagnosticStatus``
OK, WARN, ERROR = 0, 1, 2
#: one period's report: ``level`` (:data:`OK`, :data:`WARN`, :data:`ERROR`), ``name``,
#: ``hardware_id``, ``message`` and ``values`` ``[(key, text)]``
StatusReport = namedtuple('StatusReport', 'level name hardware_id message values')

#: the session's input-notice sources as /diagnostics names them
FAULT_SOURCES = {'imu': 'imu/data_raw', 'gnss': 'gnss'}
#: each input-fault reason is logged at most once per this many seconds (wall time)
LOG_PERIOD_S = 5.0
#: the longest /diagnostics message, characters (the rest: the value ``details``)
MESSAGE_MAX = 200
_CUT = ' [...]'
#: a pipeline note or a restart stays in the message this long (wall time, s), at least
#: for the period it happened in
NOTE_HOLD_S = 3.0
#: a 1-sigma at least this is an unknown angle's (sqrt(pi^2 / 3) rad, less round-off), deg
UNKNOWN_SIGMA_DEG = 0.999 * math.pi / math.sqrt(3.0) / DEG


class RecentNotes:
    """Texts shown in the message for :data:`NOTE_HOLD_S` after they appeared (once at least).

    ``clock()``: the time now, s.
    """

    def __init__(self, clock=time.monotonic):
        self.clock = clock
        self._source = None         # the list last read (a pipeline's warnings)
        self._seen = 0
        self._held = []             # [wall time, text, shown]

    def add(self, texts, now=None):
        """Take ``texts`` as new (the restarts of the period)."""
        now = self.clock() if now is None else now
        self._held.extend([now, t, False] for t in texts)

    def read(self, source, now=None):
        """Take what was appended to list ``source`` since the last call (a new list: all)."""
        if source is not self._source:
            self._source, self._seen = source, 0
        self.add(source[self._seen:], now)
        self._seen = len(source)

    def current(self, now=None):
        """Return the texts to show now, oldest first; each is shown once at least."""
        now = self.clock() if now is None else now
        self._held = [h for h in self._held if not h[2] or now - h[0] < NOTE_HOLD_S]
        for h in self._held:
            h[2] = True
        return [h[1] for h in self._held]


class FaultLog:
    """Input faults of the current diagnostic period; each reason logged once per period.

    ``logger``: has ``warn(text)``; ``clock()``: the time now, s.
    """

    def __init__(self, logger, clock=time.monotonic):
        self.logger, self.clock = logger, clock
        self.counts = Counter()       # (source, key) -> occurrences in this period
        self.text = {}                # (source, key) -> last text
        self._logged = {}             # (source, key) -> (wall time of last line, count since)

    def add(self, source, key, text):
        """Count a fault; log it at most once per :data:`LOG_PERIOD_S` with the repeat count."""
        key = (source, key)
        self.counts[key] += 1
        self.text[key] = text
        now = self.clock()
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


def alignment_status(name, hardware_id, s, state, period, coarse_duration, imu_age, imu_period,
                     faults, conditions, notes, values):
    """Return the period's :class:`StatusReport`.

    ``s`` the pipeline status; ``state`` the published typed state
    (:func:`~.status.typed_state`: its phase and reason are the status's); ``imu_age``
    seconds since the last IMU message (None before the first); ``imu_period`` (received,
    accepted) IMU messages of the period; ``faults`` text lines; ``conditions``
    ``[(level, text)]`` (1 warn, 2 error); ``notes`` the restarts and the pipeline's notes
    to show (:class:`RecentNotes`); ``values`` extra KeyValues.

    The message is at most :data:`MESSAGE_MAX` characters (:func:`cap_message`); the
    untruncated items are the value ``details``.
    """
    phase, reason = state['phase'], state['reason']
    level, msgs = OK, []
    if s['phase'] == 'waiting':
        level = WARN
        msgs.append('waiting for IMU data on imu/data_raw')
    elif phase == 'coarse':
        window = s.get('coarse_window_s', coarse_duration)
        msgs.append(f"coarse alignment {s['elapsed_s']:.0f}/{window:.0f} s")
    else:
        head = f'{phase}, {reason}' if reason and reason != NO_IMU else phase
        sig = [_deg(s['sigma_roll_deg']), _deg(s['sigma_pitch_deg']),
               _deg(s['sigma_yaw_deg'], s.get('heading_observable') is False)]
        msgs.append(f'{head}: 1-sigma roll {sig[0]}, pitch {sig[1]}, yaw {sig[2]} deg')
        if 'unknown' in sig:        # a condition that holds: WARN for as long as it holds
            level = WARN
    if imu_age is not None and imu_stopped(imu_age, period):
        level = ERROR
        msgs.insert(0, f'no IMU data for {imu_age:.1f} s')
    received, accepted = imu_period
    if received and not accepted:
        level = ERROR
        msgs.insert(0, f'none of the {received} IMU messages of the last {period:g} s was usable')
    for lvl, text in conditions:
        level = max(level, ERROR if lvl >= 2 else WARN)
        msgs.append(text)
    for text in notes:
        level = max(level, WARN)
        msgs.append(text)
    for line in faults:
        level = max(level, WARN)
        msgs.append(line)
    all_values = dict(s)
    all_values.update(values)
    all_values.update(phase=phase, reason=reason, pipeline_phase=s['phase'],
                      details=' | '.join(msgs))
    return StatusReport(level, name, hardware_id, cap_message(msgs),
                        [(k, _fmt(v)) for k, v in all_values.items()])


def cap_message(items, limit=MESSAGE_MAX):
    """Join ``items`` with ``'; '``; cut to ``limit`` characters, saying so, when longer."""
    text = '; '.join(items)
    if len(text) <= limit:
        return text
    return text[:limit - len(_CUT)].rstrip('; ,') + _CUT


def _deg(sigma_deg, unknown=False):
    """Format a 1-sigma in degrees, three significant digits (``unknown``: an unknown angle)."""
    if unknown or sigma_deg >= UNKNOWN_SIGMA_DEG:
        return 'unknown'
    return f'{sigma_deg:.3g}'


def _fmt(v):
    if isinstance(v, float):
        return f'{v:.6g}'
    if isinstance(v, (list, tuple, np.ndarray)):
        return ' '.join(_fmt(float(x)) for x in v)
    return str(v)


def input_values(session, counts, odom):
    """Return the node's KeyValues: input counts, rejections, the ``~/odom`` origin."""
    imu_counts, gnss_counts = session.input_counts()
    values = {f'imu_{k}': v for k, v in imu_counts.items()}
    values.update({f'gnss_input_{k}': v for k, v in gnss_counts.items()})
    values.update({f'{k}_count': v for k, v in counts.items()})
    values['imu_rejected_count'] = session.imu_rejected
    if odom.origin is not None:
        lat, lon, h = odom.origin          # full precision (1e-9 deg ~ 0.1 mm)
        values.update({'odom_origin_lat_deg': f'{np.degrees(lat):.9f}',
                       'odom_origin_lon_deg': f'{np.degrees(lon):.9f}',
                       'odom_origin_h_m': f'{h:.3f}'})
    values['gnss_rejected_count'] = session.gnss_rejected
    return values


class PeriodReport:
    """What the node gathers between two /diagnostics reports and says in the next.

    ``faults`` the input faults (:class:`FaultLog`), ``notes`` the restarts and pipeline
    notes to show (:class:`RecentNotes`), ``last_restart`` the text of the last restart,
    ``imu`` [received, usable] IMU messages of the period. ``logger`` has ``warn(text)``;
    ``clock()`` is the time now, s.
    """

    def __init__(self, logger, clock=time.monotonic):
        self.faults = FaultLog(logger, clock)
        self.notes = RecentNotes(clock)
        self.last_restart = ''
        self.imu = [0, 0]

    def restarted(self, text):
        """Take a restart of the session (its log text)."""
        self.notes.add([text])
        self.last_restart = text

    def status(self, name, hardware_id, session, s, state, p, imu_age, errors, counts, odom,
               noise_file=''):
        """Return the period's :class:`StatusReport` (:func:`alignment_status`); start anew.

        ``session`` the alignment session (its read-outs), ``s`` its status, ``state`` the
        typed state published, ``p`` the node's parameter values, ``imu_age`` seconds since
        the last IMU message (None before the first), ``errors`` the node's
        :class:`~sins_align_ros.ros.diagnostics.CallbackErrors` (None: no callbacks, as in
        a replay), ``counts`` its message counts, ``odom`` the ``~/odom``
        origin (:class:`.odometry.OdometryFrame`), ``noise_file`` what the IMU noise file
        said and set (the ``imu_noise_file`` KeyValue; none without a file).
        """
        self.notes.read(session.warnings)
        values = input_values(session, counts, odom)
        if noise_file:
            values['imu_noise_file'] = noise_file
        values.update(callback_error_count=0 if errors is None else errors.count,
                      notes='; '.join(session.warnings), last_restart=self.last_restart)
        conditions = ([] if errors is None else errors.lines()) + session.conditions()
        st = alignment_status(name, hardware_id, s, state, p['diagnostic_period'],
                              p['coarse_duration'], imu_age, self.imu, self.faults.lines(),
                              conditions, self.notes.current(), values)
        self.imu = [0, 0]
        return st

"""The replay's result bag: the alignment node's topics as a rosbag2 in MCAP storage.

``sins_align_replay INPUT --out RESULT.mcap`` writes the folder ``RESULT/`` holding
``RESULT.mcap`` and ``metadata.yaml``: what ``ros2 bag record -s mcap -o RESULT`` makes.
``ros2 bag play RESULT`` and ``ros2 bag info RESULT`` take the folder; Foxglove and
PlotJuggler open ``RESULT/RESULT.mcap`` (profile ``ros2``, each schema a ``ros2msg``
definition with its dependencies, messages CDR). docs/replay.md#result-bag.

The topics are the node's, under its default name (``/alignment_node``), with its
message types, contents and stamps (the same code: :func:`.cdr.echo_bodies`,
:mod:`.odometry`, :mod:`.node_status`, :mod:`.diagnostic_report`):

* ``/imu/data`` (sensor_msgs/Imu) per output row, stamped with its sample; the rates and
  accelerations are the input's (in the vehicle frame with a mounting rotation), their
  covariances zero (unknown: the replay does not keep the input's);
* ``/alignment_node/euler`` (geometry_msgs/Vector3Stamped) per row with an attitude;
* ``/alignment_node/odom`` (nav_msgs/Odometry) with the navigation filters;
* ``/diagnostics`` (diagnostic_msgs/DiagnosticArray) every ``diagnostic_period`` of data
  time, stamped at the end of the period: the node's report of the inputs before it;
* ``/alignment_node/phase``, ``reason`` (std_msgs/String), ``tilt_ready``,
  ``heading_ready`` (std_msgs/Bool) at the start and on change, offered transient local
  as the node does, so that ``ros2 bag play`` latches them.

Each message's log time is its data stamp (a replay has no wall clock). The bag is
written beside the target and moved into place when complete; an existing result bag
(a folder with ``metadata.yaml``) is replaced, anything else there is refused.
"""
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ..align import params as prm
from . import cdr
from .diagnostic_report import FAULT_SOURCES, PeriodReport
from .node_status import known_euler, typed_state
from .odometry import OdometryFrame, odometry_bodies

#: the node's default name: its private topics' namespace and the diagnostics' name
NODE = '/alignment_node'
_TYPED = (('phase', 'std_msgs/msg/String'), ('reason', 'std_msgs/msg/String'),
          ('tilt_ready', 'std_msgs/msg/Bool'), ('heading_ready', 'std_msgs/msg/Bool'))


def bag_folder(path):
    """Return the folder a result bag ``path`` names (``RESULT.mcap`` -> ``RESULT``)."""
    p = Path(path)
    return p.with_suffix('') if p.suffix.lower() == '.mcap' else p


class _Quiet:
    """A logger that drops lines (the replay says input faults itself)."""

    def warn(self, text):
        """Drop ``text``."""


def _latched_qos():
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                    QosReliability, QosTime)
    zero = QosTime(0, 0)
    return [Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE,
                QosDurability.TRANSIENT_LOCAL, zero, zero, QosLiveliness.AUTOMATIC, zero,
                False)]


def _stamp(t):
    """Return ``(8 serialized stamp bytes, log time ns)`` of data time ``t`` s."""
    ns = int(round(t * 1e9))
    return (ns // 10 ** 9).to_bytes(4, 'little', signed=True) + \
        (ns % 10 ** 9).to_bytes(4, 'little'), ns


class ResultBag:
    """Writes the node's topics for a replay; :meth:`close` completes the bag.

    ``path`` the bag (:func:`bag_folder`); ``node_values`` the node-only parameters given
    (``diagnostic_period``, ``base_frame_id``, ``odom_frame_id``; the rest defaults);
    ``coarse_duration`` s (said in the coarse phase's message); ``imu_frame`` the
    input's ``frame_id``.

    The replay calls :meth:`before` with the data time of each input it is about to
    give the session (a report is due at each period's end), :meth:`rows` with each
    output, :meth:`fault` with each input notice and :meth:`after` after each call.
    """

    def __init__(self, path, node_values=None, coarse_duration=60.0, imu_frame='imu_link'):
        from rosbags.rosbag2 import StoragePlugin, Writer

        from .bag import _typestore
        self.p = {q.name: q.default for q in prm.NODE_PARAMS}
        self.p.update(node_values or {})
        self.p['coarse_duration'] = coarse_duration
        self.imu_frame = imu_frame or 'imu_link'
        self.target = bag_folder(path)
        if self.target.exists() and not (self.target / 'metadata.yaml').is_file():
            raise OSError(f'{self.target} exists and is not a rosbag2 folder')
        self._tmp = Path(tempfile.mkdtemp(prefix=f'.{self.target.name}.',
                                          dir=self.target.parent))
        self.ts = _typestore()
        self.writer = Writer(self._tmp / self.target.name, version=8,
                             storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        add = self.writer.add_connection
        self.c_imu = add('/imu/data', 'sensor_msgs/msg/Imu', typestore=self.ts)
        self.c_euler = add(f'{NODE}/euler', 'geometry_msgs/msg/Vector3Stamped',
                           typestore=self.ts)
        self.c_diag = add('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray',
                          typestore=self.ts)
        self.c_typed = {name: (add(f'{NODE}/{name}', kind, typestore=self.ts,
                                   offered_qos_profiles=_latched_qos()), kind)
                        for name, kind in _TYPED}
        self.c_odom = None
        self.topics = {'/imu/data', f'{NODE}/euler', f'{NODE}/odom', '/diagnostics'} | {
            f'{NODE}/{name}' for name, _ in _TYPED}
        self.report = PeriodReport(_Quiet(), clock=lambda: self.now)
        self.odom = OdometryFrame()
        self.now, self.last_imu, self.next_report = None, None, None
        self.typed_last, self.accepted = {}, 0
        #: the session's phase when the typed values were last written
        self.typed_phase = None

    # -- what the replay calls -------------------------------------------------------------
    def pieces(self, t, k0, k1):
        """Yield ``(a, b)``: samples ``k0:k1`` of stamps ``t`` cut at each period's end."""
        while k0 < k1:
            if self.next_report is None:
                self.next_report = t[k0] + self.p['diagnostic_period']
            late = np.flatnonzero(t[k0:k1] > self.next_report)
            b = k1 if len(late) == 0 else k0 + max(1, int(late[0]))
            yield k0, b
            k0 = b

    def before(self, t, session):
        """Write the reports due before data time ``t``, the next input's stamp."""
        if self.now is None:
            self.now = t
            self._typed(session, force=True)
        if self.next_report is None:
            self.next_report = t + self.p['diagnostic_period']
        while t > self.next_report:
            self.now = self.next_report
            self._diagnostics(session)
            self.next_report += self.p['diagnostic_period']
        self.now = max(self.now, t)

    def rows(self, out, w_b, f_b, session):
        """Write ``imu/data``, ``~/euler`` (and ``~/odom``) for the rows of ``out``.

        ``w_b``, ``f_b`` (K, 3): the rate and specific force of each row's sample.
        """
        if not len(out.t):
            return
        src = np.zeros((len(out.t), cdr.IMU_DOUBLES))
        src[:, cdr.IMU_RATE], src[:, cdr.IMU_ACCELERATION] = w_b, f_b
        frame, C_s_v = self.imu_frame, session.C_s_v
        if C_s_v is not None:
            src[:, cdr.IMU_RATE] = src[:, cdr.IMU_RATE] @ C_s_v.T
            src[:, cdr.IMU_ACCELERATION] = src[:, cdr.IMU_ACCELERATION] @ C_s_v.T
            frame = self.p['base_frame_id']
        bodies = cdr.echo_bodies(src, out.q, out.P_phi)
        euler = known_euler(out)
        known = np.isfinite(out.q[:, 0])
        stamps = [_stamp(t) for t in out.t.tolist()]
        write = self.writer.write
        for k, (stamp, ns) in enumerate(stamps):
            head = cdr.header_bytes(stamp, frame)
            write(self.c_imu, ns, head + bodies[k].tobytes())
            if known[k]:
                write(self.c_euler, ns, head + euler[k].tobytes())
            self.last_imu = out.t[k]
        if out.nav is not None:
            self._odometry(out, bodies[:, cdr.IMU_RATE], session.navigation(), stamps, frame)

    def fault(self, source, key, text):
        """Count an input notice of the session for the period's report."""
        self.report.faults.add(FAULT_SOURCES[source], key, text)

    def after(self, session, imu_received=0):
        """Take the session after a call: restarts, the typed status, IMU counts.

        A change of phase is logged at the last row's stamp, when the node, having
        processed the batch, would publish it; the other typed values change with the
        next report, as on the node (its ``_drain``).
        """
        if self.last_imu is not None and self.now is not None:
            self.now = max(self.now, self.last_imu)
        for _, text in session.pop_events():
            self.report.restarted(text)
            self.odom = OdometryFrame()
        accepted = session.imu_accepted
        self.report.imu[0] += imu_received
        self.report.imu[1] += accepted - self.accepted
        self.accepted = accepted
        if session.phase != self.typed_phase:
            self._typed(session)

    def close(self):
        """Complete the bag and move it into place (replacing a previous result bag)."""
        self.writer.close()
        if self.target.exists():
            shutil.rmtree(self.target)
        (self._tmp / self.target.name).rename(self.target)
        shutil.rmtree(self._tmp, ignore_errors=True)

    def abort(self):
        """Drop the unfinished bag."""
        try:
            self.writer.close()
        finally:
            shutil.rmtree(self._tmp, ignore_errors=True)

    def copy_input(self, path, log=lambda m: None):
        """Copy every message of the rosbag2 ``path`` as it is, on its own topic.

        A topic the node's outputs use, or one whose definition the bag lacks and the
        Jazzy type store does not know, is left out (said through ``log``).
        """
        from .bag import raw_messages
        conns, skipped = {}, set()
        for topic, msgtype, msgdef, rihs01, t_ns, raw in raw_messages(path):
            conn = conns.get((topic, msgtype))
            if conn is None:
                if topic in self.topics or (not msgdef and msgtype not in self.ts.types):
                    if topic not in skipped:
                        skipped.add(topic)
                        log(f'input topic {topic} not copied: '
                            + ('an output topic' if topic in self.topics
                               else f'no definition of {msgtype}'))
                    continue
                conn = conns[(topic, msgtype)] = self.writer.add_connection(
                    topic, msgtype, **({'msgdef': msgdef, 'rihs01': rihs01} if msgdef
                                       else {'typestore': self.ts}))
            self.writer.write(conn, t_ns, raw)

    # -- the messages ----------------------------------------------------------------------
    def _typed(self, session, s=None, force=False):
        """Write the typed values that changed; return them (``s``: the status, if read)."""
        state = typed_state(session.status() if s is None else s, stopped=False)
        self.typed_phase = session.phase
        stamp_ns = _stamp(self.now)[1]
        for name, value in state.items():
            if force or self.typed_last.get(name) != value:
                conn, kind = self.c_typed[name]
                self.writer.write(conn, stamp_ns,
                                  self.ts.serialize_cdr(self.ts.types[kind](data=value), kind))
                self.typed_last[name] = value
        return state

    def _diagnostics(self, session):
        s = session.status()
        state = self._typed(session, s)
        age = None if self.last_imu is None else self.now - self.last_imu
        counts = {'imu': session.imu_accepted}
        rep = self.report.status(f'{NODE}: alignment', self.p['imu_frame_id'] or 'imu',
                                 session, s, state, self.p, age, None, counts, self.odom)
        T = self.ts.types
        stamp_ns = _stamp(self.now)[1]
        sec, ns = divmod(stamp_ns, 10 ** 9)
        status = T['diagnostic_msgs/msg/DiagnosticStatus'](
            level=rep.level, name=rep.name, message=rep.message, hardware_id=rep.hardware_id,
            values=[T['diagnostic_msgs/msg/KeyValue'](key=k, value=v) for k, v in rep.values])
        arr = T['diagnostic_msgs/msg/DiagnosticArray'](
            header=T['std_msgs/msg/Header'](
                stamp=T['builtin_interfaces/msg/Time'](sec=sec, nanosec=ns), frame_id=''),
            status=[status])
        self.writer.write(self.c_diag, stamp_ns,
                          self.ts.serialize_cdr(arr, 'diagnostic_msgs/msg/DiagnosticArray'))

    def _odometry(self, out, w_b, nav, stamps, child):
        ok, odo = self.odom.samples(out, nav.P_nav, w_b, nav.gyro_bias, nav.rate_var)
        if odo is None:
            return
        if self.c_odom is None:
            self.c_odom = self.writer.add_connection(f'{NODE}/odom', 'nav_msgs/msg/Odometry',
                                                     typestore=self.ts)
        rows = iter(odometry_bodies(odo))
        frame = self.p['odom_frame_id']
        for (stamp, ns), k in zip(stamps, ok.tolist()):
            if k:
                self.writer.write(self.c_odom, ns,
                                  cdr.odometry_head(stamp, frame, child) + next(rows).tobytes())

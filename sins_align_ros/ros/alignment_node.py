"""alignment_node: SINS initial alignment from sensor_msgs/Imu (and GNSS).

Subscribes ``imu/data_raw`` (sensor_msgs/Imu; best effort with a deep queue so
it takes both best-effort and reliable publishers), ``gnss/fix``
(sensor_msgs/NavSatFix) and ``gnss/vel`` (geometry_msgs/TwistWithCovarianceStamped,
ENU; used by the GNSS-aided filters) and ``heading/in`` (sensor_msgs/Imu: an external
heading, the yaw of its orientation and ``orientation_covariance[8]``; see
docs/alignment_node.md). Every message goes into an
:class:`~sins_align_ros.align.session.AlignmentSession` — the object the replay
tool drives too, with the input checks and restart rules — and the node publishes:

* ``imu/data`` (sensor_msgs/Imu): the input rates plus the orientation body ->
  ENU with ``orientation_covariance`` = the filter's misalignment covariance
  about the ENU axes (rad^2); until coarse alignment is done the orientation is
  marked unknown (``orientation_covariance[0] = -1``, REP-145). With
  ``imu_mounting_rpy_deg`` set, the body is the vehicle: rates, accelerations and their
  covariances are turned into its frame and the frame_id is ``base_frame_id``;
* ``~/euler`` (geometry_msgs/Vector3Stamped): REP-103 roll, pitch, yaw in rad; NaN for
  an angle the node does not know (yaw while the heading is unobservable,
  :func:`.status.known_euler`);
* ``~/phase``, ``~/reason`` (std_msgs/String), ``~/tilt_ready``, ``~/heading_ready``
  (std_msgs/Bool): the typed status, latched, on change (:mod:`.status`);
* ``/diagnostics`` (diagnostic_msgs/DiagnosticArray, status ``<namespace/node>:
  alignment``, :mod:`.diagnostics`);
* ``~/odom`` (nav_msgs/Odometry) with the navigation filters (``kf``, ``vbakf``,
  ``mvbakf``, ``ukf``) and ``continue_navigation``: the GNSS/INS solution at every
  IMU sample from the start of fine alignment on, pose in ``odom_frame_id`` (ENU,
  origin where fine alignment started: ``odom_origin_*`` in the diagnostics), twist
  in the body's frame, the same as ``imu/data``'s (:mod:`sins_align_ros.ros.odometry`).

Bad input is skipped or bridged, counted by reason in the diagnostics' values,
logged at most once per :data:`~.diagnostics.LOG_PERIOD_S` per reason, and raises
the diagnostic level for the period it happened in: WARN, or ERROR when IMU
messages arrived but none was usable.

IMU messages are processed in batches (``imu_batch_period``, default 10 ms of waiting:
at 1 kHz ten samples go through the input checks and the compiled filters at once,
which took the node from 0.39 to 0.22 cores with ``asckf``, bench/results/node_load.md),
then published one by one with their own headers; a GNSS message, a parameter change, a
reset or the period's timer flushes the batch first. They are taken and published as
serialized bytes, decoded by the batch (:mod:`.imu_wire`): no Python message object per
sample.

Service ``~/reset`` (std_srvs/Trigger) restarts the alignment in any phase. An exception
in a callback is handed to :meth:`AlignmentShell.on_callback_error` by the spin loop
(:func:`.runner.spin`): logged, counted, the alignment restarted; the node goes on.
Changing an alignment parameter at runtime (``fine_filter`` included) restarts
the alignment with it; invalid values are refused with the reason.

:class:`AlignmentShell` is the body; :class:`AlignmentNode` starts it at construction,
the managed node of :mod:`.alignment_lifecycle_node` in its lifecycle transitions.
"""
import sys
import time
from collections import Counter, deque

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistWithCovarianceStamped, Vector3Stamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, NavSatFix
from std_srvs.srv import Trigger

from .conversions import set_vector3, stamp_to_sec
from .diagnostics import CallbackErrors, FaultLog, RecentNotes, alignment_status, input_values
from .imu_wire import ImuRows, echo_bodies, header_message
from .messages import odometry_bodies
from .params import declare
from .runner import make_executor, run
from .status import NO_IMU, TypedStatus, imu_stopped, known_euler, typed_state
from ..align import params as prm
from .odometry import OdometryFrame
from ..align.session import AlignmentSession
from ..io import cdr
from ..nav import kernels
from ..nav.frames import quat_to_yaw

NODE_PARAMS = prm.NODE_PARAMS
PARAMS = prm.ALIGNMENT_PARAMS + NODE_PARAMS
_ALIGN_NAMES = {p.name for p in prm.ALIGNMENT_PARAMS}
_BY_NAME = {p.name: p for p in PARAMS}
#: how the input sources are named in log lines and diagnostics
_SOURCES = {'imu': 'imu/data_raw', 'gnss': 'gnss'}


class AlignmentShell:
    """The alignment node's body, a mixin for an rclpy ``Node``; see the module docstring.

    It holds the session, the input callbacks and their batching, the output, the
    ``~/reset`` service and the diagnostics. :class:`AlignmentNode` builds and starts it in
    its constructor; the managed node (:mod:`.alignment_lifecycle_node`) in its lifecycle
    transitions. The pieces: :meth:`_declare_params`, :meth:`_start_session` (builds the
    session from the parameters; ``ValueError`` when they are refused),
    :meth:`_create_outputs` (publishers, ``~/reset``, timers) and :meth:`_subscribe`.
    """

    #: the alignment session (None: a managed node that is not configured)
    session = None

    def _declare_params(self, check=True):
        """Declare the parameters (``check`` false: keep invalid values for a later check)."""
        self.p = declare(self, PARAMS, check=check)
        self._align_values = {k: v for k, v in self.p.items() if k in _ALIGN_NAMES}
        self.add_on_set_parameters_callback(self._check_pipeline_params)
        self.add_post_set_parameters_callback(self._apply_params)
        self.errors = CallbackErrors(self.get_logger())

    def _start_session(self):
        """Build the session from the parameters and start the run's state afresh.

        Raises ``ValueError`` with the reason when the parameters are refused.
        """
        self.session = AlignmentSession(self._align_values)   # ValueError: refused
        # compile the numeric kernels now, not at the coarse window's end amid the data
        self.get_logger().debug(f'numeric kernels ready in {kernels.warm_up():.2f} s')
        #: recent (stamp, message): with pre-processing an output refers to an earlier
        #: sample, published with that sample's header
        self._recent = deque(maxlen=4 * 4096 + 64)
        self.faults = FaultLog(self.get_logger())
        self._period_imu = [0, 0]     # IMU messages received, accepted in this period
        #: restarts and pipeline notes for the message; the last restart; the typed phase
        self.notes, self._last_restart, self._typed_phase = RecentNotes(), '', None
        self.odom = OdometryFrame()
        self._odom_heads = {}                 # (frame, Imu header's frame part): ~/odom's
        #: IMU messages waiting for the batch: (stamp, message); when the first came (s)
        self._batch = []
        self._batch_wall = 0.0
        self._euler = Vector3Stamped()          # re-used: publish serialises at the call
        self.counts = {'imu': 0}
        #: messages received per topic (before any check)
        self.received = Counter()
        self._last_imu_wall = None

    def _subscribe(self):
        """Subscribe to the input topics; return the subscriptions."""
        imu_qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT,
                             history=HistoryPolicy.KEEP_LAST)
        gnss_qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT,
                              history=HistoryPolicy.KEEP_LAST)
        return [self.create_subscription(Imu, 'imu/data_raw', self._on_imu, imu_qos, raw=True),
                self.create_subscription(NavSatFix, 'gnss/fix', self._on_fix, gnss_qos),
                self.create_subscription(TwistWithCovarianceStamped, 'gnss/vel',
                                         self._on_vel, gnss_qos),
                self.create_subscription(Imu, 'heading/in', self._on_heading, gnss_qos)]

    def _create_outputs(self, create_publisher):
        """Create the publishers with ``create_publisher``, ``~/reset`` and the timers.

        Returns the service and the timers (the publishers become ``pub_*``).
        """
        self.pub_imu = create_publisher(Imu, 'imu/data', 50)
        self.pub_euler = create_publisher(Vector3Stamped, '~/euler', 50)
        self.pub_diag = create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.pub_odom = create_publisher(Odometry, '~/odom', 50)
        self.typed = TypedStatus(create_publisher)
        made = [self.create_service(Trigger, '~/reset', self._on_reset),
                self.create_timer(self.p['diagnostic_period'], self._publish_diagnostics)]
        if self.p['imu_batch_period'] > 0.0:
            made.append(self.create_timer(self.p['imu_batch_period'], self._on_batch_timer))
        return made

    def _log_start(self):
        self.get_logger().info(
            f"fine filter {self.p['fine_filter']}, coarse {self.p['coarse_method']} "
            f"{self.p['coarse_duration']:.0f} s; waiting for imu/data_raw")

    @property
    def pipeline(self):
        """Return the current pipeline of the session (None without one); a restart replaces it."""
        return None if self.session is None else self.session.pipeline

    # -- parameters and restarts ------------------------------------------------------------
    def _check_pipeline_params(self, changes):
        new = dict(self._align_values)
        new.update({c.name: c.value for c in changes if c.name in _ALIGN_NAMES})
        try:
            prm.validate(new)
        except ValueError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_params(self, changes):
        names = [c.name for c in changes if c.name in _ALIGN_NAMES]
        for c in changes:
            self.p[c.name] = _BY_NAME[c.name].normalise(c.value) if c.name in _BY_NAME \
                else c.value
            if c.name in _ALIGN_NAMES:
                self._align_values[c.name] = c.value
        if names and self.session is not None:     # a managed node not configured: stored
            self._flush_imu()
            self.session.restart(f'parameters changed: {", ".join(names)}',
                                 values=self._align_values)
            self._drain()

    def _on_reset(self, request, response):
        self._flush_imu()                           # what came before goes to the old run
        self.session.restart('~/reset service')
        self._drain()
        response.success = True
        response.message = 'alignment restarted; waiting for IMU data'
        return response

    def _drain(self):
        """Log the session's restarts, count its input notices, publish a new phase."""
        for level, text in self.session.pop_events():
            if level == 'warn':       # rclpy: one severity per call site
                self.get_logger().warn(text)
            else:
                self.get_logger().info(text)
            self.notes.add([text])
            self._last_restart = text
            self.odom = OdometryFrame()
        for source, key, text in self.session.notices():
            self.faults.add(_SOURCES[source], key, text)
        if self.pipeline.phase != self._typed_phase or self.typed.last.get('reason') == NO_IMU:
            self._update_typed()

    def on_callback_error(self, exc):
        """Take an exception a callback raised (:func:`.runner.spin`): log, count, restart."""
        text = self.errors.add(exc)
        if self.session is not None:      # a managed node not configured: nothing to restart
            self._batch = []              # the messages it may have come from
            self.session.restart(f'exception in a callback ({text})', 'warn')
            self._drain()

    def _update_typed(self, s=None):
        """Publish what changed of the typed status (:mod:`.status`); return the state."""
        state = typed_state(self.pipeline.status() if s is None else s,
                            imu_stopped(self._imu_age(), self.p['diagnostic_period']))
        self._typed_phase = self.pipeline.phase
        if self._publishing():
            self.typed.update(state)
        return state

    def _publishing(self):
        """Tell whether the outputs publish (a managed node: while active)."""
        return True

    def _imu_age(self):
        """Return the seconds since the last IMU message (None before the first)."""
        return None if self._last_imu_wall is None else time.monotonic() - self._last_imu_wall

    # -- input -------------------------------------------------------------------------------
    def _on_fix(self, msg):
        self.received['gnss/fix'] += 1
        self._flush_imu()
        c = msg.position_covariance
        pos_var = (None if msg.position_covariance_type == NavSatFix.COVARIANCE_TYPE_UNKNOWN
                   else (c[0], c[4]))
        self.session.fix(stamp_to_sec(msg.header.stamp), msg.status.status, msg.latitude,
                         msg.longitude, msg.altitude, pos_var)
        self._drain()

    def _on_vel(self, msg):
        self.received['gnss/vel'] += 1
        self._flush_imu()
        v, c = msg.twist.twist.linear, msg.twist.covariance
        self.session.velocity(stamp_to_sec(msg.header.stamp), (v.x, v.y, v.z), (c[0], c[7]))
        self._drain()

    def _on_heading(self, msg):
        """Take an external heading: the yaw of the orientation and its variance (REP-145)."""
        self.received['heading/in'] += 1
        self._flush_imu()
        o, c = msg.orientation, msg.orientation_covariance
        var = None if c[8] == 0.0 else c[8]          # all zero: unknown (heading_sigma_deg)
        self.session.heading(stamp_to_sec(msg.header.stamp), quat_to_yaw((o.x, o.y, o.z, o.w)),
                             var, has_orientation=c[0] != -1.0)
        self._drain()

    def _on_imu(self, raw):
        """Queue a serialized IMU message (``raw=True``: bytes) for the batch."""
        self.received['imu/data_raw'] += 1
        now = time.monotonic()
        self._last_imu_wall = now
        self._period_imu[0] += 1
        if not self._batch:
            self._batch_wall = now
        self._batch.append(raw)
        if now - self._batch_wall >= self.p['imu_batch_period']:
            self._flush_imu()

    def _on_batch_timer(self):
        """Flush a batch the input stopped filling (a pause, the end of a recording)."""
        if self._batch:
            self._flush_imu()

    def _flush_imu(self):
        """Run the waiting IMU messages through the session; publish a row per sample."""
        if not self._batch:
            return
        batch, self._batch = ImuRows(self._batch), []
        self._refuse(batch)
        if not len(batch):
            self._drain()
            return
        missing = batch.missing
        conv = self.session.imu_input
        skipped, accepted = conv.rejected, conv.counts['accepted']
        w_b, f_b = batch.body[:, cdr.IMU_RATE], batch.body[:, cdr.IMU_ACCELERATION]
        if len(batch) == 1 and not missing[0]:       # the one-sample path costs less
            out = self.session.imu(batch.t[0], w_b[0], f_b[0])
        else:
            out = self.session.imu_block(batch.t, w_b, f_b, missing if missing.any() else None)
        self._period_imu[1] += len(batch) - (conv.rejected - skipped)
        self.counts['imu'] += conv.counts['accepted'] - accepted
        if missing.any():
            batch.select(~missing)
        C_s_v = self.pipeline.install.C_s_v
        if C_s_v is not None:
            batch.to_vehicle_frame(C_s_v, self.p['base_frame_id'])
        self._recent.extend(batch.rows())
        if len(out.t):
            self._publish(out)
        self._drain()

    def _refuse(self, batch):
        """Count and drop the messages of ``batch`` that cannot be used (bytes, frame)."""
        keep = ~batch.bad
        for _ in range(int(batch.bad.sum())):
            self.session.reject_imu('undecodable', 'message bytes not a decodable '
                                    'sensor_msgs/Imu: sample skipped')
        frame = self.p['imu_frame_id']
        if frame:
            for i, fid in enumerate(batch.frame_ids()):
                if keep[i] and fid != frame:
                    keep[i] = False
                    self.session.reject_imu('wrong_frame', f"frame_id '{fid}' is not "
                                                           f"'{frame}': sample skipped")
        if not keep.all():
            batch.select(keep)

    # -- output ------------------------------------------------------------------------------
    def _publish(self, out):
        """Publish ``imu/data`` (and ``~/euler``, ``~/odom``) for each row of ``out``.

        Each row refers to the received sample with its stamp (with pre-processing an
        earlier one than the batch's), whose header and rates it carries.
        """
        recent, srcs = self._recent, []
        for t_k in out.t.tolist():
            while len(recent) > 1 and recent[0][0] < t_k - 1e-9:
                recent.popleft()
            srcs.append(recent[0])
        bodies = echo_bodies([s[2] for s in srcs], out.q, out.P_phi)
        publish = self.pub_imu.publish
        for (_, head, _), body in zip(srcs, bodies):
            publish(head + body.tobytes())
        if self.pub_euler.get_subscription_count():     # none: not built
            euler = known_euler(out)
            for k, (_, head, _) in enumerate(srcs):
                if np.isfinite(out.q[k, 0]):
                    self._euler.header = header_message(head)
                    set_vector3(self._euler.vector, euler[k])
                    self.pub_euler.publish(self._euler)
        if out.nav is not None:
            self._publish_odom(srcs, bodies[:, cdr.IMU_RATE], out)

    def _publish_odom(self, srcs, w_b, out):
        """Publish ``~/odom`` for the rows of ``out`` (``srcs`` their samples, rates ``w_b``).

        No GNSS update happens inside a batch (a GNSS message flushes it first), so the
        filter's covariance and bias at its end serve every row.
        """
        pipe = self.pipeline
        dt = self.session.imu_input.dt_nominal or 0.01
        ok, odo = self.odom.samples(out, pipe.nav_cov(), w_b, pipe.engine.gyro_bias,
                                    pipe.noise.gyro_arw ** 2 / dt)
        if odo is None:
            return
        publish, frame = self.pub_odom.publish, self.p['odom_frame_id']
        rows = iter(odometry_bodies(odo))
        for (_, head, _), k in zip(srcs, ok.tolist()):
            if k:
                publish(self._odom_head(head, frame) + next(rows).tobytes())

    def _odom_head(self, imu_head, frame_id):
        """Return ``~/odom``'s serialized start for the sample whose Imu starts ``imu_head``.

        Its stamp, ``frame_id`` and the sample's frame as the child frame; the part after
        the stamp is the same for every sample of a frame, so it is made once.
        """
        end = cdr.STAMP.stop
        key = (frame_id, imu_head[end:])
        rest = self._odom_heads.get(key)
        if rest is None:
            if len(self._odom_heads) > 64:           # frame ids that keep changing
                self._odom_heads.clear()
            child = cdr.header_fields(imu_head)[2]
            rest = self._odom_heads[key] = cdr.odometry_head(bytes(8), frame_id, child)[end:]
        return imu_head[:end] + rest

    def _publish_diagnostics(self):
        pipe = self.pipeline
        s = pipe.status()
        state = self._update_typed(s)
        self.notes.read(pipe.warnings)
        values = input_values(self.session, self.counts, self.odom)
        values.update(callback_error_count=self.errors.count, notes='; '.join(pipe.warnings),
                      last_restart=self._last_restart)
        st = alignment_status(f'{self.get_fully_qualified_name()}: alignment',
                              self.p['imu_frame_id'] or 'imu', s, state,
                              self.p['diagnostic_period'], self.p['coarse_duration'],
                              self._imu_age(), self._period_imu, self.faults.lines(),
                              self.errors.lines() + pipe.conditions(), self.notes.current(),
                              values)
        self._period_imu = [0, 0]
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [st]
        self.pub_diag.publish(arr)


class AlignmentNode(AlignmentShell, Node):
    """Thin ROS shell around an alignment session, started at construction."""

    def __init__(self, **kwargs):
        super().__init__('alignment_node', **kwargs)
        self._declare_params()
        self._start_session()
        self._subscribe()
        self._create_outputs(self.create_publisher)
        self._update_typed()                # the typed status once at start
        self._log_start()


def main(args=None):
    """Entry point of ``ros2 run sins_align_ros alignment_node``."""
    return run(AlignmentNode, 'alignment_node', make_executor, args=args)


if __name__ == '__main__':
    sys.exit(main())

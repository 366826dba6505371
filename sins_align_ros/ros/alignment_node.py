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
* ``~/euler`` (geometry_msgs/Vector3Stamped): REP-103 roll, pitch, yaw in rad;
* ``/diagnostics`` (diagnostic_msgs/DiagnosticArray, status ``<node>: alignment``,
  :mod:`.diagnostics`);
* ``~/odom`` (nav_msgs/Odometry) with the navigation filters (``kf``, ``vbakf``,
  ``mvbakf``, ``ukf``) and ``continue_navigation``: the GNSS/INS solution at every
  IMU sample from the start of fine alignment on, pose in ``odom_frame_id`` (ENU,
  origin where fine alignment started: ``odom_origin_*`` in the diagnostics), twist
  in the body's frame, the same as ``imu/data``'s (:mod:`sins_align_ros.align.odometry`).

Bad input is skipped or bridged, counted by reason in the diagnostics' values,
logged at most once per :data:`~.diagnostics.LOG_PERIOD_S` per reason, and raises
the diagnostic level for the period it happened in: WARN, or ERROR when IMU
messages arrived but none was usable.

IMU messages are processed in batches (``imu_batch_period``, default 10 ms of waiting:
at 1 kHz ten samples go through the input checks and the compiled filters at once,
which took the node from 0.39 to 0.22 cores with ``asckf``, bench/results/node_load.md),
then published one by one with their own headers; a GNSS message, a parameter change, a
reset or the period's timer flushes the batch first.

Service ``~/reset`` (std_srvs/Trigger) restarts the alignment in any phase.
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
from .diagnostics import FaultLog, alignment_status
from .messages import imu_message, odometry_message
from .params import declare
from .runner import make_executor, run
from ..align import params as prm
from ..align.odometry import OdometryFrame
from ..align.session import AlignmentSession
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
        self._events = []
        self.odom = OdometryFrame()
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
        return [self.create_subscription(Imu, 'imu/data_raw', self._on_imu, imu_qos),
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
        """Log the session's restarts and count its input notices."""
        for level, text in self.session.pop_events():
            getattr(self.get_logger(), level)(text)
            self._events.append(text)
            self.odom = OdometryFrame()
        for source, key, text in self.session.notices():
            self.faults.add(_SOURCES[source], key, text)

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

    def _on_imu(self, msg):
        self.received['imu/data_raw'] += 1
        self._last_imu_wall = self.get_clock().now()
        self._period_imu[0] += 1
        frame = self.p['imu_frame_id']
        if frame and msg.header.frame_id != frame:
            self.session.reject_imu('wrong_frame', f"frame_id '{msg.header.frame_id}' is not "
                                                   f"'{frame}': sample skipped")
        elif msg.angular_velocity_covariance[0] == -1.0 or (
                msg.linear_acceleration_covariance[0] == -1.0):
            self.session.reject_missing_field()
        else:
            now = time.monotonic()
            if not self._batch:
                self._batch_wall = now
            self._batch.append((stamp_to_sec(msg.header.stamp), msg))
            if now - self._batch_wall < self.p['imu_batch_period']:
                return
            self._flush_imu()
            return
        self._drain()

    def _on_batch_timer(self):
        """Flush a batch the input stopped filling (a pause, the end of a recording)."""
        if self._batch:
            self._flush_imu()

    def _flush_imu(self):
        """Run the waiting IMU messages through the session; publish a row per sample."""
        if not self._batch:
            return
        batch, self._batch = self._batch, []
        n = len(batch)
        wf = np.array([(m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z,
                        m.linear_acceleration.x, m.linear_acceleration.y,
                        m.linear_acceleration.z) for _, m in batch])
        conv = self.session.imu_input
        skipped, accepted = conv.rejected, conv.counts['accepted']
        if n == 1:                                   # the one-sample path costs less
            out = self.session.imu(batch[0][0], wf[0, :3], wf[0, 3:])
        else:
            t = np.fromiter((b[0] for b in batch), dtype=float, count=n)
            out = self.session.imu_block(t, wf[:, :3], wf[:, 3:])
        self._period_imu[1] += n - (conv.rejected - skipped)
        self.counts['imu'] += conv.counts['accepted'] - accepted
        C_s_v = self.pipeline.install.C_s_v
        if C_s_v is not None:
            _to_vehicle_frame([m for _, m in batch], wf, C_s_v, self.p['base_frame_id'])
        self._recent.extend(batch)
        odo_state = self._odometry_state() if out.nav is not None and len(out.t) else None
        for k, t_k in enumerate(out.t):            # each finished sample, its own header
            while len(self._recent) > 1 and self._recent[0][0] < t_k - 1e-9:
                self._recent.popleft()
            src = self._recent[0][1]
            self._publish(src, out, k)
            if odo_state is not None:
                self._publish_odom(src, out, k, odo_state)
        self._drain()

    # -- output ------------------------------------------------------------------------------
    def _publish(self, src, out, k=-1):
        m, e = imu_message(src, out, k, self._euler)
        if e is not None and self.pub_euler.get_subscription_count():   # none: not built
            self.pub_euler.publish(e)
        self.pub_imu.publish(m)

    def _odometry_state(self):
        """Return the batch end's ``(P_nav, gyro_bias, rate_var)`` for its ~/odom rows.

        No GNSS update happens inside a batch (a GNSS message flushes it first), so the
        filter's covariance and bias at its end serve every row.
        """
        pipe = self.pipeline
        dt = self.session.imu_input.dt_nominal or 0.01
        return pipe.nav_cov(), pipe.engine.gyro_bias, pipe.noise.gyro_arw ** 2 / dt

    def _publish_odom(self, src, out, k, state):
        """Publish row ``k`` with the batch end's filter ``state`` (:meth:`_odometry_state`)."""
        P_nav, gyro_bias, rate_var = state
        w = src.angular_velocity
        odo = self.odom.sample(out, P_nav, np.array([w.x, w.y, w.z]), gyro_bias, rate_var, k)
        if odo is not None:
            self.pub_odom.publish(odometry_message(src.header.stamp, self.p['odom_frame_id'],
                                                   src.header.frame_id, odo))

    def _publish_diagnostics(self):
        session = self.session
        imu_age = None
        if self._last_imu_wall is not None:
            imu_age = (self.get_clock().now() - self._last_imu_wall).nanoseconds * 1e-9
        imu_counts, gnss_counts = session.input_counts()
        values = {f'imu_{k}': v for k, v in imu_counts.items()}
        values.update({f'gnss_input_{k}': v for k, v in gnss_counts.items()})
        values.update({f'{k}_count': v for k, v in self.counts.items()})
        values['imu_rejected_count'] = session.imu_input.rejected
        if self.odom.origin is not None:
            lat, lon, h = self.odom.origin          # full precision (1e-9 deg ~ 0.1 mm)
            values.update({'odom_origin_lat_deg': f'{np.degrees(lat):.9f}',
                           'odom_origin_lon_deg': f'{np.degrees(lon):.9f}',
                           'odom_origin_h_m': f'{h:.3f}'})
        values['gnss_rejected_count'] = session.gnss_input.rejected
        pipe = self.pipeline
        conditions = pipe.conditions() + [(1, w) for w in pipe.warnings]
        st = alignment_status(f'{self.get_name()}: alignment', self.p['imu_frame_id'] or 'imu',
                              pipe.status(), self.p['diagnostic_period'],
                              self.p['coarse_duration'], imu_age, self._period_imu,
                              self.faults.lines(), conditions, self._events, values)
        self._period_imu = [0, 0]
        self._events = []
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
        self._log_start()


def _to_vehicle_frame(msgs, wf, C_s_v, frame_id):
    """Turn received Imu ``msgs`` (rates and accelerations ``wf`` (N, 6)) into the vehicle frame.

    ``C_s_v`` (3, 3) IMU -> vehicle rotation; the rate and acceleration covariances are
    turned with them, and ``frame_id`` (``base_frame_id``) replaces the IMU's.
    """
    w = wf[:, :3] @ C_s_v.T
    f = wf[:, 3:] @ C_s_v.T
    for k, m in enumerate(msgs):
        set_vector3(m.angular_velocity, w[k])
        set_vector3(m.linear_acceleration, f[k])
        for name in ('angular_velocity_covariance', 'linear_acceleration_covariance'):
            P = np.asarray(getattr(m, name), dtype=float).reshape(3, 3)
            if np.any(P):
                setattr(m, name, (C_s_v @ P @ C_s_v.T).ravel())
        m.header.frame_id = frame_id


def main(args=None):
    """Entry point of ``ros2 run sins_align_ros alignment_node``."""
    return run(AlignmentNode, 'alignment_node', make_executor, args=args)


if __name__ == '__main__':
    sys.exit(main())

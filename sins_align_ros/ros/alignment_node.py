"""alignment_node: SINS initial alignment from sensor_msgs/Imu (and GNSS position).

Subscribes ``imu/data_raw`` (sensor_msgs/Imu; best effort with a deep queue so
it takes both best-effort and reliable publishers), ``gnss/fix`` and
``gnss/vel`` (geometry_msgs/TwistWithCovarianceStamped, ENU; used by the
moving-base filters ckf and asckf). Every IMU
sample goes through :class:`~sins_align_ros.align.imu_input.ImuInput` (input
checks), every GNSS message through :class:`~sins_align_ros.align.gnss_input.GnssInput`,
then :class:`~sins_align_ros.align.pipeline.AlignmentPipeline` — the
same objects the replay tool uses — and produces:

* ``imu/data`` (sensor_msgs/Imu): the input rates plus the orientation body ->
  ENU with ``orientation_covariance`` = the filter's misalignment covariance
  about the ENU axes (rad^2); until coarse alignment is done the orientation is
  marked unknown (``orientation_covariance[0] = -1``, REP-145);
* ``~/euler`` (geometry_msgs/Vector3Stamped): REP-103 roll, pitch, yaw in rad;
* ``/diagnostics`` (diagnostic_msgs/DiagnosticArray, status ``<node>: alignment``);
* ``~/odom`` (nav_msgs/Odometry) with the navigation filters (``kf``, ``vbakf``,
  ``mvbakf``, ``ukf``) and ``continue_navigation``: the GNSS/INS solution at every
  IMU sample from the start of fine alignment on, through ``aligned`` and after.
  Pose in ``odom_frame_id``: an ENU frame whose origin is the position where fine
  alignment started (``odom_origin_*`` in the diagnostics), orientation body -> ENU;
  twist in the IMU's frame (``child_frame_id``): body-axis velocity and the
  bias-corrected angular rate. Covariances from the filter: position and attitude
  (about the fixed ENU axes) with their cross terms; the body velocity's from the
  velocity and attitude errors; the rate's from the gyro noise.

Bad input (the rules are in the two input modules) is skipped or bridged,
counted by reason in the diagnostics' values, logged at most once per
:data:`LOG_PERIOD_S` per reason with the number of occurrences, and raises the
diagnostic level for the period it happened in: WARN, or ERROR when IMU
messages arrived but none was usable.

Service ``~/reset`` (std_srvs/Trigger) restarts the alignment in any phase.
Changing an alignment parameter at runtime (``fine_filter`` included) restarts
the alignment with it; invalid values are refused with the reason.
"""
import os
import sys
import time
from collections import Counter, deque

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from geometry_msgs.msg import TwistWithCovarianceStamped, Vector3Stamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, NavSatFix
from std_srvs.srv import Trigger

from .conversions import stamp_to_sec
from .params import Param, declare
from .runner import run
from ..align import params as prm
from ..align.gnss_input import GnssInput
from ..align.imu_input import OK, RESET, SKIP, START, ImuInput
from ..align.pipeline import COARSE, WAITING, AlignmentPipeline
from ..nav import earth
from ..nav.frames import quat_to_dcm, skew

NODE_PARAMS = (
    Param('imu_frame_id', '', 'expected frame_id of imu/data_raw (empty: accept any)'),
    Param('diagnostic_period', 1.0, 'period of /diagnostics, s', 0.05, 60.0),
    Param('odom_frame_id', 'odom', 'frame_id of ~/odom: ENU axes, origin where fine '
          'alignment started'),
)
PARAMS = prm.ALIGNMENT_PARAMS + NODE_PARAMS
_ALIGN_NAMES = {p.name for p in prm.ALIGNMENT_PARAMS}
#: each input-fault reason is logged at most once per this many seconds (wall time)
LOG_PERIOD_S = 5.0


class AlignmentNode(Node):
    """Thin ROS shell around the alignment pipeline; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__('alignment_node', **kwargs)
        self.p = declare(self, PARAMS)
        self._align_values = {k: v for k, v in self.p.items() if k in _ALIGN_NAMES}
        self.pipeline = AlignmentPipeline(self._align_values)   # ValueError: refused
        #: recent (stamp, message): with pre-processing an output refers to an earlier
        #: sample, published with that sample's header
        self._recent = deque(maxlen=4 * 4096 + 64)
        self.input = ImuInput.from_params(self.p)
        self.gnss = GnssInput()
        self._faults = Counter()      # reason -> occurrences in this diagnostic period
        self._fault_text = {}         # reason -> last text
        self._logged = {}             # reason -> (wall time of last log line, count since)
        self._period_imu = [0, 0]     # IMU messages received, accepted in this period
        self.add_on_set_parameters_callback(self._check_pipeline_params)
        self.add_post_set_parameters_callback(self._apply_params)
        imu_qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT,
                             history=HistoryPolicy.KEEP_LAST)
        self.create_subscription(Imu, 'imu/data_raw', self._on_imu, imu_qos)
        gnss_qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT,
                              history=HistoryPolicy.KEEP_LAST)
        self.create_subscription(NavSatFix, 'gnss/fix', self._on_fix, gnss_qos)
        self.create_subscription(TwistWithCovarianceStamped, 'gnss/vel', self._on_vel,
                                 gnss_qos)
        self.pub_imu = self.create_publisher(Imu, 'imu/data', 50)
        self.pub_euler = self.create_publisher(Vector3Stamped, '~/euler', 50)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.pub_odom = self.create_publisher(Odometry, '~/odom', 50)
        self._odom_origin = None          # (lat, lon, h) of the ENU origin of ~/odom
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.counts = {'imu': 0}
        #: messages received per topic (before any check)
        self.received = Counter()
        self._last_imu_wall = None
        self._events = []
        self._diag_timer = self.create_timer(self.p['diagnostic_period'],
                                             self._publish_diagnostics)
        self.get_logger().info(
            f"fine filter {self.p['fine_filter']}, coarse {self.p['coarse_method']} "
            f"{self.p['coarse_duration']:.0f} s; waiting for imu/data_raw")

    # -- parameters -------------------------------------------------------------------
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
            self.p[c.name] = c.value
            if c.name in _ALIGN_NAMES:
                self._align_values[c.name] = c.value
        if names:
            self._restart(f'parameters changed: {", ".join(names)}')
            self.input.set_params(self.p)

    def _restart(self, reason, level='info', restart_clock=True):
        """Start a new pipeline with the current parameters (keeping the last GNSS fix)."""
        old = self.pipeline
        self._odom_origin = None
        self.pipeline = AlignmentPipeline(self._align_values)
        self.pipeline.inherit_gnss(old)
        if restart_clock:
            self.input.restart()
        self._event(f'alignment restarted: {reason}', level)

    def _event(self, text, level='info'):
        getattr(self.get_logger(), level)(text)
        self._events.append(text)

    # -- callbacks -------------------------------------------------------------------
    def _on_reset(self, request, response):
        self._restart('~/reset service')
        response.success = True
        response.message = 'alignment restarted; waiting for IMU data'
        return response

    def _fault(self, source, key, text):
        """Count an input fault for the diagnostics; log it at most once per LOG_PERIOD_S."""
        key = (source, key)
        self._faults[key] += 1
        self._fault_text[key] = text
        now = time.monotonic()
        last, n = self._logged.get(key, (None, 0))
        if last is None or now - last >= LOG_PERIOD_S:
            more = f' ({n + 1} times in {now - last:.0f} s)' if last is not None and n else ''
            self.get_logger().warn(f'{source}: {text}{more}')
            self._logged[key] = (now, 0)
        else:
            self._logged[key] = (last, n + 1)

    def _drain(self, checker, source):
        for key, text in checker.pop_notices():
            self._fault(source, key, text)

    def _on_fix(self, msg):
        self.received['gnss/fix'] += 1
        t = stamp_to_sec(msg.header.stamp)
        c = msg.position_covariance
        pos_var = (None if msg.position_covariance_type == NavSatFix.COVARIANCE_TYPE_UNKNOWN
                   else (c[0], c[4]))
        var = self.gnss.fix(t, msg.status.status, msg.latitude, msg.longitude, msg.altitude,
                            pos_var)
        if var is not False:
            self.pipeline.position_fix(t, msg.latitude, msg.longitude, msg.altitude,
                                       pos_var=var)
        self._drain(self.gnss, 'gnss')

    def _on_vel(self, msg):
        self.received['gnss/vel'] += 1
        t = stamp_to_sec(msg.header.stamp)
        v = msg.twist.twist.linear
        c = msg.twist.covariance
        var = self.gnss.velocity(t, (v.x, v.y, v.z), (c[0], c[7]))
        if var is not False:
            self.pipeline.velocity_fix(t, (v.x, v.y, v.z), vel_var=var)
        self._drain(self.gnss, 'gnss')

    def _on_imu(self, msg):
        self.received['imu/data_raw'] += 1
        self._last_imu_wall = self.get_clock().now()
        self._period_imu[0] += 1
        frame = self.p['imu_frame_id']
        if frame and msg.header.frame_id != frame:
            self.input.reject('wrong_frame', f"frame_id '{msg.header.frame_id}' is not "
                                             f"'{frame}': sample skipped")
        elif msg.angular_velocity_covariance[0] == -1.0 or (
                msg.linear_acceleration_covariance[0] == -1.0):
            self.input.reject_missing_field()
        else:
            self._process_imu(msg)
        self._drain(self.input, 'imu/data_raw')

    def _process_imu(self, msg):
        t = stamp_to_sec(msg.header.stamp)
        w, a = msg.angular_velocity, msg.linear_acceleration
        action, dth, dv = self.input.push(t, (w.x, w.y, w.z), (a.x, a.y, a.z))
        if action != SKIP:
            self._period_imu[1] += 1
        if action == OK:
            self.counts['imu'] += 1
            if self.input.bridge is not None:
                self.pipeline.widen(*self.input.bridge)
            out = self.pipeline.feed(t, dth, dv)
            if self.pipeline.pre is None:
                self._publish(msg, out)
                if out.nav is not None:
                    self._publish_odom(msg, out, np.array([w.x, w.y, w.z]))
            else:
                self._recent.append((t, msg))
                for k, t_k in enumerate(out.t):        # each finished sample, its own header
                    while len(self._recent) > 1 and self._recent[0][0] < t_k - 1e-9:
                        self._recent.popleft()
                    self._publish(self._recent[0][1], out, k)
                if out.nav is not None and len(out.t):
                    w = self._recent[0][1].angular_velocity
                    self._publish_odom(self._recent[0][1], out, np.array([w.x, w.y, w.z]))
        elif action == START:
            self.pipeline.start_clock(t)
        elif action == RESET:
            self._restart(self.input.last_reason, 'warn', restart_clock=False)
            self.pipeline.start_clock(t)

    def _publish(self, msg, out, k=-1):
        m = Imu()
        m.header = msg.header
        m.angular_velocity = msg.angular_velocity
        m.angular_velocity_covariance = msg.angular_velocity_covariance
        m.linear_acceleration = msg.linear_acceleration
        m.linear_acceleration_covariance = msg.linear_acceleration_covariance
        q = out.q[k]
        if np.isfinite(q[0]):
            m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = (
                float(q[0]), float(q[1]), float(q[2]), float(q[3]))
            m.orientation_covariance = [float(v) for v in out.P_phi[k].ravel()]
            e = Vector3Stamped()
            e.header = msg.header
            e.vector.x, e.vector.y, e.vector.z = (float(v) for v in out.euler[k])
            self.pub_euler.publish(e)
        else:
            m.orientation_covariance[0] = -1.0
        self.pub_imu.publish(m)

    def _publish_odom(self, msg, out, w_b):
        """``~/odom`` for the last row of ``out`` (see the module docstring).

        ``w_b`` (3,): the sample's body angular rate, rad/s (before bias correction).
        """
        nav = out.nav[-1]
        q = out.q[-1]
        if not (np.all(np.isfinite(nav)) and np.isfinite(q[0])):
            return
        lat, lon, h = nav[:3]
        if self._odom_origin is None:
            self._odom_origin = (float(lat), float(lon), float(h))
        e, n, u = earth.local_offset_m(*self._odom_origin, np.array([lat]), np.array([lon]),
                                       np.array([h]))[0]
        C = quat_to_dcm(q)
        o = Odometry()
        o.header.stamp = msg.header.stamp
        o.header.frame_id = self.p['odom_frame_id']
        o.child_frame_id = msg.header.frame_id
        o.pose.pose.position.x, o.pose.pose.position.y, o.pose.pose.position.z = (
            float(e), float(n), float(u))
        o.pose.pose.orientation.x, o.pose.pose.orientation.y, o.pose.pose.orientation.z, \
            o.pose.pose.orientation.w = (float(v) for v in q)
        P_nav = self.pipeline.nav_cov()         # position, velocity, misalignment (9, 9)
        ip = np.r_[0:3, 6:9]
        o.pose.covariance = [float(v) for v in P_nav[np.ix_(ip, ip)].ravel()]
        v_b = C.T @ nav[3:]
        o.twist.twist.linear.x, o.twist.twist.linear.y, o.twist.twist.linear.z = (
            float(v) for v in v_b)
        w = np.asarray(w_b, dtype=float) - self.pipeline.engine.gyro_bias
        o.twist.twist.angular.x, o.twist.twist.angular.y, o.twist.twist.angular.z = (
            float(v) for v in w)
        # v_b = C~^T v~ = v_b + C^T dV - C^T [v x] phi (C~ = (I - [phi x]) C)
        J = np.hstack([C.T, -C.T @ skew(nav[3:])])
        twist_cov = np.zeros((6, 6))
        twist_cov[:3, :3] = J @ P_nav[3:, 3:] @ J.T
        dt = self.input.dt_nominal or 0.01
        twist_cov[3:, 3:] = np.eye(3) * (self.pipeline.noise.gyro_arw ** 2 / dt)
        o.twist.covariance = [float(v) for v in twist_cov.ravel()]
        self.pub_odom.publish(o)

    # -- diagnostics -----------------------------------------------------------------
    def _publish_diagnostics(self):
        st = DiagnosticStatus()
        st.name = f'{self.get_name()}: alignment'
        st.hardware_id = self.p['imu_frame_id'] or 'imu'
        s = self.pipeline.status()
        phase = s['phase']
        counts = dict(self.input.counts)
        level, msgs = DiagnosticStatus.OK, []
        if phase == WAITING:
            level = DiagnosticStatus.WARN
            msgs.append('waiting for IMU data on imu/data_raw')
        elif phase == COARSE:
            msgs.append(f"coarse alignment {s['elapsed_s']:.0f}/{self.p['coarse_duration']:.0f} s")
        else:
            msgs.append(f"{phase}: 1-sigma roll {s['sigma_roll_deg'] * 60:.2f}', pitch "
                        f"{s['sigma_pitch_deg'] * 60:.2f}', yaw {s['sigma_yaw_deg'] * 60:.2f}'")
        if self._last_imu_wall is not None:
            age = (self.get_clock().now() - self._last_imu_wall).nanoseconds * 1e-9
            if age > max(2.0, 3 * self.p['diagnostic_period']):
                level = DiagnosticStatus.ERROR
                msgs.insert(0, f'no IMU data for {age:.1f} s')
        received, accepted = self._period_imu
        if received and not accepted:
            level = DiagnosticStatus.ERROR
            msgs.insert(0, f'none of the {received} IMU messages of the last '
                           f"{self.p['diagnostic_period']:g} s was usable")
        for key, n in self._faults.items():
            level = max(level, DiagnosticStatus.WARN)
            msgs.append(f'{key[0]}: {n} x {self._fault_text[key]}')
        self._faults.clear()
        self._period_imu = [0, 0]
        for lvl, text in self.pipeline.conditions():
            level = max(level, DiagnosticStatus.ERROR if lvl >= 2 else DiagnosticStatus.WARN)
            msgs.append(text)
        for w in self.pipeline.warnings:
            level = max(level, DiagnosticStatus.WARN)
            msgs.append(w)
        if self._events:
            level = max(level, DiagnosticStatus.WARN)
            msgs.append(self._events[-1])
            self._events.clear()
        st.level = level
        st.message = '; '.join(msgs)
        values = dict(s)
        values.update({f'imu_{k}': v for k, v in counts.items()})
        values.update({f'gnss_input_{k}': v for k, v in self.gnss.counts.items()})
        values.update({f'{k}_count': v for k, v in self.counts.items()})
        values['imu_rejected_count'] = self.input.rejected
        if self._odom_origin is not None:
            lat, lon, h = self._odom_origin          # full precision (1e-9 deg ~ 0.1 mm)
            values.update({'odom_origin_lat_deg': f'{np.degrees(lat):.9f}',
                           'odom_origin_lon_deg': f'{np.degrees(lon):.9f}',
                           'odom_origin_h_m': f'{h:.3f}'})
        values['gnss_rejected_count'] = self.gnss.rejected
        st.values = [KeyValue(key=k, value=_fmt(v)) for k, v in values.items()]
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [st]
        self.pub_diag.publish(arr)


def _fmt(v):
    if isinstance(v, float):
        return f'{v:.6g}'
    if isinstance(v, (list, tuple)):
        return ' '.join(_fmt(float(x)) for x in v)
    return str(v)


def make_executor():
    """Return the lightest executor available: rclpy's EventsExecutor (experimental).

    At 1000 Hz IMU input the default SingleThreadedExecutor alone costs about a
    third of a core in wait-set handling; set SINS_ALIGN_EXECUTOR=single to use it anyway.
    """
    if os.environ.get('SINS_ALIGN_EXECUTOR', 'events') == 'events':
        try:
            from rclpy.experimental import EventsExecutor
            return EventsExecutor()
        except ImportError:  # pragma: no cover - older rclpy
            pass
    from rclpy.executors import SingleThreadedExecutor
    return SingleThreadedExecutor()


def main(args=None):
    """Entry point of ``ros2 run sins_align_ros alignment_node``."""
    return run(AlignmentNode, 'alignment_node', make_executor, args=args)


if __name__ == '__main__':
    sys.exit(main())

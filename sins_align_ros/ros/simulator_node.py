"""simulator_node: publishes simulated IMU and GNSS data with ground truth.

Publishes (relative names, remappable):

* ``imu/data_raw`` (sensor_msgs/Imu): mean angular rate and specific force over
  each sample interval (increment / dt), FLU body, stamped at the interval's end;
  covariances from the white-noise terms of the IMU spec; orientation unknown
  (``orientation_covariance[0] = -1``, REP-145).
* ``gnss/fix`` (sensor_msgs/NavSatFix): STATUS_FIX with a diagonal ENU covariance,
  or STATUS_NO_FIX with NaN position during outages.
* ``gnss/vel`` (geometry_msgs/TwistWithCovarianceStamped): ENU velocity.
* ``sim/truth`` (nav_msgs/Odometry): pose in the local ENU frame ``world_frame_id``
  with its origin at the start position; twist in the body frame (the
  message's convention: ``child_frame_id``).
* ``/clock`` (rosgraph_msgs/Clock) when ``publish_clock`` is true or
  ``real_time_factor`` is 0 (as fast as possible), so ``use_sim_time`` nodes follow.

Stamps are ``start_time + t`` where ``start_time`` defaults to the node's clock at
start-up. Output is deterministic for a given ``seed``.
"""
import math
import sys
import time
from collections import deque

from geometry_msgs.msg import TwistWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus

from .conversions import diag_cov, ns_to_stamp, sec_to_ns, set_quaternion, set_vector3
from .params import Param, declare
from .runner import run
from ..nav import earth
from ..nav.frames import euler_rates_to_w_nb_b, euler_to_dcm, euler_to_quat
from ..sim.imu import DPSH, UG
from ..sim.presets import SCENARIOS, scenario
from ..sim.scenario import ScenarioStream

PARAMS = (
    Param('scenario', 'static_navigation', 'named scenario preset (sim/presets.py)',
          choices=SCENARIOS, read_only=True),
    Param('seed', 0, 'random seed; the same seed gives the same data', 0, 2 ** 31 - 1,
          read_only=True),
    Param('imu_rate_hz', 0.0, 'IMU rate, Hz (0: the scenario default, 100 Hz)', 0.0, 4000.0,
          read_only=True),
    Param('gnss_rate_hz', 0.0, 'GNSS rate, Hz (0: the scenario default)', 0.0, 50.0,
          read_only=True),
    Param('duration', 0.0, 'simulated duration, s (0: the scenario default)', 0.0, 1e6,
          read_only=True),
    Param('real_time_factor', 1.0, 'simulated seconds per wall second; 0 = as fast as '
          'possible (publishes /clock)', 0.0, 1000.0),
    Param('publish_clock', False, 'publish /clock (always on when real_time_factor is 0)'),
    Param('start_time', 0.0, 'stamp of t = 0, s since the epoch (0: the clock at start-up)',
          0.0, 4e9, read_only=True),
    Param('truth_rate_hz', 10.0, 'rate of sim/truth, Hz (capped at the IMU rate)', 0.1, 4000.0,
          read_only=True),
    Param('imu_frame_id', 'imu_link', 'frame_id of imu/data_raw (FLU body)', read_only=True),
    Param('gnss_frame_id', 'gnss_link', 'frame_id of gnss/fix and gnss/vel', read_only=True),
    Param('world_frame_id', 'enu', 'frame_id of sim/truth (local ENU at the start position)',
          read_only=True),
    Param('shutdown_when_done', False,
          'exit after the last sample, once reliable subscribers acknowledged it (at most 5 s)'),
)

_BLOCK_S = 1.0   # seconds of data generated per block
_TICK_S = 0.005  # publishing timer period (wall time)
_DRAIN_S = 5.0   # at most this long waiting for acknowledgements before exiting


class SimulatorNode(Node):
    """Streams a scenario preset onto the ROS graph; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__('simulator_node', **kwargs)
        p = declare(self, PARAMS)
        self.sc = scenario(p['scenario'])
        if p['duration'] > 0:
            self.sc.duration = p['duration']
        self.stream = ScenarioStream(self.sc, seed=p['seed'],
                                     imu_rate_hz=p['imu_rate_hz'] or None,
                                     gnss_rate_hz=p['gnss_rate_hz'] or None)
        self.dt = self.stream.dt
        self.n_total = int(round(self.sc.duration / self.dt))
        self.truth_every = max(1, int(round(1.0 / (p['truth_rate_hz'] * self.dt))))
        self.frames = (p['imu_frame_id'], p['gnss_frame_id'], p['world_frame_id'])
        self.shutdown_when_done = p['shutdown_when_done']
        self.done = False
        start = p['start_time'] or self.get_clock().now().nanoseconds * 1e-9
        self.t0_ns = sec_to_ns(start)

        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                         history=HistoryPolicy.KEEP_LAST)
        self.pub_imu = self.create_publisher(Imu, 'imu/data_raw', qos)
        self.pub_fix = self.create_publisher(NavSatFix, 'gnss/fix', 10)
        self.pub_vel = self.create_publisher(TwistWithCovarianceStamped, 'gnss/vel', 10)
        self.pub_truth = self.create_publisher(Odometry, 'sim/truth', 50)
        self.pub_clock = self.create_publisher(Clock, '/clock', 10)

        spec = self.sc.imu
        self.gyro_var = (spec.gyro_arw_dpsh * DPSH) ** 2 / self.dt
        self.accel_var = (spec.accel_vrw_ug_rthz * UG) ** 2 / self.dt
        self.origin = self.sc.trajectory.initial_position
        self._queue = deque()   # pending (t, kind, payload) in time order
        self._k = 0             # IMU samples published
        self._wall0 = None
        self._sim_t_at_wall0 = 0.0
        self._rtf = p['real_time_factor']
        self._publish_clock = p['publish_clock']
        self.add_post_set_parameters_callback(self._on_params)
        self.timer = self.create_timer(_TICK_S, self._tick)
        self.get_logger().info(
            f"scenario '{self.sc.name}': {self.sc.description}; {self.sc.duration:.0f} s at "
            f'{1.0 / self.dt:.0f} Hz, seed {p["seed"]}, real-time factor '
            f'{self._rtf or "as fast as possible"}')

    def _on_params(self, changes):
        """Apply accepted runtime changes (validation ran before, in params.declare)."""
        for c in changes:
            if c.name == 'real_time_factor':
                self._sim_t_at_wall0 = self._k * self.dt
                self._wall0 = time.monotonic()
                self._rtf = c.value
            elif c.name == 'publish_clock':
                self._publish_clock = c.value
            elif c.name == 'shutdown_when_done':
                self.shutdown_when_done = c.value

    # -- data generation --------------------------------------------------------
    def _refill(self):
        n = min(int(round(_BLOCK_S / self.dt)), self.n_total - self.stream.imu.k)
        if n <= 0:
            return False
        b = self.stream.next_block(n)
        imu = b.imu
        items = []
        kin = self.sc.trajectory.kinematics(imu.t)
        w_nb_b = euler_rates_to_w_nb_b(kin.euler, kin.euler_rate)
        for i in range(n):
            k = self.stream.imu.k - n + i + 1
            items.append((imu.t[i], 0, (imu.dtheta[i], imu.dv[i])))
            if k % self.truth_every == 0:
                items.append((imu.t[i], 1, (imu.euler[i], imu.v_n[i], imu.pos[i], w_nb_b[i])))
        if b.gnss is not None:
            g = b.gnss
            for j in range(len(g.t)):
                items.append((g.t[j], 2, (g.lat[j], g.lon[j], g.h[j], g.v_n[j], g.fix[j],
                                          g.pos_cov, g.vel_cov)))
        items.sort(key=lambda it: (it[0], it[1]))
        self._queue.extend(items)
        return True

    # -- publishing -----------------------------------------------------------------
    def _tick(self):
        if self.done:
            return
        if self._wall0 is None:
            self._wall0 = time.monotonic()
        if self._rtf > 0:
            target = self._sim_t_at_wall0 + (time.monotonic() - self._wall0) * self._rtf
        else:
            target = self._k * self.dt + 0.1   # as fast as possible: 0.1 s of data a tick
        last_t = None
        while True:
            if not self._queue and not self._refill():
                self._finish()
                break
            t, kind, payload = self._queue[0]
            if t > target + 1e-9:
                break
            self._queue.popleft()
            stamp = ns_to_stamp(self.t0_ns + sec_to_ns(t))
            if kind == 0:
                self._publish_imu(stamp, *payload)
                self._k += 1
            elif kind == 1:
                self._publish_truth(stamp, *payload)
            else:
                self._publish_gnss(stamp, *payload)
            last_t = t
        if last_t is not None and (self._publish_clock or self._rtf == 0):
            self.pub_clock.publish(Clock(clock=ns_to_stamp(self.t0_ns + sec_to_ns(last_t))))

    def _finish(self):
        self.timer.cancel()
        self.get_logger().info(f'scenario finished after {self._k} IMU samples '
                               f'({self._k * self.dt:.1f} s)')
        if self.shutdown_when_done:
            self._drain()
        self.done = True

    def _drain(self, timeout_s=_DRAIN_S):
        """Wait until every reliable subscriber acknowledged what we published.

        The process exits right after the last sample when ``shutdown_when_done`` is set; without
        this, the last messages still in the writer's history die with it.
        """
        pubs = (self.pub_imu, self.pub_fix, self.pub_vel, self.pub_truth, self.pub_clock)
        late = [p.topic_name for p in pubs
                if not p.wait_for_all_acked(Duration(seconds=timeout_s))]
        if late:
            self.get_logger().warn(f'exiting with messages unacknowledged after {timeout_s:.0f} s '
                                   f'on {", ".join(late)}')

    def _publish_imu(self, stamp, dtheta, dv):
        m = Imu()
        m.header.stamp = stamp
        m.header.frame_id = self.frames[0]
        m.orientation_covariance[0] = -1.0
        set_vector3(m.angular_velocity, dtheta / self.dt)
        set_vector3(m.linear_acceleration, dv / self.dt)
        m.angular_velocity_covariance = diag_cov(3, [self.gyro_var] * 3)
        m.linear_acceleration_covariance = diag_cov(3, [self.accel_var] * 3)
        self.pub_imu.publish(m)

    def _publish_truth(self, stamp, euler, v_n, pos, w_nb_b):
        m = Odometry()
        m.header.stamp = stamp
        m.header.frame_id = self.frames[2]
        m.child_frame_id = self.frames[0]
        off = earth.local_offset_m(self.origin[0], self.origin[1], self.origin[2], *pos)
        set_vector3(m.pose.pose.position, off)
        set_quaternion(m.pose.pose.orientation, euler_to_quat(euler))
        set_vector3(m.twist.twist.linear, euler_to_dcm(euler).T @ v_n)
        set_vector3(m.twist.twist.angular, w_nb_b)
        self.pub_truth.publish(m)

    def _publish_gnss(self, stamp, lat, lon, h, v_n, fix, pos_cov, vel_cov):
        f = NavSatFix()
        f.header.stamp = stamp
        f.header.frame_id = self.frames[1]
        f.status.service = NavSatStatus.SERVICE_GPS
        if fix:
            f.status.status = NavSatStatus.STATUS_FIX
            f.latitude = math.degrees(lat)
            f.longitude = math.degrees(lon)
            f.altitude = float(h)
            f.position_covariance = diag_cov(3, pos_cov)
            f.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
        else:
            f.status.status = NavSatStatus.STATUS_NO_FIX
            f.latitude = f.longitude = f.altitude = float('nan')
            f.position_covariance_type = NavSatFix.COVARIANCE_TYPE_UNKNOWN
        self.pub_fix.publish(f)
        if fix:
            v = TwistWithCovarianceStamped()
            v.header = f.header
            set_vector3(v.twist.twist.linear, v_n)
            v.twist.covariance = diag_cov(6, list(vel_cov) + [1e6] * 3)
            self.pub_vel.publish(v)


def main(args=None):
    """Entry point of ``ros2 run sins_align_ros simulator_node``."""
    return run(SimulatorNode, 'simulator_node',
               done=lambda node: node.done and node.shutdown_when_done, args=args)


if __name__ == '__main__':
    sys.exit(main())

"""simulator_node: publishes simulated IMU and GNSS data with ground truth.

Publishes (relative names, remappable):

* ``imu/data_raw`` (sensor_msgs/Imu): mean angular rate and specific force over
  each sample interval (increment / dt), FLU body, stamped at the interval's end;
  covariances from the white-noise terms of the IMU spec; orientation unknown
  (``orientation_covariance[0] = -1``, REP-145).
* ``gnss/fix`` (sensor_msgs/NavSatFix): STATUS_FIX with a diagonal ENU covariance,
  or STATUS_NO_FIX with NaN position during outages.
* ``gnss/vel`` (geometry_msgs/TwistWithCovarianceStamped): ENU velocity; not created
  for a scenario whose receiver has no velocity (``GnssSpec.velocity`` False).
* ``sim/truth`` (nav_msgs/Odometry): pose in the local ENU frame ``world_frame_id``
  with its origin at the start position; twist in the body frame (the
  message's convention: ``child_frame_id``).
* ``/clock`` (rosgraph_msgs/Clock) when ``publish_clock`` is true or
  ``real_time_factor`` is 0 (as fast as possible), so ``use_sim_time`` nodes follow.

Stamps are ``start_time + t`` where ``start_time`` defaults to the node's clock at
start-up. Output is deterministic for a given ``seed``. The messages are built by
:class:`~sins_align_ros.io.sim_messages.SimulatedMessages`, which also records them into a
rosbag2 without a ROS graph (``sins_align_record``).
"""
import importlib
import sys
import time
from collections import deque

from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from .conversions import ns_to_stamp, sec_to_ns
from .params import Param, declare
from .runner import run
from ..io.sim_messages import SimulatedMessages, simulated_scenario, topics
from ..sim.presets import SCENARIOS, SENSOR_GRADES

PARAMS = (
    Param('scenario', 'static_navigation', 'named scenario preset (sim/presets.py)',
          choices=SCENARIOS, read_only=True),
    Param('grade', '', 'sensor grade preset that replaces the scenario\'s IMU error model: '
          f'{", ".join(SENSOR_GRADES)}; empty: the scenario\'s own', read_only=True),
    Param('seed', 0, 'random seed; the same seed gives the same data', 0, 2 ** 31 - 1,
          read_only=True),
    Param('imu_rate_hz', 0.0, 'IMU rate, Hz (0: the scenario default, 100 Hz for most)', 0.0,
          4000.0,
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

_TICK_S = 0.005  # publishing timer period (wall time)
_DRAIN_S = 5.0   # at most this long waiting for acknowledgements before exiting


class SimulatorNode(Node):
    """Streams a scenario preset onto the ROS graph; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__('simulator_node', **kwargs)
        p = declare(self, PARAMS)
        self.sc = simulated_scenario(p['scenario'], p['grade'], p['duration'])
        start = p['start_time'] or self.get_clock().now().nanoseconds * 1e-9
        self.t0_ns = sec_to_ns(start)
        self.messages = SimulatedMessages(
            self.sc, ros_message_class, seed=p['seed'], imu_rate_hz=p['imu_rate_hz'] or None,
            gnss_rate_hz=p['gnss_rate_hz'] or None, truth_rate_hz=p['truth_rate_hz'],
            frames=(p['imu_frame_id'], p['gnss_frame_id'], p['world_frame_id']),
            start_ns=self.t0_ns)
        self.dt = self.messages.dt
        self.shutdown_when_done = p['shutdown_when_done']
        self.done = False

        # The IMU writer keeps five wall seconds of samples (at least 1000): a reader whose
        # executor is held up loses packets in transport, and the reliable protocol repairs
        # them on the next heartbeat (3 s in Fast DDS by default) only if the writer still
        # holds them (CI lost 6 samples in 1200 at 8x and 200 Hz with a 1000-sample history).
        rate = max(p["real_time_factor"], 1.0) / self.dt
        qos = QoSProfile(depth=int(min(max(1000, 5 * rate), 50000)),
                         reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
        depth = {'imu': qos, 'fix': 10, 'vel': 10, 'truth': 50}
        self.pubs = {k: self.create_publisher(ros_message_class(typ), name, depth[k])
                     for k, (name, typ) in topics(self.sc).items()}
        self.pub_clock = self.create_publisher(Clock, '/clock', 10)
        self._queue = deque()   # pending (t, key, args) in stamp order
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
        items = self.messages.next_block()
        self._queue.extend(items)
        return bool(items)

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
            t, key, args = self._queue[0]
            if t > target + 1e-9:
                break
            self._queue.popleft()
            self.pubs[key].publish(self.messages.build(key, args))
            self._k += key == 'imu'
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
        pubs = (*self.pubs.values(), self.pub_clock)
        late = [p.topic_name for p in pubs
                if not p.wait_for_all_acked(Duration(seconds=timeout_s))]
        if late:
            self.get_logger().warn(f'exiting with messages unacknowledged after {timeout_s:.0f} s '
                                   f'on {", ".join(late)}')


def ros_message_class(name):
    """Return the ROS message class of a type name such as ``'sensor_msgs/msg/Imu'``."""
    package, kind, cls = name.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), cls)


def main(args=None):
    """Entry point of ``ros2 run sins_align_ros simulator_node``."""
    return run(SimulatorNode, 'simulator_node',
               done=lambda node: node.done and node.shutdown_when_done, args=args)


if __name__ == '__main__':
    sys.exit(main())

"""alignment_node: SINS initial alignment from sensor_msgs/Imu (and GNSS).

This first version is the node shell of DESIGN.md: it declares the shared
parameters, subscribes to ``imu/data_raw`` (sensor-data QoS) and ``gnss/fix``,
checks and counts the input, and publishes ``/diagnostics`` in
diagnostic_updater's layout (status name ``<node>: alignment``) with the
phase ``waiting``. The alignment pipeline (coarse -> fine -> aligned) plugs
in behind the same topics.
"""
import sys

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus

from .conversions import finite, stamp_to_ns
from .params import Param, declare

FINE_FILTERS = ('reduced7', 'stationary10', 'stationary12', 'ckf', 'asckf', 'ukf',
                'vbakf', 'mvbakf', 'vbckf', 'vbch')
COARSE_METHODS = ('auto', 'analytic', 'inertial_frame')

PARAMS = (
    Param('fine_filter', 'reduced7', 'fine-alignment filter', choices=FINE_FILTERS),
    Param('coarse_method', 'auto', 'coarse alignment method', choices=COARSE_METHODS),
    Param('coarse_duration', 60.0, 'coarse alignment time, s', 1.0, 3600.0),
    Param('initial_latitude_deg', 0.0, 'latitude used without a GNSS fix, deg', -90.0, 90.0),
    Param('initial_longitude_deg', 0.0, 'longitude used without a GNSS fix, deg', -180.0, 180.0),
    Param('initial_height_m', 0.0, 'height used without a GNSS fix, m', -1000.0, 50000.0),
    Param('imu_frame_id', '', 'expected frame_id of imu/data_raw (empty: accept any)'),
    Param('diagnostic_period', 1.0, 'period of /diagnostics, s', 0.05, 60.0),
)


class AlignmentNode(Node):
    """Subscribes to IMU and GNSS, publishes diagnostics; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__('alignment_node', **kwargs)
        self.p = declare(self, PARAMS)
        imu_qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.BEST_EFFORT,
                             history=HistoryPolicy.KEEP_LAST,
                             durability=qos_profile_sensor_data.durability)
        self.create_subscription(Imu, 'imu/data_raw', self._on_imu, imu_qos)
        self.create_subscription(NavSatFix, 'gnss/fix', self._on_fix, qos_profile_sensor_data)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.counts = {'imu': 0, 'imu_rejected': 0, 'gnss': 0, 'gnss_no_fix': 0}
        self.last_imu_ns = None
        self.first_imu_ns = None
        self.phase = 'waiting'
        self.create_timer(self.p['diagnostic_period'], self._publish_diagnostics)

    def _on_imu(self, msg):
        t_ns = stamp_to_ns(msg.header.stamp)
        w, a = msg.angular_velocity, msg.linear_acceleration
        if not finite(w.x, w.y, w.z, a.x, a.y, a.z) or (
                self.last_imu_ns is not None and t_ns <= self.last_imu_ns):
            self.counts['imu_rejected'] += 1
            return
        if self.first_imu_ns is None:
            self.first_imu_ns = t_ns
        self.last_imu_ns = t_ns
        self.counts['imu'] += 1

    def _on_fix(self, msg):
        if msg.status.status < NavSatStatus.STATUS_FIX:
            self.counts['gnss_no_fix'] += 1
        else:
            self.counts['gnss'] += 1

    def _publish_diagnostics(self):
        st = DiagnosticStatus()
        st.name = f'{self.get_name()}: alignment'
        st.hardware_id = self.p['imu_frame_id'] or 'imu'
        if self.counts['imu'] == 0:
            st.level = DiagnosticStatus.WARN
            st.message = 'waiting for IMU data on imu/data_raw'
        else:
            st.level = DiagnosticStatus.OK
            st.message = f'phase {self.phase}'
        elapsed = 0.0
        if self.first_imu_ns is not None:
            elapsed = (self.last_imu_ns - self.first_imu_ns) * 1e-9
        values = {'phase': self.phase, 'elapsed_s': f'{elapsed:.3f}',
                  'fine_filter': self.p['fine_filter']}
        values.update({f'{k}_count': str(v) for k, v in self.counts.items()})
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = [st]
        self.pub_diag.publish(arr)


def main(args=None):
    """Entry point of ``ros2 run sins_align_ros alignment_node``."""
    rclpy.init(args=args)
    node = None
    try:
        node = AlignmentNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ValueError as exc:
        print(f'alignment_node: {exc}', file=sys.stderr)
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())

"""Publish a :class:`~sins_align_ros.sim.faults.MessageStream` on a real ROS graph.

Used by the fault-injection tests and the soak benchmark: a publisher node sends
the (possibly corrupted) messages in publication order, in batches, and after
each batch spins the executor until the receiving alignment node has taken
them all, so nothing is lost to queue depth however fast the stream is played.
"""
import time

from geometry_msgs.msg import TwistWithCovarianceStamped
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, NavSatFix

from .conversions import diag_cov, ns_to_stamp, sec_to_ns, set_vector3


def imu_msg(s, i):
    """sensor_msgs/Imu of sample ``i`` of stream ``s``."""
    c = s.imu
    m = Imu()
    m.header.stamp = ns_to_stamp(sec_to_ns(c['t'][i]))
    m.header.frame_id = c['frame'][i]
    m.orientation_covariance[0] = -1.0
    set_vector3(m.angular_velocity, c['w'][i])
    set_vector3(m.linear_acceleration, c['f'][i])
    if c['missing'][i]:
        m.angular_velocity_covariance[0] = -1.0
    return m


def gnss_msgs(s, i):
    """Build the NavSatFix (and TwistWithCovarianceStamped or None) of GNSS epoch ``i``."""
    c = s.gnss
    f = NavSatFix()
    f.header.stamp = ns_to_stamp(sec_to_ns(c['t'][i]))
    f.header.frame_id = 'gnss_link'
    f.status.status = int(c['status'][i])
    f.latitude, f.longitude, f.altitude = (float(c['lat_deg'][i]), float(c['lon_deg'][i]),
                                           float(c['h'][i]))
    f.position_covariance = diag_cov(3, list(c['pos_var'][i]) + [float(c['pos_var'][i][0])])
    f.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
    if not c['has_vel'][i]:
        return f, None
    v = TwistWithCovarianceStamped()
    v.header = f.header
    set_vector3(v.twist.twist.linear, c['vel'][i])
    v.twist.covariance = diag_cov(6, list(c['vel_var'][i]) + [1.0, 1e6, 1e6, 1e6])
    return f, v


class Player:
    """Publisher node for a stream; ``play`` waits until ``target`` has received everything.

    ``target`` is an :class:`~sins_align_ros.ros.alignment_node.AlignmentNode` (its
    ``received`` counter is read).
    """

    def __init__(self, node, target):
        self.node = node
        self.target = target
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                         history=HistoryPolicy.KEEP_LAST)
        self.pub_imu = node.create_publisher(Imu, 'imu/data_raw', qos)
        self.pub_fix = node.create_publisher(NavSatFix, 'gnss/fix', 100)
        self.pub_vel = node.create_publisher(TwistWithCovarianceStamped, 'gnss/vel', 100)
        self.sent = 0

    def wait_for_subscribers(self, executor, timeout_s=10.0):
        """Spin until the three topics are matched (discovery); returns success."""
        end = time.monotonic() + timeout_s
        pubs = (self.pub_imu, self.pub_fix, self.pub_vel)
        while time.monotonic() < end:
            if all(p.get_subscription_count() > 0 for p in pubs):
                return True
            executor.spin_once(timeout_sec=0.05)
        return False

    def play(self, executor, stream, t0=float('-inf'), t1=float('inf'), batch=200,
             timeout_s=30.0):
        """Publish the messages of ``stream`` published in [t0, t1); returns the number sent."""
        n0 = self.sent
        evs = stream.events(t0, t1)
        for b in range(0, len(evs), batch):
            for kind, i in evs[b:b + batch]:
                if kind == 'imu':
                    self.pub_imu.publish(imu_msg(stream, i))
                    self.sent += 1
                else:
                    fix, vel = gnss_msgs(stream, i)
                    self.pub_fix.publish(fix)
                    self.sent += 1
                    if vel is not None:
                        self.pub_vel.publish(vel)
                        self.sent += 1
            self.drain(executor, timeout_s)
        return self.sent - n0

    def drain(self, executor, timeout_s=30.0):
        """Spin until the target has received every message sent; raises on timeout."""
        end = time.monotonic() + timeout_s
        while sum(self.target.received.values()) < self.sent:
            if time.monotonic() > end:
                raise TimeoutError(f'{self.sent - sum(self.target.received.values())} of '
                                   f'{self.sent} messages not received')
            executor.spin_once(timeout_sec=0.01)

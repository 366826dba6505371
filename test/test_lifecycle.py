"""The managed alignment node over real executors, driven through its lifecycle services.

A client node in the same Context calls ``/alignment_node/change_state`` and
``/alignment_node/get_state`` (lifecycle_msgs), feeds ``imu/data_raw`` with a still,
noise-free IMU (gravity and Earth rate at 34 deg N, a known attitude) and records
``imu/data`` and ``/diagnostics``; the transition methods are never called directly.
"""

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from lifecycle_msgs.msg import State, Transition  # noqa: E402
from lifecycle_msgs.srv import ChangeState, GetState  # noqa: E402
from rcl_interfaces.msg import Log  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import Imu  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from conftest import running, spin_until  # noqa: E402
from sins_align_ros.nav import earth  # noqa: E402
from sins_align_ros.nav.frames import euler_to_dcm, quat_to_euler  # noqa: E402
from sins_align_ros.ros.alignment_lifecycle_node import AlignmentLifecycleNode  # noqa: E402
from sins_align_ros.ros.conversions import ns_to_stamp, set_vector3, stamp_to_ns  # noqa: E402
from sins_align_ros.units import DEG  # noqa: E402
from test_package import resolve_executable  # noqa: E402

pytestmark = pytest.mark.ros
LAT = 34.0 * DEG
#: the IMU's attitude (REP-103 roll, pitch, yaw) and its specific force and rate
RPY = np.array([2.0, -3.0, 30.0]) * DEG
_C_b_n = euler_to_dcm(RPY)
F_B = _C_b_n.T @ [0.0, 0.0, earth.gravity(LAT, 0.0)]
W_B = _C_b_n.T @ [0.0, earth.OMEGA_IE * np.cos(LAT), earth.OMEGA_IE * np.sin(LAT)]
RATE_NS = 10_000_000                     # 100 Hz
T0_NS = 100 * 10 ** 9
RELIABLE = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
PARAMS = {'coarse_duration': 1.0, 'diagnostic_period': 0.1, 'fine_filter': 'reduced7',
          'initial_latitude_deg': 34.0}


def still_imu(i):
    """Sample ``i`` (stamp ``T0 + i * 10 ms``) of the still IMU."""
    m = Imu()
    m.header.stamp = ns_to_stamp(T0_NS + i * RATE_NS)
    m.header.frame_id = 'imu_link'
    m.orientation_covariance[0] = -1.0
    set_vector3(m.angular_velocity, W_B)
    set_vector3(m.linear_acceleration, F_B)
    return m


def euler_of(msg):
    q = msg.orientation
    return quat_to_euler([q.x, q.y, q.z, q.w])


class Client:
    """A lifecycle client node feeding the IMU and recording the output, one executor."""

    def __init__(self, ctx, node_name='lifecycle_client', node=None):
        self.node = node
        self.cl = rclpy.create_node(node_name, context=ctx)
        self.change = self.cl.create_client(ChangeState, '/alignment_node/change_state')
        self.get = self.cl.create_client(GetState, '/alignment_node/get_state')
        self.reset = self.cl.create_client(Trigger, '/alignment_node/reset')
        self.pub = self.cl.create_publisher(Imu, 'imu/data_raw', RELIABLE)
        self.out, self.diag, self.log = [], [], []
        self.sub_out = self.cl.create_subscription(Imu, 'imu/data', self.out.append, RELIABLE)
        self.cl.create_subscription(DiagnosticArray, '/diagnostics', self.diag.append, RELIABLE)
        # /rosout keeps its last messages (transient local): a subscription that matched
        # after the node logged still gets them (a discovery race failed CI once)
        self.sub_log = self.cl.create_subscription(Log, '/rosout', self.log.append, QoSProfile(
            depth=1000, reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.ex = SingleThreadedExecutor(context=ctx)
        self.ex.add_node(self.cl)
        if node is not None:
            self.ex.add_node(node)
        self.sent = 0
        assert spin_until(self.ex, lambda: self.change.service_is_ready()
                          and self.get.service_is_ready(), timeout_s=30.0)

    def call(self, client, request):
        fut = client.call_async(request)
        assert spin_until(self.ex, fut.done, timeout_s=10.0)
        return fut.result()

    def transition(self, transition_id):
        """Request a transition over ~/change_state; return its success."""
        req = ChangeState.Request(transition=Transition(id=transition_id))
        return self.call(self.change, req).success

    def state(self):
        """Return the node's state label from ~/get_state."""
        return self.call(self.get, GetState.Request()).current_state.label

    def feed(self, n, wait=True):
        """Publish the next ``n`` samples; with ``wait``, until the node took them all."""
        start = self.node.received['imu/data_raw'] if wait else 0
        for _ in range(n):
            self.sent += 1
            self.pub.publish(still_imu(self.sent))
        if wait:
            assert spin_until(self.ex, lambda: self.node.received['imu/data_raw'] - start == n,
                              timeout_s=10.0)

    def wait_matched(self):
        """Spin until imu/data_raw reaches the node and imu/data reaches us (discovery)."""
        assert spin_until(self.ex, lambda: self.pub.get_subscription_count() == 1
                          and self.sub_out.get_publisher_count() == 1, timeout_s=10.0)

    def wait_log_matched(self, node_name='alignment_node'):
        """Spin until ``node_name``'s /rosout publisher is matched by our log subscription.

        Transient local keeps the node's lines only for their 10 s lifespan: a loaded CI run once
        matched later than that and the first refusal's line never arrived.
        """
        def matched():
            names = {i.node_name for i in self.cl.get_publishers_info_by_topic('/rosout')}
            return node_name in names and self.sub_log.get_publisher_count() >= 2
        assert spin_until(self.ex, matched, timeout_s=30.0)

    def settle(self, seconds):
        spin_until(self.ex, lambda: False, timeout_s=seconds)


def make(ros_context, **params):
    node = AlignmentLifecycleNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in dict(PARAMS, **params).items()])
    return node, Client(ros_context, node=node)


def test_configure_activate_deactivate_cleanup_through_the_services(ros_context):
    node, c = make(ros_context)
    assert c.state() == 'unconfigured'
    assert node.session is None and node.pub_imu is None
    assert c.reset.service_is_ready() is False

    assert c.transition(Transition.TRANSITION_CONFIGURE)
    assert c.state() == 'inactive'
    assert node.pipeline.phase == 'waiting' and node.pipeline.cfg['fine_filter'] == 'reduced7'
    # inactive: the publishers exist (matched), but nothing is subscribed or published
    assert spin_until(c.ex, lambda: c.sub_out.get_publisher_count() == 1
                      and node.pub_diag.get_subscription_count() >= 1, timeout_s=10.0)
    c.feed(50, wait=False)
    c.settle(0.6)                          # six diagnostic periods
    assert c.pub.get_subscription_count() == 0
    assert sum(node.received.values()) == 0 and node.counts['imu'] == 0
    assert c.out == [] and c.diag == []

    assert c.transition(Transition.TRANSITION_ACTIVATE)
    assert c.state() == 'active'
    c.wait_matched()
    c.feed(300)
    # every accepted sample (the first only starts the clock) comes out with its own stamp
    assert spin_until(c.ex, lambda: len(c.out) == 299, timeout_s=5.0)
    assert [stamp_to_ns(m.header.stamp) for m in c.out] == [
        T0_NS + i * RATE_NS for i in range(52, 351)]
    assert node.counts['imu'] == 299 and node.received['imu/data_raw'] == 300
    assert c.out[0].orientation_covariance[0] == -1.0          # coarse: unknown (REP-145)
    assert c.out[-1].orientation_covariance[0] > 0.0
    assert node.pipeline.phase in ('fine', 'aligned')
    assert np.abs(euler_of(c.out[-1]) - RPY).max() < 0.01 * DEG
    assert spin_until(c.ex, lambda: c.diag, timeout_s=2.0)
    assert c.diag[-1].status[0].name == '/alignment_node: alignment'   # fully qualified

    assert c.transition(Transition.TRANSITION_DEACTIVATE)
    assert c.state() == 'inactive'
    c.settle(0.3)                          # what was in flight
    n_out, n_diag, received = len(c.out), len(c.diag), sum(node.received.values())
    assert n_out == 299
    c.feed(100, wait=False)
    c.settle(0.6)
    assert c.pub.get_subscription_count() == 0
    assert len(c.out) == n_out and len(c.diag) == n_diag
    assert sum(node.received.values()) == received
    assert node.pipeline.phase in ('fine', 'aligned')           # the session is kept

    assert c.transition(Transition.TRANSITION_CLEANUP)
    assert c.state() == 'unconfigured'
    assert node.session is None and node.pipeline is None and node.pub_imu is None
    assert spin_until(c.ex, lambda: not c.reset.service_is_ready()
                      and c.sub_out.get_publisher_count() == 0, timeout_s=5.0)

    # configure again: a new session, counters from zero, and it publishes once active
    assert c.transition(Transition.TRANSITION_CONFIGURE)
    assert c.state() == 'inactive'
    assert node.pipeline.phase == 'waiting' and node.counts['imu'] == 0
    assert c.transition(Transition.TRANSITION_ACTIVATE)
    c.wait_matched()
    n_out = len(c.out)
    c.feed(20)
    assert spin_until(c.ex, lambda: len(c.out) == n_out + 19, timeout_s=5.0)
    assert node.counts['imu'] == 19
    assert c.transition(Transition.TRANSITION_ACTIVE_SHUTDOWN)
    assert c.state() == 'finalized'
    assert node.session is None and node.pub_imu is None
    c.ex.shutdown()


def test_reset_while_active_restarts_and_output_continues(ros_context):
    node, c = make(ros_context)
    assert c.transition(Transition.TRANSITION_CONFIGURE)
    assert c.transition(Transition.TRANSITION_ACTIVATE)
    c.wait_matched()
    c.feed(200)
    assert spin_until(c.ex, lambda: len(c.out) == 199, timeout_s=5.0)
    old = node.pipeline
    assert old.phase in ('fine', 'aligned')
    assert c.reset.wait_for_service(timeout_sec=5.0)
    res = c.call(c.reset, Trigger.Request())
    assert res.success and 'restarted' in res.message
    assert node.pipeline is not old and node.pipeline.phase == 'waiting'
    assert c.state() == 'active'

    c.feed(150)
    # the restart starts the clock again: the first sample after it gives no row
    assert spin_until(c.ex, lambda: len(c.out) == 199 + 149, timeout_s=5.0)
    after = c.out[199:]
    assert stamp_to_ns(after[0].header.stamp) == T0_NS + 202 * RATE_NS
    assert after[0].orientation_covariance[0] == -1.0          # coarse again
    assert after[-1].orientation_covariance[0] > 0.0
    assert node.pipeline.phase in ('fine', 'aligned')
    assert np.abs(euler_of(after[-1]) - RPY).max() < 0.01 * DEG
    assert spin_until(c.ex, lambda: any(
        'alignment restarted: ~/reset service' in d.status[0].message for d in c.diag),
        timeout_s=2.0)
    c.ex.shutdown()


def test_invalid_parameter_fails_configure_and_changes_are_stored_until_configured(
        ros_context, capfd):
    node, c = make(ros_context, fine_filter='magic')
    assert c.state() == 'unconfigured'
    assert not c.transition(Transition.TRANSITION_CONFIGURE)
    assert c.state() == 'unconfigured'
    assert node.session is None and node.pub_imu is None
    # the reason is logged at ERROR: on /rosout, or (its delivery over DDS raced the
    # subscription's discovery twice in full parallel runs) on the console
    on_rosout = spin_until(c.ex, lambda: any(
        m.name == 'alignment_node' and m.level == Log.ERROR and "fine_filter='magic'" in m.msg
        for m in c.log), timeout_s=5.0)
    err = capfd.readouterr().err
    assert on_rosout or ('[ERROR]' in err and "fine_filter='magic'" in err), err
    # unconfigured: a bad value is still refused on its own, a good one just stored
    res = node.set_parameters([Parameter('fine_filter', value='kalman')])[0]
    assert not res.successful and 'fine_filter' in res.reason
    res = node.set_parameters([Parameter('fine_filter', value='stationary10')])[0]
    assert res.successful and node.session is None
    assert c.transition(Transition.TRANSITION_CONFIGURE)
    assert c.state() == 'inactive'
    assert node.pipeline.cfg['fine_filter'] == 'stationary10'
    # configured: an alignment parameter restarts the session with it
    old = node.pipeline
    res = node.set_parameters([Parameter('coarse_duration', value=2.0)])[0]
    assert res.successful
    assert node.pipeline is not old and node.pipeline.cfg['coarse_duration'] == 2.0
    res = node.set_parameters([Parameter('fine_filter', value='magic')])[0]
    assert not res.successful and node.pipeline.cfg['fine_filter'] == 'stationary10'
    # that restart happened while inactive: the first diagnostics after activation say so
    assert spin_until(c.ex, lambda: node.pub_diag.get_subscription_count() >= 1, 10.0)
    c.settle(0.3)
    assert c.diag == []
    assert c.transition(Transition.TRANSITION_ACTIVATE)
    assert spin_until(c.ex, lambda: c.diag, timeout_s=2.0)
    assert ('alignment restarted: parameters changed: coarse_duration'
            in c.diag[0].status[0].message)
    c.ex.shutdown()


def test_lifecycle_executable_is_managed_over_its_services_and_exits_on_sigint(
        ros_context, domain_id):
    """`ros2 run sins_align_ros alignment_lifecycle_node`: configure, activate, output, Ctrl-C."""
    with running([resolve_executable('alignment_lifecycle_node'), '--ros-args',
                  '-p', 'coarse_duration:=1.0', '-p', 'initial_latitude_deg:=34.0'],
                 domain_id) as proc:
        c = Client(ros_context, node_name='probe')
        assert spin_until(c.ex, lambda: 'alignment_node' in c.cl.get_node_names(),
                          timeout_s=10.0)
        assert c.state() == 'unconfigured'
        assert c.transition(Transition.TRANSITION_CONFIGURE)
        assert c.transition(Transition.TRANSITION_ACTIVATE)
        assert c.call(c.get, GetState.Request()).current_state.id == State.PRIMARY_STATE_ACTIVE
        c.wait_matched()
        for _ in range(3):
            c.feed(50, wait=False)
            c.settle(0.1)
        assert spin_until(c.ex, lambda: len(c.out) == 149, timeout_s=10.0)
        assert np.abs(euler_of(c.out[-1]) - RPY).max() < 0.01 * DEG
    assert proc.returncode == 0, proc.err
    assert 'Traceback' not in proc.err and 'Traceback' not in proc.out

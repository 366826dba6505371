"""The alignment node as a navigator (issue 5): ~/odom at IMU rate over real DDS."""
import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402

from conftest import spin_until  # noqa: E402
from sins_align_ros.nav import earth  # noqa: E402
from sins_align_ros.nav.frames import euler_to_dcm  # noqa: E402
from sins_align_ros.ros.alignment_node import AlignmentNode  # noqa: E402
from sins_align_ros.ros.conversions import stamp_to_sec  # noqa: E402
from sins_align_ros.ros.playback import Player  # noqa: E402
from sins_align_ros.sim.faults import MessageStream  # noqa: E402
from sins_align_ros.sim.presets import alignment_params, scenario  # noqa: E402
from sins_align_ros.sim.scenario import ScenarioStream  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _run_car(ros_context, fine_filter, duration=200.0, **extra):
    sc = scenario('seed003_car', duration=duration)
    block = ScenarioStream(sc, seed=2).next_block(int(duration * 100))
    stream = MessageStream(block)
    params = alignment_params(sc, fine_filter, **extra)
    node = AlignmentNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in params.items()] + [
        Parameter('diagnostic_period', value=0.5), Parameter('odom_frame_id', value='car_odom')])
    pub = rclpy.create_node('player', context=ros_context)
    probe = rclpy.create_node('odom_probe', context=ros_context)
    odom, diag = [], []
    probe.create_subscription(Odometry, 'alignment_node/odom', odom.append,
                              QoSProfile(depth=30000, reliability=ReliabilityPolicy.RELIABLE))
    probe.create_subscription(DiagnosticArray, '/diagnostics', diag.append, 10)
    ex = SingleThreadedExecutor(context=ros_context)
    for n in (node, pub, probe):
        ex.add_node(n)
    player = Player(pub, node)
    assert player.wait_for_subscribers(ex)
    player.play(ex, stream, batch=500)
    return node, ex, odom, diag, block


def test_ukf_node_publishes_odometry_at_imu_rate_against_truth(ros_context):
    """fine_filter ukf on 120 s of seed 003's car through real publishers: one ~/odom per
    IMU sample from the start of fine alignment, frames as documented, position and body
    velocity within 3 sigma of the simulator truth, and the origin in the diagnostics."""
    node, ex, odom, diag, block = _run_car(ros_context, 'ukf', duration=120.0)
    # the car drives off at 30 s; the coarse window ends 5 s after the 1 Hz receiver shows
    # it moving (issue 46), by 38 s: from there on one ~/odom per IMU sample
    n_fine = int(np.sum(block.imu.t > 38.0 + 1e-6))
    assert spin_until(ex, lambda: len(odom) >= n_fine - 5, timeout_s=30.0)
    spin_until(ex, lambda: False, timeout_s=1.0)       # diagnostics of the final state
    t = np.array([stamp_to_sec(m.header.stamp) for m in odom])
    assert 35.0 <= t[0] <= 38.0 + 1e-6
    n_fine = int(np.sum(block.imu.t > t[0] - 1e-6))
    assert n_fine - 5 <= len(odom) <= n_fine + 1
    assert np.all(np.diff(t) > 0) and np.median(np.diff(t)) == pytest.approx(0.01)
    last = odom[-1]
    assert last.header.frame_id == 'car_odom' and last.child_frame_id == 'imu_link'
    k = int(np.argmin(np.abs(block.imu.t - t[-1])))
    lat0, lon0, h0 = node.odom.origin
    truth = earth.local_offset_m(lat0, lon0, h0, *(block.imu.pos[k:k + 1].T))[0]
    p = last.pose.pose.position
    cov = np.array(last.pose.covariance).reshape(6, 6)
    assert np.allclose(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) > 0)
    # the origin (the INS position at fine start) itself carries the GNSS error there:
    # compare with 3 sigma of the current error and of the origin's (about the GNSS noise)
    err = np.array([p.x, p.y, p.z]) - truth
    assert np.all(np.abs(err) <= 3.0 * np.sqrt(np.diag(cov)[:3]) + 3.0 * np.array([10, 10, 5]))
    C = euler_to_dcm(block.imu.euler[k])
    v_b_true = C.T @ block.imu.v_n[k]
    tw = last.twist.twist.linear
    tcov = np.array(last.twist.covariance).reshape(6, 6)
    assert np.all(np.abs(np.array([tw.x, tw.y, tw.z]) - v_b_true)
                  <= 3.0 * np.sqrt(np.diag(tcov)[:3]) + 0.05)
    kv = {v.key: v.value for v in diag[-1].status[0].values}
    assert float(kv['odom_origin_lat_deg']) == pytest.approx(np.degrees(lat0), abs=1e-9)
    assert kv['fine_filter'] == 'ukf' and len(kv['R_sigma'].split()) == 6
    ex.shutdown()


def test_continue_navigation_false_publishes_no_odometry(ros_context):
    node, ex, odom, diag, block = _run_car(ros_context, 'mvbakf', duration=80.0,
                                           continue_navigation=False)
    spin_until(ex, lambda: False, timeout_s=1.0)
    assert odom == [] and node.pipeline.phase in ('fine', 'aligned')
    kv = {v.key: v.value for v in diag[-1].status[0].values}
    assert 'P_pred_trace_ratio' in kv
    ex.shutdown()

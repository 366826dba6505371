"""Nodes on a real DDS graph: simulator output, /clock, parameters, config files, SIGINT."""
import os
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import TwistWithCovarianceStamped  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus  # noqa: E402

from conftest import running, spin_until  # noqa: E402
from sins_align_ros.nav import earth  # noqa: E402
from sins_align_ros.nav.frames import (euler_to_dcm, nav_to_euler,  # noqa: E402
                                       quat_to_euler)
from sins_align_ros.ros.alignment_node import AlignmentNode  # noqa: E402
from sins_align_ros.ros.conversions import stamp_to_ns  # noqa: E402
from sins_align_ros.ros.runner import stop_processes  # noqa: E402
from sins_align_ros.ros.simulator_node import SimulatorNode  # noqa: E402
from sins_align_ros.units import DEG, DPSH, UG  # noqa: E402
from test_package import resolve_executable  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.exclusive]   # wall-clock paced nodes
ROOT = Path(__file__).resolve().parents[1]


class Recorder:
    """A node that records every message on the simulator's topics."""

    def __init__(self, ctx):
        self.node = rclpy.create_node('recorder', context=ctx)
        qos = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
        self.msgs = {k: [] for k in ('imu', 'fix', 'vel', 'truth', 'clock', 'diag')}
        for topic, typ, key in (('imu/data_raw', Imu, 'imu'), ('gnss/fix', NavSatFix, 'fix'),
                                ('gnss/vel', TwistWithCovarianceStamped, 'vel'),
                                ('sim/truth', Odometry, 'truth'), ('/clock', Clock, 'clock'),
                                ('/diagnostics', DiagnosticArray, 'diag')):
            self.node.create_subscription(typ, topic, self.msgs[key].append, qos)


def test_simulator_publishes_consistent_physical_data(ros_context):
    sim = SimulatorNode(context=ros_context, parameter_overrides=[
        Parameter('scenario', value='static_navigation'), Parameter('imu_rate_hz', value=200.0),
        Parameter('real_time_factor', value=4.0), Parameter('start_time', value=1000.0),
        Parameter('seed', value=3)])
    rec = Recorder(ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(sim)
    ex.add_node(rec.node)
    assert spin_until(ex, lambda: len(rec.msgs['fix']) >= 6 and len(rec.msgs['imu']) >= 1200,
                      timeout_s=30.0)
    imu = rec.msgs['imu']
    ns = np.array([stamp_to_ns(m.header.stamp) for m in imu])
    assert ns[0] == 1000 * 10 ** 9 + 5_000_000                 # start_time + first dt
    assert np.all(np.diff(ns) == 5_000_000)                     # 200 Hz, no gap, in order
    assert {m.header.frame_id for m in imu} == {'imu_link'}
    m0 = imu[0]
    assert m0.orientation_covariance[0] == -1.0                 # REP-145: no orientation
    assert m0.angular_velocity_covariance[0] == pytest.approx((0.001 * DPSH) ** 2 * 200)
    assert m0.linear_acceleration_covariance[8] == pytest.approx((10 * UG) ** 2 * 200)
    acc = np.array([[m.linear_acceleration.x, m.linear_acceleration.y,
                     m.linear_acceleration.z] for m in imu]).mean(axis=0)
    gyr = np.array([[m.angular_velocity.x, m.angular_velocity.y,
                     m.angular_velocity.z] for m in imu]).mean(axis=0)
    g = earth.gravity(34 * DEG, 50.0)
    assert acc == pytest.approx([0.0, 0.0, g], abs=3e-3)        # level: +g on z (100 ug bias)
    assert np.linalg.norm(gyr) == pytest.approx(earth.OMEGA_IE, rel=0.01)

    fix = rec.msgs['fix']
    fns = np.array([stamp_to_ns(m.header.stamp) for m in fix])
    assert np.all(np.diff(fns) == 10 ** 9)                      # 1 Hz
    assert all(m.status.status == NavSatStatus.STATUS_FIX for m in fix)
    assert fix[0].position_covariance_type == NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
    assert fix[0].position_covariance[0] == pytest.approx(1.0)
    assert fix[0].header.frame_id == 'gnss_link'
    lat = np.array([m.latitude for m in fix])
    assert np.abs(lat - 34.0).max() * DEG * earth.A < 6.0       # within 6 sigma of truth
    vel = rec.msgs['vel']
    assert vel and abs(vel[0].twist.twist.linear.x) < 0.3
    assert vel[0].twist.covariance[0] == pytest.approx(0.05 ** 2)

    truth = rec.msgs['truth']
    tns = np.array([stamp_to_ns(m.header.stamp) for m in truth])
    assert np.all(np.diff(tns) == 100_000_000)                  # 10 Hz
    q = truth[-1].pose.pose.orientation
    euler = quat_to_euler([q.x, q.y, q.z, q.w])
    assert euler == pytest.approx(nav_to_euler(0.0, 0.0, 30 * DEG), abs=1e-12)
    assert truth[-1].header.frame_id == 'enu' and truth[-1].child_frame_id == 'imu_link'
    ex.shutdown()


def test_as_fast_as_possible_mode_drives_use_sim_time_nodes(ros_context):
    sim = SimulatorNode(context=ros_context, parameter_overrides=[
        Parameter('scenario', value='ship_sway'), Parameter('duration', value=20.0),
        Parameter('real_time_factor', value=0.0), Parameter('start_time', value=500.0)])
    follower = rclpy.create_node('follower', context=ros_context, parameter_overrides=[
        Parameter('use_sim_time', value=True)])
    rec = Recorder(ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    for n in (sim, follower, rec.node):
        ex.add_node(n)
    t_wall = time.monotonic()
    assert spin_until(ex, lambda: sim.done, timeout_s=60.0)
    wall = time.monotonic() - t_wall
    spin_until(ex, lambda: follower.get_clock().now().nanoseconds == 520 * 10 ** 9 and stamp_to_ns(
        rec.msgs['clock'][-1].clock) == 520 * 10 ** 9, timeout_s=5.0)
    assert stamp_to_ns(rec.msgs['clock'][-1].clock) == 520 * 10 ** 9
    assert follower.get_clock().now().nanoseconds == 520 * 10 ** 9
    assert wall < 20.0                                           # faster than real time
    ex.shutdown()


def test_same_seed_same_data_different_seed_different_data(ros_context):
    def run(seed):
        sim = SimulatorNode(context=ros_context, parameter_overrides=[
            Parameter('scenario', value='static_tactical'), Parameter('duration', value=2.0),
            Parameter('real_time_factor', value=0.0), Parameter('seed', value=seed),
            Parameter('start_time', value=10.0)])
        rec = Recorder(ros_context)
        ex = SingleThreadedExecutor(context=ros_context)
        ex.add_node(sim)
        ex.add_node(rec.node)
        spin_until(ex, lambda: len(rec.msgs['imu']) >= 200, timeout_s=30.0)
        ex.shutdown()
        sim.destroy_node()
        rec.node.destroy_node()
        return [m.angular_velocity.x for m in rec.msgs['imu']][:200]

    a, b, c = run(1), run(1), run(2)
    assert len(a) == 200 and a == b and a != c


def test_invalid_parameters_are_refused_with_a_reason(ros_context):
    with pytest.raises(ValueError, match='not one of'):
        SimulatorNode(context=ros_context,
                      parameter_overrides=[Parameter('scenario', value='atlantis')])
    sim = SimulatorNode(context=ros_context)
    res = sim.set_parameters([Parameter('real_time_factor', value=-1.0)])[0]
    assert not res.successful and res.reason
    res = sim.set_parameters([Parameter('real_time_factor', value=2.0)])[0]
    assert res.successful and sim.get_parameter('real_time_factor').value == 2.0
    node = AlignmentNode(context=ros_context)
    res = node.set_parameters([Parameter('fine_filter', value='magic')])[0]
    assert not res.successful and 'fine_filter' in res.reason
    res = node.set_parameters([Parameter('initial_latitude_deg', value=95.0)])[0]
    assert not res.successful
    res = node.set_parameters([Parameter('fine_filter', value='mvbakf')])[0]
    assert res.successful and node.pipeline.aided
    res = node.set_parameters([Parameter('fine_filter', value='stationary12')])[0]
    assert res.successful and node.pipeline.cfg['fine_filter'] == 'stationary12'
    res = node.set_parameters([Parameter('fine_filter', value='asckf')])[0]
    assert res.successful and node.pipeline.aided
    res = node.set_parameters([Parameter('fine_filter', value='vbch')])[0]
    assert res.successful and node.pipeline.aided
    res = node.set_parameters([Parameter('gnss_lever_arm_m', value=[1.0, 2.0])])[0]
    assert not res.successful and 'array of 3' in res.reason
    res = node.set_parameters([Parameter('gnss_lever_arm_m', value=[-12.0, 3.0, 18.0])])[0]
    assert res.successful
    assert node.pipeline.configured['gnss_lever_arm_m'] == (-12.0, 3.0, 18.0)
    assert not node.pipeline.install.no_arm


def test_rotated_imu_gives_the_vehicle_attitude_in_base_link(ros_context):
    """imu_mounting_rpy_deg: imu/data in base_link, its rates and attitude the vehicle's."""
    from sins_align_ros.sim.presets import ROBOT_IMU_MOUNTING_RPY_DEG
    C_s_v = euler_to_dcm(np.radians(ROBOT_IMU_MOUNTING_RPY_DEG))
    node = AlignmentNode(context=ros_context, parameter_overrides=[
        Parameter('imu_mounting_rpy_deg', value=list(ROBOT_IMU_MOUNTING_RPY_DEG)),
        Parameter('coarse_duration', value=5.0), Parameter('fine_filter', value='reduced7'),
        Parameter('initial_latitude_deg', value=34.0)])
    sim = SimulatorNode(context=ros_context, parameter_overrides=[
        Parameter('scenario', value='seed003_car_rotated'), Parameter('start_time', value=10.0),
        Parameter('real_time_factor', value=5.0)])
    rec = Recorder(ros_context)
    out = []
    qos = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
    rec.node.create_subscription(Imu, 'imu/data', out.append, qos)
    ex = SingleThreadedExecutor(context=ros_context)
    for n in (node, sim, rec.node):
        ex.add_node(n)
    assert spin_until(ex, lambda: len(out) > 1000 and out[-1].orientation_covariance[0] > 0,
                      timeout_s=40.0)
    assert {m.header.frame_id for m in out} == {'base_link'}
    assert {m.header.frame_id for m in rec.msgs['imu']} == {'imu_link'}
    raw = {stamp_to_ns(m.header.stamp): m for m in rec.msgs['imu']}
    both = [m for m in out if stamp_to_ns(m.header.stamp) in raw]
    assert len(both) > 500
    for m in both[::50]:
        r = raw[stamp_to_ns(m.header.stamp)]
        w_s = [r.angular_velocity.x, r.angular_velocity.y, r.angular_velocity.z]
        f_s = [r.linear_acceleration.x, r.linear_acceleration.y, r.linear_acceleration.z]
        w_v = [m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z]
        f_v = [m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z]
        assert np.allclose(w_v, C_s_v @ w_s, atol=1e-12)
        assert np.allclose(f_v, C_s_v @ f_s, atol=1e-12)
    # the car stands still for 30 s, level: the vehicle's roll and pitch are near zero
    # (the IMU's own roll would be 90 deg)
    q = out[-1].orientation
    roll, pitch, _ = quat_to_euler([q.x, q.y, q.z, q.w])
    assert abs(roll) < 1.0 * DEG and abs(pitch) < 1.0 * DEG
    ex.shutdown()


def test_moving_base_diagnostics_carry_the_asckf_internals(ros_context):
    """fine_filter asckf: /diagnostics has fading factors, Q/R diagonals, NIS, test count."""
    from sins_align_ros.eval.feed import feed_arrays
    from sins_align_ros.sim.presets import scenario
    from sins_align_ros.sim.scenario import ScenarioStream
    node = AlignmentNode(context=ros_context, parameter_overrides=[
        Parameter('fine_filter', value='asckf'), Parameter('diagnostic_period', value=0.1),
        Parameter('gnss_pos_sigma_m', value=0.2)])
    b = ScenarioStream(scenario('seed000_case1', duration=80.0), seed=3).next_block(8000)
    node.session.start_clock(0.0)
    feed_arrays(node.session, b.imu, b.gnss)
    got = []
    probe = rclpy.create_node('diag_probe', context=ros_context)
    probe.create_subscription(DiagnosticArray, '/diagnostics', got.append, 10)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    ex.add_node(probe)
    assert spin_until(ex, lambda: got, timeout_s=10.0)
    kv = {v.key: v.value for v in got[-1].status[0].values}
    # the GNSS-aided fine stage, 20 s in: aligned once its estimate has settled inside the
    # thresholds (issue 46), so either phase of that stage
    assert kv['phase'] in ('fine', 'aligned') and kv['fine_filter'] == 'asckf'
    assert len(kv['fading_factors'].split()) == 13          # seed 000's 10 + accel bias
    assert len(kv['R_diag'].split()) == 4 and len(kv['Q_diag'].split()) == 13
    assert int(kv['divergence_test_fired']) >= 0 and float(kv['innovation_nis']) >= 0.0
    assert int(kv['gnss_used']) >= 15
    ex.shutdown()


def test_alignment_node_reports_waiting_then_counts_imu(ros_context):
    node = AlignmentNode(context=ros_context, parameter_overrides=[
        Parameter('diagnostic_period', value=0.2)])
    sim = SimulatorNode(context=ros_context, parameter_overrides=[
        Parameter('real_time_factor', value=5.0), Parameter('start_time', value=100.0)])
    rec = Recorder(ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    ex.add_node(rec.node)
    assert spin_until(ex, lambda: rec.msgs['diag'], timeout_s=10.0)
    st = rec.msgs['diag'][0].status[0]
    assert st.name == '/alignment_node: alignment' and 'waiting' in st.message
    assert st.level == DiagnosticStatus.WARN
    ex.add_node(sim)
    assert spin_until(ex, lambda: node.counts['imu'] > 300, timeout_s=30.0)
    assert node.session.imu_input.rejected == 0
    ex.shutdown()


def test_preprocessing_node_publishes_each_attitude_with_its_own_sample_header(ros_context):
    """preprocess: true: imu/data comes later than imu/data_raw (the denoising window), but
    every message carries the header of the raw sample it belongs to, in order."""
    node = AlignmentNode(context=ros_context, parameter_overrides=[
        Parameter('preprocess', value=True), Parameter('preprocess_window', value=32)])
    sim = SimulatorNode(context=ros_context, parameter_overrides=[
        Parameter('real_time_factor', value=5.0), Parameter('start_time', value=100.0)])
    rec = Recorder(ros_context)
    out = []
    rec.node.create_subscription(Imu, 'imu/data', out.append,
                                 QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE))
    ex = SingleThreadedExecutor(context=ros_context)
    for n in (node, sim, rec.node):
        ex.add_node(n)
    assert spin_until(ex, lambda: len(out) > 300, timeout_s=30.0)
    raw = {stamp_to_ns(m.header.stamp): m for m in rec.msgs['imu']}
    got = [stamp_to_ns(m.header.stamp) for m in out]
    assert all(b > a for a, b in zip(got, got[1:])), 'out of order or repeated'
    assert all(g % 10_000_000 == 0 for g in got)     # on the simulator's 100 Hz grid
    assert np.median(np.diff(got)) == 10_000_000     # every sample, not one per window
    both = [m for m in out if stamp_to_ns(m.header.stamp) in raw]
    assert len(both) > 100                           # (a loaded recorder may miss some)
    for m in both:                                   # the header and its own sample's data
        r = raw[stamp_to_ns(m.header.stamp)]
        assert m.angular_velocity.x == r.angular_velocity.x
        assert m.linear_acceleration.z == r.linear_acceleration.z
    # (messages still in flight to the probe: a few)
    assert node.counts['imu'] - len(got) <= node.pipeline.pre.delay_samples + 10
    assert len(got) < node.counts['imu']            # it really waits for its window
    ex.shutdown()


def _diag_values(msg):
    return {kv.key: kv.value for kv in msg.status[0].values}


@pytest.mark.slow
def test_end_to_end_simulator_and_alignment_node_against_truth(ros_context, domain_id):
    """Issue 3 must-show 4: static navigation grade, accelerated, phases in order, truth.

    Both nodes run as their own processes, started as ``ros2 run`` does; this test only
    observes the topics.
    """
    from sins_align_ros.eval.limits import scenario_limits
    from sins_align_ros.nav.frames import attitude_error, quat_to_dcm
    from sins_align_ros.sim.presets import scenario
    from sins_align_ros.units import ARCMIN
    obs = rclpy.create_node('observer', context=ros_context)
    out, truth, diag = [], [], []
    obs.create_subscription(Imu, 'imu/data', out.append,
                            QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE))
    qos = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
    obs.create_subscription(Odometry, 'sim/truth', truth.append, qos)
    obs.create_subscription(DiagnosticArray, '/diagnostics', diag.append, qos)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(obs)
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    align = subprocess.Popen([resolve_executable('alignment_node'), '--ros-args',
                              '-p', 'diagnostic_period:=0.25', '-p', 'coarse_duration:=30.0',
                              '-p', 'imu_frame_id:=imu_link'],
                             env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    sim = None
    try:
        assert spin_until(ex, lambda: diag, timeout_s=30.0)     # the node is up
        sim = subprocess.Popen([resolve_executable('simulator_node'), '--ros-args',
                                '-p', 'scenario:=static_navigation', '-p', 'duration:=100.0',
                                '-p', 'real_time_factor:=5.0', '-p', 'seed:=4',
                                '-p', 'start_time:=2000.0', '-p', 'shutdown_when_done:=true'],
                               env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               text=True)
        assert spin_until(ex, lambda: sim.poll() is not None, timeout_s=120.0)
        end = 2100 * 10 ** 9              # the last output and the truth at its stamp
        # the simulator waited for our acknowledgements before exiting: nothing is lost
        assert spin_until(ex, lambda: out and stamp_to_ns(out[-1].header.stamp) == end and truth
                          and stamp_to_ns(truth[-1].header.stamp) >= end, timeout_s=5.0)
        spin_until(ex, lambda: False, timeout_s=0.6)             # one more diagnostics
    finally:
        stop_processes([sim, align])
    assert sim.returncode == 0, sim.stderr.read()
    assert align.returncode == 0, align.stderr.read()
    # (a diagnostics message of a stopped input says 'fine' for 'aligned': the simulator's
    # pauses at 5x and its end)
    phases = [_diag_values(m).get('phase') for m in diag
              if 'no IMU data' not in m.status[0].message]
    seen = [p for i, p in enumerate(phases) if i == 0 or p != phases[i - 1]]
    # the window ends at 20 s and the stage, run over it, may hand over aligned (issue 46).
    # (100 s at 5x: at 10x, 1000 messages a second, a CI run whose other core was busy saw
    # the phase leave aligned, as a still base does when lost samples look like motion)
    why = [(_diag_values(m).get('elapsed_s'), _diag_values(m).get('not_aligned_reason'))
           for m in diag if _diag_values(m).get('phase') == 'fine']
    assert seen in (['waiting', 'coarse', 'fine', 'aligned'], ['waiting', 'coarse', 'fine'],
                    ['waiting', 'coarse', 'aligned']), (seen, why[:3])
    last = out[-1]
    assert stamp_to_ns(last.header.stamp) == 2100 * 10 ** 9
    tq = {stamp_to_ns(m.header.stamp): m.pose.pose.orientation for m in truth}[
        stamp_to_ns(last.header.stamp)]
    q = last.orientation
    err = attitude_error(quat_to_dcm([q.x, q.y, q.z, q.w]), quat_to_dcm([tq.x, tq.y, tq.z, tq.w]))
    band = scenario_limits(scenario('static_navigation'), 70.0).tolerance()
    assert np.all(np.abs(err) <= band), (err / ARCMIN, band / ARCMIN)
    cov = np.array(last.orientation_covariance).reshape(3, 3)
    assert np.all(np.abs(err) <= 3 * np.sqrt(np.diag(cov)))
    vals = _diag_values(diag[-1])
    assert vals['position_source'] == 'gnss'
    assert int(vals['imu_rejected_count']) == 0 and int(vals.get('imu_gap', 0)) == 0
    # no sample lost once the stream reached the node (discovery may take the first seconds)
    assert int(vals['imu_accepted']) == round(float(vals['elapsed_s']) * 100), vals
    # the forecast (issue 23): the same time to aligned from coarse alignment on, and the
    # outcome when it came (at rest it is exact to the model: align/forecast/expectation.py)
    fc = [(_diag_values(m)['phase'], _diag_values(m)['expected_aligned_at_s']) for m in diag]
    fc = [(ph, float(v)) for ph, v in fc if ph in ('coarse', 'fine')]
    assert fc and max(v for _, v in fc) - min(v for _, v in fc) <= 3.0, fc
    aligned = [float(_diag_values(m)['elapsed_s']) for m in diag
               if _diag_values(m)['phase'] == 'aligned']
    if aligned:
        assert abs(aligned[0] - fc[-1][1]) <= 3.0, (aligned[0], fc[-1])
    else:
        assert fc[-1][1] > float(vals['elapsed_s']) - 1.0, (fc[-1], vals['elapsed_s'])
    ex.shutdown()


def test_alignment_node_follows_sim_time(ros_context):
    """use_sim_time: diagnostics are stamped with the simulator's /clock.

    The simulator is paced (3x, /clock on) rather than as fast as possible: in one
    single-threaded executor an unpaced stream overflows the node's best-effort queue, and
    at 10x (1000 messages a second) a CI machine whose other core ran a heavy test received
    only 1269 of 3000.
    """
    node = AlignmentNode(context=ros_context, parameter_overrides=[
        Parameter('use_sim_time', value=True), Parameter('diagnostic_period', value=0.2)])
    sim = SimulatorNode(context=ros_context, parameter_overrides=[
        Parameter('duration', value=15.0), Parameter('real_time_factor', value=3.0),
        Parameter('publish_clock', value=True), Parameter('start_time', value=777.0)])
    obs = rclpy.create_node('diag_observer', context=ros_context)
    diag = []
    obs.create_subscription(DiagnosticArray, '/diagnostics', diag.append,
                            QoSProfile(depth=500, reliability=ReliabilityPolicy.RELIABLE))
    ex = SingleThreadedExecutor(context=ros_context)
    for n in (node, sim, obs):
        ex.add_node(n)
    assert spin_until(ex, lambda: sim.done, timeout_s=60.0)
    spin_until(ex, lambda: False, timeout_s=0.5)
    stamped = [stamp_to_ns(m.header.stamp) for m in diag]
    assert stamped and all(777 * 10 ** 9 <= s <= 792 * 10 ** 9 for s in stamped)
    assert node.counts['imu'] > 1000
    ex.shutdown()


def test_reset_service_restarts_alignment(ros_context):
    from std_srvs.srv import Trigger
    node = AlignmentNode(context=ros_context)
    client_node = rclpy.create_node('client', context=ros_context)
    cli = client_node.create_client(Trigger, 'alignment_node/reset')
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    ex.add_node(client_node)
    assert spin_until(ex, lambda: cli.service_is_ready(), timeout_s=10.0)
    node.pipeline.process([0.01, 0.02], np.zeros((2, 3)), [[0.0, 0.0, 0.098]] * 2)
    assert node.pipeline.phase == 'coarse'
    fut = cli.call_async(Trigger.Request())
    assert spin_until(ex, fut.done, timeout_s=10.0)
    assert fut.result().success
    assert node.pipeline.phase == 'waiting'
    ex.shutdown()


@pytest.mark.parametrize('path', sorted((ROOT / 'config').glob('*.yaml')), ids=lambda p: p.name)
def test_config_files_load_into_the_nodes(path, domain_id):
    """Every YAML in config/ is loaded by the node it names, through --params-file."""
    data = yaml.safe_load(path.read_text())
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain_id,
               args=['--ros-args', '--params-file', str(path)])
    try:
        for node_name, body in data.items():
            cls = {'alignment_node': AlignmentNode, 'simulator_node': SimulatorNode}[node_name]
            node = cls(context=ctx)
            for name, value in body['ros__parameters'].items():
                got = node.get_parameter(name).value
                assert (list(got) if isinstance(value, list) else got) == value
            node.destroy_node()
    finally:
        ctx.try_shutdown()


@pytest.mark.parametrize('exe', ['alignment_node', 'simulator_node'])
def test_executables_start_and_exit_cleanly_on_sigint(exe, ros_context, domain_id):
    """`ros2 run sins_align_ros EXE` then Ctrl-C: exit code 0, no traceback."""
    probe = rclpy.create_node('probe', context=ros_context)
    with running([resolve_executable(exe)], domain_id) as proc:
        end = time.monotonic() + 30.0
        while exe not in probe.get_node_names() and time.monotonic() < end:
            assert proc.poll() is None
            time.sleep(0.1)
        assert exe in probe.get_node_names()
    assert proc.returncode == 0, proc.err
    assert 'Traceback' not in proc.err and 'Traceback' not in proc.out


@pytest.mark.parametrize('exe', ['alignment_node', 'alignment_lifecycle_node'])
def test_out_of_range_start_parameter_exits_with_one_line(exe, domain_id):
    """A value outside its declared range: exit code 2 and the reason, no traceback."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    proc = subprocess.run([resolve_executable(exe), '--ros-args', '-p', 'coarse_duration:=0.1'],
                          env=env, capture_output=True, text=True, timeout=60.0)
    assert proc.returncode == 2, proc.stderr
    assert 'coarse_duration' in proc.stderr and 'Traceback' not in proc.stderr


def test_heading_in_gives_a_still_mems_imu_its_heading(ros_context):
    """heading/in (a GNSS compass bridged to sensor_msgs/Imu) with heading_offset_deg.

    The model's gyro (100 deg/h) cannot see Earth rate: without the compass the heading
    is published as unknown. The compass's baseline points 90 deg left of forward, so it
    reports the vehicle's yaw + 90 deg; one message without an orientation is refused.
    """
    from test_lifecycle import RPY, still_imu
    from sins_align_ros.nav.frames import euler_to_quat
    from sins_align_ros.ros.conversions import ns_to_stamp
    node = AlignmentNode(context=ros_context, parameter_overrides=[
        Parameter('coarse_duration', value=2.0), Parameter('fine_filter', value='stationary12'),
        Parameter('gyro_bias_dph', value=100.0), Parameter('initial_latitude_deg', value=34.0),
        Parameter('heading_offset_deg', value=90.0), Parameter('diagnostic_period', value=0.2),
        Parameter('imu_batch_period', value=0.0)])
    cl = rclpy.create_node('compass', context=ros_context)
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    pub_imu = cl.create_publisher(Imu, 'imu/data_raw', qos)
    pub_hd = cl.create_publisher(Imu, 'heading/in', qos)
    out, diag = [], []
    cl.create_subscription(Imu, 'imu/data', out.append, qos)
    cl.create_subscription(DiagnosticArray, '/diagnostics', diag.append, qos)
    ex = SingleThreadedExecutor(context=ros_context)
    for n in (node, cl):
        ex.add_node(n)
    assert spin_until(ex, lambda: pub_imu.get_subscription_count() and
                      pub_hd.get_subscription_count(), timeout_s=10.0)
    q = euler_to_quat([0.0, 0.0, RPY[2] + 90.0 * DEG])
    for i in range(600):                                   # 6 s at 100 Hz
        if i % 100 == 0:
            h = Imu()
            h.header.stamp = ns_to_stamp(100 * 10 ** 9 + i * 10_000_000)
            h.orientation.x, h.orientation.y, h.orientation.z, h.orientation.w = q
            h.orientation_covariance[8] = (0.2 * DEG) ** 2
            if i == 300:
                h.orientation_covariance[0] = -1.0         # no orientation: refused
            pub_hd.publish(h)
            ex.spin_once(timeout_sec=0.0)
        pub_imu.publish(still_imu(i))
        ex.spin_once(timeout_sec=0.0)
    assert spin_until(ex, lambda: len(out) >= 590, timeout_s=20.0)
    last = out[-1]
    yaw = quat_to_euler([last.orientation.x, last.orientation.y, last.orientation.z,
                         last.orientation.w])[2]
    assert abs(yaw - RPY[2]) < 0.05 * DEG
    assert 0.0 < last.orientation_covariance[8] < (0.3 * DEG) ** 2
    assert node.pipeline.coarse_info['coarse_heading_source'] == 'external'
    assert spin_until(ex, lambda: diag and _diag_values(diag[-1]).get(
        'gnss_input_no_orientation') == '1', timeout_s=5.0)
    assert _diag_values(diag[-1])['gnss_input_accepted_heading'] == '5'
    ex.shutdown()

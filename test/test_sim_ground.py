"""Simulator for ground vehicles (issue 44 item 5): axis misalignment and per-run scale
factors, the raw MEMS AHRS grade, vibration, a receiver without velocity, and the robot and
car scenarios' kinematics."""
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import run_simulator
from sins_align_ros.io.sim_messages import TOPICS, SimulatedMessages, topics
from sins_align_ros.sim.gnss import GnssErrors, GnssSpec
from sins_align_ros.sim.imu import ImuErrors, ImuSpec
from sins_align_ros.sim.presets import SENSOR_GRADES, scenario
from sins_align_ros.sim.scenario import ScenarioStream
from sins_align_ros.units import DEG, DPH, DPSH, UG

M_PPM = np.array([[0.0, 3000.0, -2000.0],
                  [5000.0, 0.0, 1000.0],
                  [-4000.0, 2500.0, 0.0]])


def _errors(spec, seed=3):
    return ImuErrors(spec, np.random.default_rng(seed))


def test_misalignment_leaks_a_rate_on_one_axis_into_the_others_in_closed_form():
    """measured = (I + S + M) true: a rate about x alone reads M[1,0] w on y and M[2,0] w on
    z, (1 + S[0]) w on x; a specific force on z alone reads through column 2."""
    spec = ImuSpec(gyro_scale_ppm=[20000.0, -15000.0, 10000.0], gyro_misalign_ppm=M_PPM,
                   accel_scale_ppm=4000.0, accel_misalign_ppm=5000.0)
    e = _errors(spec)
    dt, w, f = 0.01, 30.0 * DEG, 9.8
    n = 100
    dth = np.tile([w * dt, 0.0, 0.0], (n, 1))
    dv = np.tile([0.0, 0.0, f * dt], (n, 1))
    gy, ac = e.apply(dth, dv, dt)
    want_g = np.array([1.02, 5000e-6, -4000e-6]) * w
    assert np.allclose(gy / dt, want_g, rtol=0.0, atol=1e-15)
    want_a = np.array([5000e-6, 5000e-6, 1.004]) * f     # scalar: all off-diagonal entries
    assert np.allclose(ac / dt, want_a, rtol=0.0, atol=1e-13)
    # the matrix given has its diagonal ignored: the scale factors alone are there
    assert np.array_equal(np.diag(e.gyro_sm), [0.02, -0.015, 0.01])
    assert e.gyro_sm[0, 1] == pytest.approx(3000e-6, rel=1e-15)


def test_misalignment_under_white_noise_mean_converges_to_the_closed_form():
    """With the gyros' ARW on, the mean of 200 s of y samples is M[1,0] w within 4 sigma of
    the white noise's mean (ARW / sqrt(T)); the leak is 75 sigma above zero."""
    spec = ImuSpec(gyro_arw_dpsh=0.42, gyro_misalign_ppm=M_PPM)
    dt, n, w = 0.01, 20000, 30.0 * DEG
    gy, _ = _errors(spec, seed=11).apply(np.tile([w * dt, 0.0, 0.0], (n, 1)),
                                         np.zeros((n, 3)), dt)
    mean = gy.mean(axis=0) / dt
    sig = 0.42 * DPSH / np.sqrt(n * dt)                       # rad/s, the mean's sigma
    assert abs(mean[1] - 5000e-6 * w) < 4 * sig
    assert abs(mean[2] + 4000e-6 * w) < 4 * sig
    assert 5000e-6 * w > 70 * sig


def test_turn_on_scale_factors_and_misalignment_are_drawn_per_run():
    """random_bias: N(0, value^2) per axis (scale) and per off-diagonal entry
    (misalignment), seeded; a spec without them draws exactly what it drew before."""
    spec = ImuSpec(gyro_scale_ppm=20000.0, gyro_misalign_ppm=5000.0, accel_scale_ppm=4000.0,
                   random_bias=True)
    a, b, c = _errors(spec, 5), _errors(spec, 5), _errors(spec, 6)
    assert np.array_equal(a.gyro_sm, b.gyro_sm) and not np.array_equal(a.gyro_sm, c.gyro_sm)
    draws = [_errors(spec, s) for s in range(2000)]
    g = np.array([d.gyro_sm for d in draws])
    acc = np.array([d.accel_sm for d in draws])
    off = ~np.eye(3, dtype=bool)
    # 6000 draws: the sample sigma is good to about 1 %
    assert np.diagonal(g, axis1=1, axis2=2).std() == pytest.approx(0.02, rel=0.04)
    assert g[:, off].std() == pytest.approx(0.005, rel=0.04)
    assert np.diagonal(acc, axis1=1, axis2=2).std() == pytest.approx(0.004, rel=0.04)
    assert np.all(acc[:, off] == 0.0)                         # none given, none drawn
    # the streams of specs without scale factor or misalignment are unchanged
    plain = ImuSpec(gyro_bias_dph=1.0, accel_bias_ug=100.0, random_bias=True)
    rng = np.random.default_rng(8)
    e = ImuErrors(plain, rng)
    ref = np.random.default_rng(8)
    assert np.array_equal(e.gyro_bias, DPH * ref.standard_normal(3))
    ref.standard_normal(9)                # the accelerometer bias, the Markov states
    assert rng.standard_normal() == ref.standard_normal()     # nothing else was drawn


def test_mems_ahrs_grade_has_the_raw_triads_errors():
    """The grade's values (presets docstring: issue 44's sizes, MTi-1 series noise), and the
    sizes its runs draw: RMS over 500 runs within 10 % of the sigmas."""
    s = SENSOR_GRADES['mems_ahrs']
    assert s.random_bias
    assert (s.gyro_bias_dph, s.gyro_arw_dpsh, s.gyro_markov_dph, s.gyro_markov_tau_s) == (
        400.0, 0.42, 10.0, 300.0)
    assert (s.gyro_scale_ppm, s.gyro_misalign_ppm) == (20000.0, 5000.0)
    assert (s.accel_bias_ug, s.accel_vrw_ug_rthz, s.accel_scale_ppm,
            s.accel_misalign_ppm) == (7000.0, 120.0, 4000.0, 5000.0)
    assert 0.3 <= s.gyro_arw_dpsh <= 0.5                      # 0.007 deg/s/rt-Hz
    runs = [_errors(s, k) for k in range(500)]
    rms = lambda x: float(np.sqrt(np.mean(np.square(x))))    # noqa: E731
    assert rms([r.gyro_bias for r in runs]) == pytest.approx(400.0 * DPH, rel=0.1)
    assert rms([r.accel_bias for r in runs]) == pytest.approx(7000.0 * UG, rel=0.1)
    assert rms([np.diag(r.gyro_sm) for r in runs]) == pytest.approx(0.02, rel=0.1)
    assert rms([np.diag(r.accel_sm) for r in runs]) == pytest.approx(0.004, rel=0.1)
    off = ~np.eye(3, dtype=bool)
    assert rms([r.gyro_sm[off] for r in runs]) == pytest.approx(0.005, rel=0.1)
    assert rms([r.accel_sm[off] for r in runs]) == pytest.approx(0.005, rel=0.1)


def test_vibration_has_its_sample_rms_does_not_drift_and_stops_at_rest():
    """Sample RMS at the IMU rate within 3 % of the value given; the summed vibration stays
    bounded (its angle/velocity process sigma, not a random walk); none when still."""
    spec = ImuSpec(vibration_gyro_dps=3.0, vibration_accel_mps2=1.5, vibration_tau_s=0.05,
                   vibration_full_speed_mps=0.5)
    dt, n = 1.0 / 30.0, 36000                                  # 20 minutes at 30 Hz
    z = np.zeros((n, 3))
    e = _errors(spec, 2)
    gy, ac = e.apply(z, z, dt, speed=np.full(n, 1.0))
    assert np.sqrt(np.mean((gy / dt) ** 2)) == pytest.approx(3.0 * DEG, rel=0.03)
    assert np.sqrt(np.mean((ac / dt) ** 2)) == pytest.approx(1.5, rel=0.03)
    # the sums telescope: bounded by the process's sigma, 1.5 dt / sqrt(2 (1 - phi)) m/s
    sig_v = 1.5 * dt / np.sqrt(2.0 * (1.0 - np.exp(-dt / 0.05)))
    assert np.abs(np.cumsum(ac, axis=0)).max() < 6 * sig_v
    # a white specific force of the same sample RMS would wander 1.5 sqrt(dt n) = 52 m/s
    assert 6 * sig_v < 0.01 * 1.5 * np.sqrt(dt * n)
    gy, ac = _errors(spec, 2).apply(z[:300], z[:300], dt, speed=np.zeros(300))
    assert not gy.any() and not ac.any()


def test_receiver_without_velocity_gives_positions_only():
    """velocity=False: no velocity in the epochs, the same position errors as the receiver
    with velocity for the same seed; the reported sigma is the one set (optimistic)."""
    spec = GnssSpec(rate_hz=2.5, pos_sigma_h=0.8, pos_sigma_v=1.6, pos_markov_sigma=1.5,
                    pos_markov_tau_s=60.0, reported_pos_sigma_h=0.9, reported_pos_sigma_v=1.8)
    n = 200
    t = np.arange(1, n + 1) / 2.5
    pos = np.tile([0.8, 0.2, 500.0], (n, 1))
    with_v = GnssErrors(spec, np.random.default_rng(4)).measure(t, pos, np.ones((n, 3)))
    no_v = GnssErrors(spec.with_(velocity=False), np.random.default_rng(4)).measure(
        t, pos, np.ones((n, 3)))
    assert no_v.v_n is None and no_v.vel_cov is None
    assert with_v.v_n.shape == (n, 3)
    assert np.array_equal(no_v.pos_err_m, with_v.pos_err_m)
    assert np.array_equal(no_v.pos_cov, [0.81, 0.81, 1.8 ** 2])
    # unset, the reported sigma is the total of the white and Markov parts (as before)
    assert np.allclose(GnssSpec(pos_sigma_h=0.8, pos_markov_sigma=1.5).reported_pos_sigma[:2],
                       1.7)


def _plain_types(name):
    """Message 'classes' that keep their fields: the builder's contents without ROS."""
    return lambda **fields: SimpleNamespace(_type=name, **fields)


def test_position_only_scenario_has_no_vel_messages_and_reports_optimistic_covariance():
    """robot_skid through the simulator's message builder (node and recorder): no gnss/vel
    topic nor message; NavSatFix at 2.5 Hz reporting 0.9 m while the error is 1.7 m."""
    sc = scenario('robot_skid', duration=20.0)
    assert 'vel' not in topics(sc) and set(topics(sc)) == set(TOPICS) - {'vel'}
    assert set(topics(scenario('car_consumer'))) == set(TOPICS)
    msgs = SimulatedMessages(sc, _plain_types, seed=3)
    keys, fixes = [], []
    while True:
        items = msgs.next_block()
        if not items:
            break
        keys += [k for _, k, _ in items]
        fixes += [msgs.build(k, a) for _, k, a in items if k == 'fix']
    assert keys.count('vel') == 0
    assert keys.count('imu') == 600 and len(fixes) == 50      # 30 Hz, 2.5 Hz for 20 s
    assert all(f.position_covariance[0] == pytest.approx(0.81) for f in fixes)
    assert sc.gnss.pos_sigma[0] == pytest.approx(np.hypot(0.8, 1.5))


def test_recorded_position_only_bag_has_no_vel_topic(tmp_path):
    """sins_align_record's writer: the bag of robot_skid holds no gnss/vel connection."""
    pytest.importorskip('rosbags')
    from rosbags.rosbag2 import Reader

    from sins_align_ros.io.sim_messages import write_simulated_bag
    counts = write_simulated_bag(tmp_path / 'bag', scenario('robot_skid', duration=4.0),
                                 seed=1, start_ns=1_700_000_000 * 10 ** 9)
    assert counts == {'imu': 120, 'fix': 10, 'truth': 40}
    with Reader(tmp_path / 'bag') as r:
        assert sorted(c.topic for c in r.connections) == ['/gnss/fix', '/imu/data_raw',
                                                          '/sim/truth']


@pytest.mark.ros
def test_simulator_node_publishes_no_gnss_vel_for_a_position_only_receiver(ros_context):
    """Over DDS: robot_skid's node has no gnss/vel publisher and nothing arrives there;
    gnss/fix arrives at 2.5 Hz, the IMU at 30 Hz."""
    _, got, publishers = run_simulator(ros_context, scenario='robot_skid', duration=4.0)
    assert publishers == {'imu': 1, 'fix': 1, 'vel': 0, 'truth': 1}
    assert len(got['imu']) == 120 and len(got['fix']) == 10 and got['vel'] == []


def _kinematics(name, step=0.1):
    sc = scenario(name)
    t = np.arange(0.0, sc.duration, step)
    k = sc.trajectory.kinematics(t)
    speed = np.hypot(k.v_n[:, 0], k.v_n[:, 1])
    rate = np.gradient(np.unwrap(k.euler[:, 2]), t)
    return sc, t, speed, rate


def _turns(t, rate, threshold=5.0 * DEG):
    """(start time, heading change) of each span turning faster than ``threshold``."""
    on = np.abs(rate) > threshold
    edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
    dt = t[1] - t[0]
    return [(t[a], float(np.sum(rate[a:b]) * dt)) for a, b in zip(edges[::2], edges[1::2])]


def test_robot_skid_is_never_still_and_turns_often_by_random_amounts():
    """About 1 m/s from the first sample, 20+ turns of 20-180 deg, 30 Hz raw AHRS triads with
    vibration, GNSS positions only at 2.5 Hz."""
    sc, t, speed, rate = _kinematics('robot_skid')
    assert 300.0 <= sc.duration <= 700.0 and sc.imu_rate_hz == 30.0
    assert np.all(np.abs(speed - 1.0) < 1e-9)
    turns = _turns(t, rate)
    sizes = np.degrees(np.abs([a for _, a in turns]))
    assert len(turns) >= 20 and np.all(np.diff([s for s, _ in turns]) < 30.0)
    assert sizes.min() < 45.0 and sizes.max() > 150.0        # small and large, both ways
    assert {np.sign(a) for _, a in turns} == {-1.0, 1.0}
    assert sc.imu.gyro_scale_ppm == SENSOR_GRADES['mems_ahrs'].gyro_scale_ppm
    assert sc.imu.vibration_accel_mps2 > 0 and sc.gnss.velocity is False
    assert (sc.gnss.rate_hz, sc.gnss.pos_sigma_h, sc.gnss.pos_markov_sigma,
            sc.gnss.pos_markov_tau_s) == (2.5, 0.8, 1.5, 60.0)


@pytest.mark.parametrize('name', ['car_consumer', 'car_rtk'])
def test_cars_drive_in_town_with_turns_and_stops(name):
    """Junction turns, stops of 5-20 s, 8-14 m/s between; car_rtk still for its first 30 s,
    car_consumer under way from the start; the same route in every build."""
    sc, t, speed, rate = _kinematics(name)
    assert 300.0 <= sc.duration <= 700.0
    assert speed.max() < 15.0 and np.median(speed[speed > 1.0]) > 7.0
    big = [a for _, a in _turns(t, rate) if abs(a) > 50 * DEG]
    assert len(big) >= 4
    still = speed < 1e-6
    starts = np.flatnonzero(np.diff(still.astype(int)) == 1)   # the car comes to a stop
    assert len(starts) >= 3
    if name == 'car_rtk':
        assert np.all(still[t < 30.0]) and not still[t > 31.0][0]
        assert sc.gnss.pos_sigma_h == 0.02 and sc.imu is SENSOR_GRADES['mems']
        assert sc.gnss.pos_markov_sigma == 0.0
    else:
        assert speed[0] == pytest.approx(10.0)
        assert sc.imu is SENSOR_GRADES['mems_ahrs'] and sc.gnss.velocity
        assert (sc.gnss.rate_hz, sc.gnss.pos_sigma_h, sc.gnss.pos_markov_sigma) == (
            5.0, 1.0, 1.5)
        assert sc.gnss.reported_pos_sigma[0] == 1.0          # reports its white noise
    again = scenario(name).trajectory.kinematics(t[::50])
    assert np.array_equal(again.v_n, sc.trajectory.kinematics(t[::50]).v_n)


def test_car_rtk_still_start_reads_only_earth_rate_and_gravity():
    """The first 30 s of car_rtk: the simulated increments are those of a still MEMS IMU
    (mean rate within 4 sigma of the grade's bias and noise)."""
    sc = scenario('car_rtk')
    b = ScenarioStream(sc, seed=2).next_block(2900)
    w = b.imu.dtheta.mean(axis=0) / 0.01
    s = sc.imu
    bound = (np.hypot(s.gyro_bias_dph, s.gyro_markov_dph) * DPH * 4
             + 4 * s.gyro_arw_dpsh * DPSH / np.sqrt(29.0) + 7.3e-5)
    assert np.all(np.abs(w) < bound)
    assert np.allclose(b.imu.v_n, 0.0, atol=1e-12)

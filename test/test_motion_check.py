"""The self-check in motion: the sensor model against the fine stage's IMU windows (issue 44, 3).

A robot that waits still through the coarse window shows its chassis's vibration and its
turns only once it drives: the running filter's model must then be widened (never
narrowed, but for a random walk the growing data bound tighter) and the finding said; a
ship's IMU, whose model is right, must not be touched.
"""
import math

import numpy as np
import pytest

from sins_align_ros.align.stages.gnss_noise_check import velocity_jitter
from sins_align_ros.align.stages.grade_check import (ACCEL_SCALE_BY_GYRO_NOISE,
                                                     ACCEL_VRW_BY_GYRO_NOISE,
                                                     SCALE_BY_GYRO_NOISE)
from sins_align_ros.align.stages.motion_check import TURN_RATE, WINDOW_S, MotionCheck
from sins_align_ros.align.stages.noise_estimates import NOISE_RATIO, difference_density
from sins_align_ros.align.engines.process_noise import ProcessNoise
from sins_align_ros.align.engines.rotation_error import COHERENCE_FACTOR
from sins_align_ros.eval.integrity import run_integrity
from sins_align_ros.eval.run import run_scenario
from sins_align_ros.models.stationary import NoiseSpec
from sins_align_ros.sim.imu import ImuErrors, ImuSpec
from sins_align_ros.sim.presets import scenario, starting_still
from sins_align_ros.units import DPSH, UG

DT = 0.01


class Engine(ProcessNoise):
    """The least of an aided engine the check uses: 13 noise densities, the slices, a recorder."""

    i_phi, i_v = slice(4, 7), slice(0, 2)
    own_Q = False
    velocity_jitter_var = 0.0

    def __init__(self, noise, vel_var=None):
        self.Qc = np.r_[[noise.accel_vrw ** 2] * 2, [0.0] * 2, [noise.gyro_arw ** 2] * 3,
                        [1e-12] * 3, [0.0] * 3]
        self._Qc0 = self.Qc.copy()
        self.rotation = self.force = None
        self.vel_var = vel_var

    def receiver_velocity_var(self):
        return self.vel_var

    def set_rotation_error(self, scale, misalignment):
        self.rotation = (scale, misalignment)

    def set_force_error(self, scale, misalignment):
        self.force = (scale, misalignment)


def _samples(n, arw, vrw, rate=0.0, seed=1):
    """``n`` samples at DT of white rate / specific-force noise of densities ``arw``, ``vrw``.

    Plus a constant rate ``rate`` (rad/s) about z (a turn); gravity along z.
    """
    rng = np.random.default_rng(seed)
    t = DT * np.arange(1, n + 1)
    w = rng.normal(0.0, arw / math.sqrt(DT), (n, 3)) + [0.0, 0.0, rate]
    f = rng.normal(0.0, vrw / math.sqrt(DT), (n, 3)) + [0.0, 0.0, 9.81]
    return t, w * DT, f * DT, np.full(n, DT)


MODEL = NoiseSpec(gyro_bias=0.0, gyro_arw=0.4 * DPSH, accel_bias=0.0, accel_vrw=120.0 * UG)


def test_vibration_widens_the_running_model_by_the_square_of_the_ratio():
    # 10x the configured gyro noise, 2.5x the accelerometer's (below its class's 350 ug cap)
    arw, vrw = 4.0 * DPSH, 300.0 * UG
    chk, eng = MotionCheck(MODEL), Engine(MODEL)
    n = int(WINDOW_S / DT)
    t, dth, dv, dt = _samples(n + 50, arw, vrw)
    chk.push(t, dth, dv, dt)
    # not a whole window up to this epoch: nothing judged (the samples after it wait)
    assert not chk.epoch(t[n - 10], eng) and chk.n_windows == 0
    assert chk.epoch(t[n], eng) and chk.n_windows == 1
    w, f = dth[:n + 1] / DT, dv[:n + 1] / DT
    est_g, est_a = difference_density(w, DT), difference_density(f, DT)
    # the estimates of white noise: relative sigma of a mean of 3N squared third differences
    # (lag correlations -0.75, 0.3, -0.05: variance factor 2 (1 + 2 * 0.655) / 3N) is 1.4 %
    # of the density at N = 2000; 7 % is 5 of them
    assert est_g == pytest.approx(arw, rel=0.07) and est_a == pytest.approx(vrw, rel=0.07)
    factor = (est_g / MODEL.gyro_arw) ** 2
    for q, q0 in ((eng.Qc, Engine(MODEL).Qc), (eng._Qc0, Engine(MODEL)._Qc0)):
        assert q[4:7] == pytest.approx(q0[4:7] * factor, rel=1e-12)
        assert q[0:2] == pytest.approx(q0[0:2] * (est_a / MODEL.accel_vrw) ** 2, rel=1e-12)
        assert np.array_equal(q[2:4], q0[2:4]) and np.array_equal(q[7:], q0[7:])
    assert set(chk.widened) == {'gyro_arw_dpsh', 'accel_vrw_ug_rthz'}
    assert chk.widened['gyro_arw_dpsh'] == pytest.approx(est_g / DPSH, rel=1e-12)
    assert len(chk.take_findings()) == 2 and chk.take_findings() == []
    assert eng.rotation is None                 # no turn in the window
    # the next window has the same noise: the widened model holds it, nothing more
    t2, dth2, dv2, dt2 = _samples(n, arw, vrw, seed=2)
    chk.push(t2 + t[-1], dth2, dv2, dt2)
    before = eng.Qc.copy()
    assert not chk.epoch(t2[-1] + t[-1], eng)
    assert np.array_equal(eng.Qc, before)


def test_noise_as_configured_or_less_never_narrows_and_the_accelerometer_is_capped():
    chk, eng = MotionCheck(MODEL), Engine(MODEL)
    n = int(WINDOW_S / DT) + 1
    t, dth, dv, dt = _samples(n, 0.2 * DPSH, 60.0 * UG)         # half the model's
    chk.push(t, dth, dv, dt)
    assert not chk.epoch(t[-1], eng) and chk.n_windows == 1
    assert np.array_equal(eng.Qc, Engine(MODEL).Qc) and chk.widened == {}
    # accelerometer vibration far above its class's white noise counts only up to it (a
    # gyro of the consumer MEMS class, below twice the model's: 350 ug/sqrt(Hz))
    chk = MotionCheck(MODEL)
    t, dth, dv, dt = _samples(n, 0.7 * DPSH, 5000.0 * UG)
    chk.push(t, dth, dv, dt)
    chk.epoch(t[-1], eng)
    cap = next(v for edge, v in ACCEL_VRW_BY_GYRO_NOISE
               if difference_density(dth / DT, DT) / DPSH <= edge)
    assert cap == 350.0 and set(chk.widened) == {'accel_vrw_ug_rthz'}
    assert chk.widened['accel_vrw_ug_rthz'] == pytest.approx(cap, rel=1e-12)


@pytest.mark.parametrize('gyro_dpsh, mems', [(0.4, True), (0.01, False)])
def test_turns_take_the_scale_factors_of_the_gyros_class(gyro_dpsh, mems):
    model = NoiseSpec(0.0, gyro_dpsh * DPSH, 0.0, 120.0 * UG)
    chk, eng = MotionCheck(model), Engine(model)
    n = int(WINDOW_S / DT) + 1
    t, dth, dv, dt = _samples(n, gyro_dpsh * DPSH, 120.0 * UG, rate=1.5 * TURN_RATE)
    chk.push(t, dth, dv, dt)
    chk.epoch(t[-1], eng)
    arw = difference_density(dth / DT, DT) / DPSH
    scale, mis = next(v for edge, v in SCALE_BY_GYRO_NOISE if arw <= edge)
    a_scale, a_mis = next(v for edge, v in ACCEL_SCALE_BY_GYRO_NOISE if arw <= edge)
    if mems:
        assert eng.rotation == (scale * 1e-6, mis * 1e-6) == (0.02, 0.005)
        assert chk.widened['gyro_misalignment_ppm'] == pytest.approx(5000.0)
        # the accelerometer triad of the same class (a MEMS AHRS's raw triads)
        assert eng.force == (a_scale * 1e-6, a_mis * 1e-6) and a_scale > 0.0
        assert chk.widened['accel_scale_factor_ppm'] == pytest.approx(a_scale)
    else:                                       # tactical class: none
        assert eng.rotation is None and scale == 0.0
        assert eng.force is None and a_scale == 0.0
    # a tactical gyro whose window is noisy from vibration keeps its class's (none)
    model = NoiseSpec(0.0, 0.05 * DPSH, 0.0, 120.0 * UG)
    chk, eng = MotionCheck(model), Engine(model)
    t, dth, dv, dt = _samples(n, 2.0 * DPSH, 120.0 * UG, rate=1.5 * TURN_RATE)
    chk.push(t, dth, dv, dt)
    assert chk.epoch(t[-1], eng) and 'gyro_arw_dpsh' in chk.widened
    assert eng.rotation is None
    # without a turn, a MEMS gyro keeps the model's (none here)
    chk, eng = MotionCheck(NoiseSpec(0.0, 0.4 * DPSH, 0.0, 120.0 * UG)), Engine(model)
    t, dth, dv, dt = _samples(n, 0.4 * DPSH, 120.0 * UG, rate=0.5 * TURN_RATE)
    chk.push(t, dth, dv, dt)
    chk.epoch(t[-1], eng)
    assert eng.rotation is None


def test_a_robot_that_waited_still_widens_its_noise_once_it_drives():
    """robot_skid still for 60 s (no vibration at rest), then driving with its chassis's
    vibration; an external heading at 1 Hz lets the GNSS-aided kf start at rest. The filter
    is told the triads' noise but no scale factors."""
    sc = starting_still(scenario('robot_skid', duration=140.0), 60.0, accel=0.5)
    run = run_scenario(sc, 2, 'kf', heading_sigma_deg=2.0, gyro_scale_factor_ppm=0.0,
                       gyro_misalignment_ppm=0.0)
    p = run.pipeline
    told = sc.imu.gyro_arw_dpsh
    # the coarse window at rest showed the configured noise: nothing widened there
    assert 'gyro_arw_dpsh' not in p.check.widened
    chk, eng = p.fine.motion_check, p.engine
    assert chk.n_windows >= 3
    # under way: the vibration (3 deg/s RMS per sample at 30 Hz) widened the gyro noise
    # beyond twice the model's, and the filter's process noise with it; the walk bound
    # over the windows narrows it back where it is lower (never below the configured
    # figure): with the stage run over the window (10 windows by 140 s, 7 without) the
    # widened 4.2 deg/sqrt(h) is under the walk's 8.0 and stays
    arw = chk.widened['gyro_arw_dpsh']
    assert arw > NOISE_RATIO * told
    walk = chk.figures['motion_check_gyro_walk_dpsh']
    narrowed = chk.figures.get('motion_check_gyro_walk_narrowed_dpsh')
    assert narrowed == arw if narrowed is not None else walk >= arw
    assert eng.Qc[eng.i_phi] == pytest.approx((arw * DPSH) ** 2, rel=1e-9)
    # the turns: the scale factors of a MEMS triad
    # (the model takes COHERENCE_FACTOR times the class's sigmas: rotation_error.py)
    assert eng._rot_sigma == (COHERENCE_FACTOR * 0.02, COHERENCE_FACTOR * 0.005)
    texts = [text for lvl, text in p.conditions() if lvl == 1]
    assert any('gyro_arw_dpsh widened in the running filter' in x for x in texts)
    assert any('gyro_scale_factor_ppm' in x for x in texts)
    st = p.status()
    assert 'gyro_arw_dpsh=' in st['motion_check_widened']
    assert not run_integrity(run, 30)['silent']


def test_a_ship_underway_keeps_its_model():
    run = run_scenario(scenario('ship_underway', duration=200.0), 5, 'kf')
    chk = run.pipeline.fine.motion_check
    assert chk.n_windows >= 5 and chk.widened == {}
    assert run.pipeline.status()['motion_check_gyro_noise_dpsh'] < NOISE_RATIO * (
        scenario('ship_underway').imu.gyro_arw_dpsh)


def test_a_vibrating_chassis_raises_the_velocity_jitter_against_rtk_only():
    """The robot's vibration (1.5 m/s^2 per sample at 30 Hz, 0.05 s: 0.051 m/s of bounded
    velocity) in a window: raised to the window's jitter against an RTK receiver's 0.02 m/s
    velocity noise (said), not against a consumer receiver's 0.1 nor without velocity rows;
    never narrowed (a second window leaves it)."""
    n = int(WINDOW_S * 30.0) + 30
    errors = ImuErrors(ImuSpec(vibration_accel_mps2=1.5, vibration_tau_s=0.05),
                       np.random.default_rng(3))
    dt = 1.0 / 30.0
    dth, dv = errors.apply(np.zeros((n, 3)), np.tile([0.0, 0.0, 9.8 * dt], (n, 1)), dt)
    t = dt * np.arange(1, n + 1)
    j = velocity_jitter(dth, dv, np.full(n, dt))
    for vel_var, raised in ((0.02 ** 2, True), (0.1 ** 2, False), (None, False)):
        chk, eng = MotionCheck(MODEL), Engine(MODEL, vel_var)
        chk.push(t, dth, dv, np.full(n, dt))
        chk.epoch(t[-1], eng)
        assert (eng.velocity_jitter_var > 0.0) == raised
        if raised:
            # the window is the samples up to the epoch: all of them here
            assert eng.velocity_jitter_var == pytest.approx(j * j, rel=1e-12)
            assert chk.widened['imu_velocity_jitter_mps'] == pytest.approx(j, rel=1e-12)
            assert any('imu_velocity_jitter_mps widened' in x for x in chk.findings)
            chk.push(t + t[-1], dth, dv, np.full(n, dt))
            chk.epoch(2.0 * t[-1], eng)
            assert eng.velocity_jitter_var == pytest.approx(j * j, rel=1e-12)


def _vibrating_windows(n_windows, seed=4):
    """``n_windows`` motion windows of the simulator's robot gyro (0.42 deg/sqrt(h), 3 deg/s
    vibration per sample at 30 Hz correlated over 0.05 s), still: ``(t, dtheta, dv, dt)``."""
    dt = 1.0 / 30.0
    n = int(round(n_windows * WINDOW_S / dt)) + 1
    spec = ImuSpec(gyro_arw_dpsh=0.42, vibration_gyro_dps=3.0, vibration_tau_s=0.05)
    dth, dv = ImuErrors(spec, np.random.default_rng(seed)).apply(
        np.zeros((n, 3)), np.tile([0.0, 0.0, 9.81 * dt], (n, 1)), dt)
    return dt * np.arange(1, n + 1), dth, dv, np.full(n, dt)


@pytest.mark.parametrize('configured_dpsh', [0.42, 13.0])
def test_a_random_walk_widened_beyond_its_bound_is_narrowed_to_it(configured_dpsh):
    """The coarse window (or a first window) left the robot's gyro walk at 13 deg/sqrt(h);
    400 s of vibration bound it well under that (angle_walk: 3.5-4 at 400 s, never under
    the truth, 0.42). The check narrows the model and the engine's attitude process noise to
    the bound, but never below the configured figure (13: kept as it is)."""
    widened = NoiseSpec(0.0, 13.0 * DPSH, 0.0, 1000.0 * UG)
    chk = MotionCheck(widened, configured_arw=configured_dpsh * DPSH)
    eng = Engine(widened)
    t, dth, dv, dt = _vibrating_windows(20)
    chk.push(t, dth, dv, dt)
    for k in range(1, 21):
        chk.epoch(k * WINDOW_S + 0.5 * dt[0], eng)
    assert chk.n_windows == 20
    q = chk.noise.gyro_arw
    if configured_dpsh == 13.0:
        assert q == widened.gyro_arw and np.array_equal(eng.Qc, Engine(widened).Qc)
        assert 'motion_check_gyro_walk_narrowed_dpsh' not in chk.figures
        return
    assert 0.42 * DPSH < q < 13.0 * DPSH / 2.0
    assert chk.figures['motion_check_gyro_walk_narrowed_dpsh'] == pytest.approx(q / DPSH)
    for Q in (eng.Qc, eng._Qc0):
        assert Q[4:7] == pytest.approx([q * q] * 3, rel=1e-12)
    # narrowing is not a finding (nothing to warn of), and the other rows keep their noise
    assert not any('gyro_arw' in x for x in chk.findings)
    assert np.array_equal(eng.Qc[7:], Engine(widened).Qc[7:])

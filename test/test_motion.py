"""Whether GNSS shows the base moving, what ``fine_filter: auto`` runs (align/inputs/motion.py).

Windows built from closed forms: GNSS velocities of a known speed, IMU increments of a body
at rest, turning at a constant rate, or driving with a known velocity profile; the
judgements are checked against the thresholds of the module and the profile's truth.
"""
import math
import re

import numpy as np
import pytest

from sins_align_ros.align.inputs.gnss_buffer import GnssBuffer
from sins_align_ros.align.inputs.installation import Installation
from sins_align_ros.align.inputs.motion import (DRIVE_DV_MPS, DRIVE_TURN_RAD, NEEDS_GNSS,
                                                TRACK_S, Motion, Onset,
                                                cannot_start, choose_filter, gnss_motion,
                                                imu_translation, judge, watch)
from sins_align_ros.align.params import defaults
from sins_align_ros.nav import earth

DT, T = 0.01, 60.0
G = 9.80665
LAT = math.radians(45.0)


def _cfg(**kw):
    cfg = defaults()
    cfg.update(kw)
    return cfg


def _gnss(v_en, t0=-3.0, t1=T + 3.0, vel_var=None):
    """GNSS velocity messages at 1 Hz over [t0, t1] of a constant ENU velocity."""
    g = GnssBuffer()
    for t in np.arange(t0, t1 + 0.5, 1.0):
        g.velocity_fix(t, [v_en[0], v_en[1], 0.0], vel_var)
    return g


def _window(w_b, f_b):
    """Window (t, dtheta, dv, dt) of ``T`` s at ``DT`` of rates / forces ``w_b(t)``, ``f_b(t)``."""
    t = DT * np.arange(1, int(round(T / DT)) + 1)
    return t, w_b(t) * DT, f_b(t) * DT, np.full(len(t), DT)


def _still():
    w = np.array([0.0, earth.OMEGA_IE * math.cos(LAT), earth.OMEGA_IE * math.sin(LAT)])
    return _window(lambda t: np.tile(w, (len(t), 1)),
                   lambda t: np.tile([0.0, 0.0, G], (len(t), 1)))


def _turning(turn_rad):
    """A level body turning about its vertical axis by ``turn_rad`` over the window."""
    r = turn_rad / T
    return _window(lambda t: np.tile([0.0, 0.0, r], (len(t), 1)),
                   lambda t: np.tile([0.0, 0.0, G], (len(t), 1)))


def _driving(amp):
    """A level body whose forward velocity is ``amp sin(2 pi t / T)`` (m/s), no rotation."""
    w = 2.0 * math.pi / T
    return _window(lambda t: np.zeros((len(t), 3)),
                   lambda t: np.column_stack([amp * w * np.cos(w * t), 0 * t, G + 0 * t]))


def _quadratic_residual(amp):
    """Largest departure (m/s) of ``amp sin(2 pi t / T)`` from its least-squares quadratic."""
    t = DT * np.arange(1, int(round(T / DT)) + 1)
    v = amp * np.sin(2.0 * math.pi * t / T)
    return float(np.max(np.abs(v - np.polyval(np.polyfit(t, v, 2), t))))


# -- GNSS ----------------------------------------------------------------------------------
def test_gnss_speed_against_the_speed_threshold_and_the_lever_arm():
    cfg = _cfg()                  # motion_speed_mps 0.5 above 4 x gnss_vel_sigma_mps 0.1
    tt = np.array([0.0, T])
    assert gnss_motion(_gnss((0.3, 0.4)), cfg, tt) == (False, pytest.approx(0.5))
    moving, speed = gnss_motion(_gnss((0.36, 0.48)), cfg, tt)
    assert moving and speed == pytest.approx(0.6, rel=1e-12)
    # an antenna swaying at 0.2 m/s on its mast: the IMU moves at least 0.4 m/s
    moving, speed = gnss_motion(_gnss((0.36, 0.48)), cfg, tt, arm_speed=0.2)
    assert not moving and speed == pytest.approx(0.4, rel=1e-12)
    assert gnss_motion(_gnss((5.0, 0.0)), cfg, tt, arm_speed=9.0) == (False, 0.0)
    # no GNSS: nothing is judged
    assert gnss_motion(GnssBuffer(), cfg, tt) == (False, None)


def _fixes(speed, rate, t1, white=0.0, markov=0.0, tau=60.0, seed=0, t0=0.0):
    """Fixes of a base moving north-east at ``speed`` m/s from ``t0`` to ``t1`` at ``rate`` Hz.

    Position error: ``white`` m white plus ``markov`` m Gauss-Markov (``tau`` s) per axis,
    from generator ``seed``.
    """
    rng = np.random.default_rng(seed)
    g, dt = GnssBuffer(), 1.0 / rate
    a = math.exp(-dt / tau)
    m = np.zeros(2)
    R_M, R_N = earth.radii(LAT)
    for t in np.arange(t0, t1 + 1e-9, dt):
        m = a * m + markov * math.sqrt(1.0 - a * a) * rng.standard_normal(2)
        d = speed * (t - t0) / math.sqrt(2.0) + m + white * rng.standard_normal(2)
        g.position_fix(t, math.degrees(LAT + d[1] / R_M),
                       math.degrees(d[0] / (R_N * math.cos(LAT))), 0.0, None, None, False)
    return g


def test_the_track_of_the_fixes_gives_their_speed_and_the_slope_sigma():
    """Noise-free fixes: the slope is the speed; its sigma the least-squares slope's."""
    g = _fixes(1.0, 2.5, 60.0)
    v, sig, k = g.track_speed(60.0, 30.0, 1.5, 1e-9, 60.0)
    n = 75                          # fixes in (30, 60] at 2.5 Hz
    assert v == pytest.approx(1.0, rel=1e-5)    # small-area ENU offsets
    assert sig == pytest.approx(1.5 / math.sqrt(0.4 ** 2 * n * (n * n - 1) / 12.0), rel=1e-9)
    assert k == 4.0                 # no scatter: the configured noise
    assert g.track_speed(60.0, 90.0, 1.5, 0.0, 60.0) == (None, None, None)   # 60 s of 90


def test_a_robot_at_one_metre_per_second_behind_a_consumer_receiver_is_seen_moving():
    """1 m/s, positions only at 2.5 Hz, 1.5 m: the 3-s speed's 4 sigma is 2.8 m/s.

    The slope over 30 s has a 1-sigma of 0.02 m/s (white) and 0.04 m/s (a 1.5-m wander
    over 60 s): the threshold is motion_speed_mps, 0.5 m/s, 25 white sigmas below 1 m/s.
    """
    cfg = _cfg(gnss_pos_sigma_m=1.5)
    g = _fixes(1.0, 2.5, 60.0, white=1.5, seed=7)
    assert not gnss_motion(_fixes(1.0, 2.5, 60.0), cfg, np.array([57.0, 60.0]))[0]
    moving, speed = gnss_motion(g, cfg, np.array([57.0, 60.0]), track_s=(30.0,))
    assert moving and speed == pytest.approx(1.0, abs=0.2)
    assert watch(g, cfg, 60.0, False, False) is not None
    # the coarse window's judgement reads the track over the whole window
    m = judge(g, cfg, _still())
    assert m.gnss and m.moving


def test_a_still_base_whose_receiver_wanders_three_times_its_sigma_is_not_moving():
    """A 3-m wander over 60 s, told 1 m: the 30-s slope's sigma is 0.08 m/s per axis.

    The threshold 0.5 m/s is 6 of them: the track takes no epoch of an hour for motion
    that the 3-s speed does not (that one sees this first-order wander's fast steps).
    """
    cfg = _cfg(gnss_pos_sigma_m=1.0)
    g = _fixes(0.0, 1.0, 3600.0, white=0.5, markov=3.0, seed=3)
    added = [t for t in np.arange(30.0, 3600.0, 1.0)
             if gnss_motion(g, cfg, np.array([t - 3.0, t]), track_s=TRACK_S)[0]
             and not gnss_motion(g, cfg, np.array([t - 3.0, t]))[0]]
    assert added == []


def test_the_antennas_swing_is_taken_off_the_track():
    """A still base whose mast antenna (20 m arm) drifts 15 m north over a 30-s span.

    The track's slope is 0.5 m/s above motion_speed_mps; twice the arm over the span
    (1.33 m/s) is taken off: not moving. Without the arm it is motion.
    """
    cfg = _cfg(gnss_pos_sigma_m=0.1)
    g = GnssBuffer()
    R_M = earth.radii(LAT)[0]
    for t in np.arange(1.0, 31.5, 1.0):
        g.position_fix(t, math.degrees(LAT + 0.52 * t / R_M), 0.0, 0.0, None, None, False)
    tt = np.array([28.0, 31.0])
    assert g.track_speed(31.0, 30.0, 0.1, 0.0, 60.0)[0] == pytest.approx(0.52, rel=1e-4)
    assert gnss_motion(g, cfg, tt, track_s=(30.0,), arm_m=20.0)[0] is False
    assert gnss_motion(g, cfg, tt, track_s=(30.0,), arm_m=0.0)[0] is True


def test_a_receiver_noisier_than_configured_is_judged_by_its_scatter():
    """seed 003's 10-m fixes at 1 Hz told the default 1 m, a still car: over 10 s the
    slope's noise is 3 m/s, not 0.3; the scatter about the line sets it, with the bound
    of an estimated noise (16 degrees of freedom: 5.2 sigma). Over an hour of 10-s
    windows, no motion; a car at 15 m/s is still seen."""
    cfg = _cfg(gnss_pos_sigma_m=1.0)
    g = _fixes(0.0, 1.0, 3600.0, white=10.0, seed=5)
    k = g.track_speed(10.0, 10.0, 1.0, 0.0, 60.0)[2]
    assert k == pytest.approx(math.sqrt(16 * (math.exp(1.0) - 1.0)), rel=1e-12)
    moving = [t for t in np.arange(10.0, 3600.0, 10.0)
              if gnss_motion(g, cfg, np.array([t - 10.0, t]), track_s=(10.0,))[0]
              and not gnss_motion(g, cfg, np.array([t - 10.0, t]))[0]]
    assert len(moving) <= 1          # 359 windows at a tail of e^-8 (3e-4) each
    fast = _fixes(15.0, 1.0, 20.0, white=10.0, seed=5)
    assert gnss_motion(fast, cfg, np.array([10.0, 20.0]), track_s=(10.0,))[0]


def test_noisy_gnss_velocity_raises_the_threshold_to_four_sigma():
    tt = np.array([0.0, T])
    g = _gnss((0.7, 0.0))
    assert gnss_motion(g, _cfg(gnss_vel_sigma_mps=0.1), tt)[0]
    assert not gnss_motion(g, _cfg(gnss_vel_sigma_mps=0.2), tt)[0]       # 4 sigma = 0.8
    # a filter that takes R from the messages judges with their sigma: 0.3 m/s -> 1.2
    g = _gnss((1.0, 0.0), vel_var=[0.09, 0.09])
    assert gnss_motion(g, _cfg(fine_filter='ckf'), tt)[0] is False
    assert gnss_motion(g, _cfg(fine_filter='ckf', use_reported_gnss_covariance=False), tt)[0]


def test_auto_runs_the_moving_filter_only_on_a_moving_base():
    cfg = _cfg(auto_still_filter='stationary12', auto_moving_filter='vbckf')
    assert choose_filter(cfg, False) == 'stationary12'
    assert choose_filter(cfg, True) == 'vbckf'
    cfg['fine_filter'] = 'stationary10'       # a filter chosen by name is kept either way
    assert choose_filter(cfg, True) == choose_filter(cfg, False) == 'stationary10'


def test_watch_restarts_a_stationary_filter_and_an_aided_one_without_heading():
    cfg = _cfg(fine_filter='reduced7')
    g = _gnss((2.0, 0.0))
    why = watch(g, cfg, T, aided=False, heading_known=True)
    assert 'moving at 2.0 m/s' in why and 'reduced7 no longer holds' in why
    assert 'heading becomes observable' in watch(g, cfg, T, aided=True, heading_known=False)
    assert watch(g, cfg, T, aided=True, heading_known=True) is None
    assert watch(_gnss((0.1, 0.0)), cfg, T, aided=False, heading_known=True) is None
    assert watch(GnssBuffer(), cfg, T, aided=False, heading_known=True) is None


# -- the IMU -------------------------------------------------------------------------------
def test_the_imu_at_rest_or_at_constant_acceleration_shows_no_drive():
    assert imu_translation(_still()) is None
    # a constant force is quadratic in the velocity integral: a tilt, not a drive
    accel = _window(lambda t: np.zeros((len(t), 3)),
                    lambda t: np.tile([0.5, 0.0, G], (len(t), 1)))
    assert imu_translation(accel) is None
    short = tuple(a[:9] for a in _driving(10.0))
    assert imu_translation(short) is None             # fewer than 10 samples: not judged


@pytest.mark.parametrize('amp', [1.0, 2.0])
def test_a_drive_is_told_by_its_departure_from_a_quadratic(amp):
    want = _quadratic_residual(amp)
    msg = imu_translation(_driving(amp))
    if want < DRIVE_DV_MPS:
        assert msg is None
        return
    got = float(re.fullmatch(r'changes its velocity by ([0-9.]+) m/s', msg).group(1))
    # printed to 0.1 m/s; the rectangle sum of the samples differs from the sine by
    # at most amp * w * DT = 0.002 m/s
    assert abs(got - want) <= 0.05 + amp * 2 * math.pi / T * DT


def test_a_turn_is_told_beyond_thirty_degrees():
    assert imu_translation(_turning(DRIVE_TURN_RAD - math.radians(1.0))) is None
    msg = imu_translation(_turning(math.radians(75.0)))
    assert msg == 'turns by 75 deg'


# -- the coarse window's judgement ---------------------------------------------------------
def test_judge_and_cannot_start():
    cfg = _cfg()
    drive = _driving(3.0)
    m = judge(_gnss((3.0, 0.0)), cfg, drive)
    assert m.gnss and m.moving and m.drive is None and m.speed == pytest.approx(3.0)
    m = judge(_gnss((0.1, 0.0)), cfg, drive)      # a crawl below motion_speed_mps, driving
    assert not m.gnss and m.moving and m.drive.startswith('changes its velocity')
    assert 'stationary filter reduced7 cannot align it' in cannot_start('reduced7', False, m)
    assert cannot_start('kf', True, m) is None
    m = judge(GnssBuffer(), cfg, drive)           # no GNSS, the IMU drives
    assert not m.moving and m.speed is None
    assert cannot_start('kf', True, m) == NEEDS_GNSS.format(what=m.drive)
    m = judge(GnssBuffer(), cfg, _still())
    assert m == Motion(False, None, None) and cannot_start('reduced7', False, m) is None
    m = judge(_gnss((3.0, 0.0)), cfg, _still())
    assert 'moving at 3.0 m/s' in cannot_start('stationary12', False, m)


def test_judge_takes_the_lever_arms_speed_off_the_gnss_speed():
    # a 2 m mast rolling at 0.3 rad/s: the antenna moves 0.6 m/s about the IMU
    roll = _window(lambda t: np.tile([0.3, 0.0, 0.0], (len(t), 1)),
                   lambda t: np.tile([0.0, 0.0, G], (len(t), 1)))
    mast = Installation(lever_arm_m=(0.0, 0.0, 2.0))
    g = _gnss((0.9, 0.0))
    assert judge(g, _cfg(), roll).gnss
    m = judge(g, _cfg(), roll, mast)
    assert not m.gnss and m.speed == pytest.approx(0.3, rel=1e-9)


def _onset(speeds, cfg, t0=0.0, rate=5.0):
    """Feed GNSS velocities ``speeds`` (m/s east, at ``rate`` Hz from ``t0``) to an Onset."""
    g, on = GnssBuffer(), Onset()
    for k, v in enumerate(speeds):
        t = t0 + k / rate
        g.velocity_fix(t, [v, 0.0, 0.0], None)
        on.fix(g, cfg, t)
    return on


def test_the_onset_of_motion_after_rest_ends_the_coarse_window_coarse_motion_s_later():
    """Issue 46: 25 s at rest, then 3 m/s: the window that began at 0 ends 5 s after the
    first message showing the motion (the motion over its last second above 0.5 m/s)."""
    cfg = _cfg(coarse_motion_s=5.0)
    rest, rate = 25.0, 5.0
    on = _onset([0.0] * int(rest * rate) + [3.0] * 20, cfg)
    assert on.t == pytest.approx(rest)
    assert on.window_end(cfg, 0.0) == pytest.approx(rest + 5.0)
    # a window begun less than coarse_min_duration before the motion lasts that long
    # (the self-check reads as much as on a still base), not the whole coarse_duration
    t_first = rest - 2.0
    assert on.window_end(cfg, t_first) == pytest.approx(t_first + cfg['coarse_min_duration'])
    # a rest shorter than coarse_min_duration by less than coarse_motion_s: the onset's end
    assert on.window_end(cfg, rest - cfg['coarse_min_duration'] + 0.5) == pytest.approx(
        rest + 5.0)
    # one that begins with the motion (a base moving from the start) alike
    assert on.window_end(cfg, rest) == pytest.approx(rest + cfg['coarse_min_duration'])
    # off
    assert on.window_end(_cfg(coarse_motion_s=0.0), 0.0) is None


@pytest.mark.parametrize('name, fine_filter, window_s', [
    ('ship_underway', 'asckf', 20.0),       # marine grade, under way from the start
    ('seed001_flight', 'kf', 20.0),         # tactical grade, flying from the start
    ('car_consumer', 'auto', 60.0)])        # raw MEMS AHRS triads, driving from the start
def test_a_base_moving_from_the_start_ends_its_window_after_20_s_unless_mems(
        name, fine_filter, window_s):
    """Issue 46 (session 52): GNSS shows the base moving from its first fixes. A gyro that
    finds north ends the window after coarse_min_duration (20 s) and the aided filter,
    run over it, publishes 40 s sooner; a MEMS one keeps coarse_duration (60 s), where its
    self-check reads a minute of vibration and turns (CoarseWindow.refuse_short_end: the
    skid-steer robot's early rows were its silent-wrong ones)."""
    from sins_align_ros.eval.run import run_scenario
    run = run_scenario(name, 1000, fine_filter, duration=window_s + 5.0, cached=True)
    info = run.pipeline.coarse_info
    assert info['duration_s'] == pytest.approx(window_s, abs=0.05)
    assert info['reprocessed_s'] == pytest.approx(window_s, abs=0.05)
    first = np.flatnonzero(run.out.phase != 'coarse')[0]
    assert run.out.t[first] - run.data.imu.t[0] == pytest.approx(window_s, abs=0.05)


def test_a_stop_before_the_motion_lasted_forgets_it_one_after_keeps_it():
    """Decided by the messages in order (the replay's blocks and the node's samples alike):
    a motion that stops within coarse_motion_s was not the start; one that lasted is kept."""
    cfg = _cfg(coarse_motion_s=5.0)
    short = _onset([0.0] * 125 + [3.0] * 10 + [0.0] * 10, cfg)      # 2 s of motion
    assert short.t is None
    lasted = _onset([0.0] * 125 + [3.0] * 30 + [0.0] * 10, cfg)     # 6 s, then a stop
    assert lasted.t == pytest.approx(25.0)

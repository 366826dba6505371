"""GNSS history and the queue of epochs waiting for the IMU (align/inputs/gnss_buffer.py).

The buffer's rules (ahead of the IMU, queue full, before the filter's start, late), its
history window, the position it gives the fine filter, and the velocity it derives from the
fixes against the closed form of a least-squares slope.
"""
import math

import numpy as np
import pytest

from sins_align_ros.align.inputs.gnss_buffer import (KEEP_S, MAX_LAG_S, MAX_LEAD_S, MEDIAN_FIXES,
                                                     QUEUE, GnssBuffer)
from sins_align_ros.align.params import defaults
from sins_align_ros.nav import earth
from sins_align_ros.units import DEG
from tolerance import assert_roundoff

LAT, LON, H = 48.0, 11.0, 500.0


def _cfg(**kw):
    cfg = defaults()
    cfg.update(kw)
    return cfg


def test_a_fix_ahead_of_the_imu_clock_is_dropped_and_counted():
    g = GnssBuffer()
    g.position_fix(100.0 + MAX_LEAD_S + 0.01, LAT, LON, H, None, t_imu=100.0, queue=True)
    assert g.counts['ahead_of_imu'] == 1 and g.last_fix is None
    assert not g.fixes and not g.pending
    g.position_fix(100.0 + MAX_LEAD_S, LAT, LON, H, None, t_imu=100.0, queue=True)
    assert g.last_fix == (100.0 + MAX_LEAD_S, LAT, LON, H) and len(g.pending) == 1
    g.position_fix(1e6, LAT, LON, H, None, t_imu=None, queue=False)     # before any IMU
    assert g.last_fix[0] == 1e6 and len(g.pending) == 1 and g.counts['ahead_of_imu'] == 1


def test_the_history_keeps_the_last_hour_and_the_queue_its_last_hundred():
    g = GnssBuffer()
    n = QUEUE + 5
    for k in range(n):
        t = k * KEEP_S / 50.0           # 72 s apart: the first fixes leave the history
        g.position_fix(t, LAT, LON, H, [4.0, 9.0], None, queue=True)
        g.velocity_fix(t, [1.0, 0.0, 0.0], None)
    t_end = (n - 1) * KEEP_S / 50.0
    assert [f[0] for f in g.fixes] == [k * KEEP_S / 50.0 for k in range(n)
                                       if k * KEEP_S / 50.0 >= t_end - KEEP_S]
    assert len(g.vels) == len(g.fixes) == 51
    # the queue holds QUEUE; each epoch beyond it pushed out the oldest, counted
    assert len(g.pending) == QUEUE and g.counts['queue_full'] == n - QUEUE
    assert g.pending[0][0] == (n - QUEUE) * KEEP_S / 50.0
    assert len(g.recent_fixes) == MEDIAN_FIXES
    # a fix's record: radians, metres and the reported variances
    t, lat, lon, h, pv = g.fixes[-1]
    assert (lat, lon, h) == (LAT * DEG, LON * DEG, H) and list(pv) == [4.0, 9.0]
    # reset empties the queue and the counts; the history only unless kept
    g.reset(keep_history=True)
    assert not g.pending and g.counts['queue_full'] == 0 and len(g.fixes) == 51
    g.reset()
    assert not g.fixes and not g.vels and g.last_fix is not None      # the last fix stays


def test_queued_epochs_wait_for_the_imu_and_the_stale_ones_are_counted():
    g = GnssBuffer()
    for t in (1.0, 2.0, 3.0, 4.0, 5.0):
        g.position_fix(t, LAT, LON, H, None, None, queue=True)
    g.velocity_fix(3.0 + 0.015, [1.0, 2.0, 0.0], [0.01, 0.04])     # within 20 ms of 3.0
    g.velocity_fix(4.0 - 0.03, [9.0, 9.0, 0.0], None)             # 30 ms off 4.0
    assert not g.due(0.5) and g.due(1.0)
    stamps = np.arange(0.0, 6.0, 0.25)
    assert g.next_due_index(stamps, 0) == 4                        # the stamp 1.0
    assert g.next_due_index(stamps, 10) == 10                      # already due
    assert g.next_due_index(stamps[:4], 0) is None
    # IMU at 3.2 s, filter started at 1.5 s: 1.0 before the start, 2.0 late (> MAX_LAG_S)
    assert 3.2 - 2.0 > MAX_LAG_S
    fix = g.pop_due(3.2, 1.5)
    assert g.counts['before_start'] == 1 and g.counts['late'] == 1
    assert fix.t == 3.0 and (fix.lat, fix.lon, fix.h) == (LAT * DEG, LON * DEG, H)
    assert list(fix.v_n) == [1.0, 2.0, 0.0] and list(fix.vel_var) == [0.01, 0.04]
    assert g.counts['used'] == 0
    g.used(fix)
    assert g.counts['used'] == 1 and g.t_used == 3.0
    assert g.pop_due(3.2, 1.5) is None and len(g.pending) == 2     # 4.0, 5.0 wait
    fix = g.pop_due(4.5, 1.5)
    assert fix.t == 4.0 and fix.v_n is None and fix.vel_var is None
    assert g.velocity_at_stamp(7.0) == (None, None)


def test_the_fine_filters_position_median_last_fix_or_parameters():
    g = GnssBuffer()
    cfg = _cfg()
    # before any fix: the parameters; the latitude unset -> 0 and said so
    pos, src = g.position(cfg, aided=False)
    assert src == 'latitude_not_set' and pos[0] == 0.0 and not g.latitude_known(cfg)
    pos, src = g.position(_cfg(initial_latitude_deg=30.0, initial_height_m=7.0), False)
    assert src == 'parameters' and (pos[0], pos[2]) == (30.0 * DEG, 7.0)
    # a jump in the last fix moves an aided filter's position, not the stationary median
    for k in range(9):
        g.position_fix(k, LAT + 1e-6 * k, LON, H + k, None, None, queue=False)
    g.position_fix(9, LAT + 0.1, LON, H + 100.0, None, None, queue=False)
    pos, src = g.position(cfg, aided=False)
    assert src == 'gnss' and g.latitude_known(cfg)
    want = np.array([(LAT + 4.5e-6) * DEG, LON * DEG, H + 4.5])
    assert_roundoff(pos, want, 8, np.abs(want))          # a sum, a mean, a product each
    pos, _ = g.position(cfg, aided=True)
    want = np.array([(LAT + 0.1) * DEG, LON * DEG, H + 100.0])
    assert_roundoff(pos, want, 2, np.abs(want))
    pos, src = g.position(_cfg(use_gnss_position=False, initial_latitude_deg=30.0), True)
    assert src == 'parameters' and pos[0] == 30.0 * DEG
    # a new buffer inherits the position history
    g2 = GnssBuffer()
    g2.inherit(g)
    assert g2.position(cfg, aided=False)[0] == pytest.approx(g.position(cfg, False)[0])


def _track(v_en, dt_fix, t1=30.0, vel=False):
    """A buffer of fixes (and gnss/vel if ``vel``) of a constant ENU velocity from (LAT, LON)."""
    g = GnssBuffer()
    R_M, R_N = earth.radii(LAT * DEG)
    for t in np.arange(0.0, t1 + 1e-9, dt_fix):
        lat = LAT + v_en[1] * t / (R_M + H) / DEG
        lon = LON + v_en[0] * t / ((R_N + H) * math.cos(LAT * DEG)) / DEG
        g.position_fix(t, lat, lon, H, None, None, queue=False)
        if vel:
            g.velocity_fix(t, [v_en[0], v_en[1], 0.0], None)
    return g


@pytest.mark.parametrize('dt_fix', [1.0, 0.2])
def test_velocity_from_the_fixes_is_the_least_squares_slope(dt_fix):
    g = _track((3.0, -4.0), dt_fix)
    tt = np.linspace(5.0, 25.0, 41)
    V, sig, src = g.velocity_over(tt, 0.1, 2.0)
    assert src == 'gnss_positions'
    # the slope of a straight track is its velocity, up to the small-area approximation:
    # the offsets use the radii and cos(lat) of the window's first fix, not of the track's
    # start, a relative error below (tan L + d ln R / d lat ~ 0.01) times the latitude
    # travelled; round-off (1e-16 rad of position, ~1e-9 m) is far below that
    dlat = 4.0 * 30.0 / earth.radii(LAT * DEG)[0]
    tol = 5.0 * (math.tan(LAT * DEG) + 0.02) * dlat                # 1.2e-4 m/s
    assert np.allclose(V[:, :2], [3.0, -4.0], rtol=0, atol=tol) and np.all(V[:, 2] == 0)
    # the slope's sigma over 7 fixes dt apart: pos_sigma / sqrt(sum t^2) = 2 / (dt sqrt(28))
    assert sig == pytest.approx(2.0 / (dt_fix * math.sqrt(28.0)), rel=1e-12)
    speed, s = g.speed_over(tt, 0.1, 2.0)
    assert speed == pytest.approx(5.0, abs=tol) and s == sig


def test_velocity_messages_are_preferred_and_interpolated():
    g = _track((1.0, 0.0), 1.0, vel=True)
    g.velocity_fix(30.5, [3.0, 0.0, 0.0], None)
    tt = np.array([29.0, 30.25, 30.5])
    V, sig, src = g.velocity_over(tt, 0.1, 2.0)
    assert src == 'gnss_velocity' and sig == 0.1
    assert V[:, 0] == pytest.approx([1.0, 2.0, 3.0], rel=1e-12)
    # a dropped message (an outlier) is left out of the interpolation
    V, _, _ = g.velocity_over(tt, 0.1, 2.0, drop=(30.5,))
    assert V[:, 0] == pytest.approx([1.0, 1.0, 1.0])
    t_v, V_v = g.velocity_epochs(np.array([28.0, 30.5]))
    assert list(t_v) == [28.0, 29.0, 30.0, 30.5] and V_v.shape == (4, 3)
    assert list(g.velocity_stamps(np.array([28.0, 30.5]), drop=(30.5,))) == [28.0, 29.0, 30.0]
    # no messages, too few fixes: no velocity
    assert GnssBuffer().velocity_over(tt, 0.1, 2.0) == (None, None, 'none')
    assert GnssBuffer().speed_over(tt, 0.1, 2.0) == (None, None)


def test_the_sigmas_are_the_messages_for_filters_that_take_them():
    g = _track((1.0, 0.0), 1.0)
    for t in np.arange(0.0, 31.0):
        g.velocity_fix(t, [1.0, 0.0, 0.0], [0.04, 0.04])
    g.position_fix(31.0, LAT, LON, H, [9.0, 9.0], None, queue=False)
    tt = np.array([25.0, 30.0])
    # kf takes R from the messages: sqrt(0.04) and sqrt(9)
    assert g.sigmas_over(tt, _cfg(fine_filter='kf')) == (pytest.approx(0.2), pytest.approx(3.0))
    # vbckf estimates its own R: the parameters
    cfg = _cfg(fine_filter='vbckf')
    assert g.sigmas_over(tt, cfg) == (cfg['gnss_vel_sigma_mps'], cfg['gnss_pos_sigma_m'])
    pos, vel = g.reported_over(25.0, 31.0)
    assert len(pos) == 1 and len(vel) == 6

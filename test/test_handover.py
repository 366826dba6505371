"""The hand-over from a full coarse window to a fine stage or why not (align/stages/handover.py).

Simulated coarse windows (60 s, seeded) of a still IMU, a ship underway and a car that
drives off: which filter ``auto`` picks, the position the fine filter gets, the refusal
reasons, an external heading taken into the coarse attitude, and the fine stage's start
against the simulator's truth.
"""
import functools
import math
import re

import numpy as np
import pytest

from sins_align_ros.align.engines.factory import noise_spec
from sins_align_ros.align.inputs.gnss_buffer import MEDIAN_FIXES, GnssBuffer
from sins_align_ros.align.inputs.heading import COARSE_MAX_AGE_S, HeadingBuffer
from sins_align_ros.align.inputs.installation import Installation
from sins_align_ros.align.inputs.motion import NEEDS_GNSS
from sins_align_ros.align.output import ANGLE_UNKNOWN_VAR
from sins_align_ros.align.params import defaults
from sins_align_ros.align.stages.coarse_stage import CoarseResult
from sins_align_ros.align.stages.fine_stage import Clock
from sins_align_ros.align.stages.handover import FineStart, fine_stage_for, hand_over
from sins_align_ros.nav import earth
from sins_align_ros.nav.frames import attitude_error, dcm_to_euler, euler_to_dcm
from sins_align_ros.sim.presets import alignment_params, scenario
from sins_align_ros.sim.scenario import ScenarioStream
from sins_align_ros.units import DEG, DPH, DPSH
from tolerance import EPS, assert_roundoff

N = 6000          # the default coarse window: 60 s at 100 Hz


@functools.lru_cache(maxsize=None)
def _block(name):
    """The first 60 s of scenario ``name`` (seed 3): IMU, GNSS and truth."""
    sc = scenario(name)
    return sc, ScenarioStream(sc, seed=3).next_block(N)


def _hand_over(name, fine_filter='auto', gnss=True, heading=None, **params):
    """Run the hand-over on scenario ``name``'s window; returns (block, cfg, FineStart, why)."""
    sc, b = _block(name)
    cfg = defaults()
    cfg.update(alignment_params(sc, fine_filter))
    cfg.update(params)
    g = GnssBuffer()
    if gnss:
        G = b.gnss
        for k in range(len(G.t)):
            g.position_fix(G.t[k], G.lat[k] / DEG, G.lon[k] / DEG, G.h[k], G.pos_cov[:2],
                           None, queue=False)
            g.velocity_fix(G.t[k], G.v_n[k], G.vel_cov[:2])
    clock = Clock()
    clock.t_first, clock.t_last = 0.0, float(b.imu.t[-1])
    headings = HeadingBuffer()
    if heading is not None:
        headings.add(*heading, t_imu=clock.t_last, queue=False)
    window = (b.imu.t, b.imu.dtheta, b.imu.dv, np.diff(np.r_[0.0, b.imu.t]))
    given = dict(cfg)
    start, why = hand_over(window, cfg, noise_spec(cfg), clock, g, headings,
                           Installation.from_params(cfg))
    assert cfg == given                         # the configured parameters are not changed
    return b, cfg, start, why


def _within_3_sigma(b, start):
    """Assert the fine stage starts within 3 sigma of the truth at the window's end."""
    phi = attitude_error(start.fine.mech.C_b_n, euler_to_dcm(b.imu.euler[-1]))
    sig = np.sqrt(np.diag(start.fine.attitude_cov()))
    assert np.all(np.abs(phi) <= 3.0 * sig), (phi / sig)


def test_a_still_base_runs_the_still_filter_at_the_median_fix():
    b, cfg, start, why = _hand_over('static_tactical')
    assert why is None and isinstance(start, FineStart)
    assert start.cfg['fine_filter'] == cfg['auto_still_filter'] and not start.aided
    assert start.check is not None and not start.heading_measured
    assert start.fine.heading_known and start.coarse_info['method'] == 'analytic'
    # the stationary models' position: the median of the recent fixes
    G = b.gnss
    want = np.array([np.median(G.lat[-MEDIAN_FIXES:] / DEG) * DEG,
                     np.median(G.lon[-MEDIAN_FIXES:] / DEG) * DEG, np.median(G.h[-MEDIAN_FIXES:])])
    assert start.position_source == 'gnss'
    assert_roundoff(start.position, want, 8, np.abs(want))      # deg <-> rad, a median
    _within_3_sigma(b, start)


def test_gnss_showing_the_ship_move_makes_auto_aid_from_the_last_fix():
    b, cfg, start, why = _hand_over('ship_underway')
    assert why is None
    assert start.cfg['fine_filter'] == cfg['auto_moving_filter'] and start.aided
    assert start.coarse_info['heading_source'] == 'gnss_track'
    # an aided filter starts at the last fix (its gate judges the ones that follow)
    G = b.gnss
    assert list(start.position) == [G.lat[-1] / DEG * DEG, G.lon[-1] / DEG * DEG, G.h[-1]]
    _within_3_sigma(b, start)


def test_a_stationary_filter_refuses_a_base_gnss_shows_moving():
    sc, b = _block('seed003_car')
    _, _, start, why = _hand_over('seed003_car', 'stationary12')
    assert start is None
    m = re.fullmatch(r'GNSS shows the base moving at ([0-9.]+) m/s: the stationary filter '
                     r'stationary12 cannot align it \(use fine_filter auto or a GNSS-aided '
                     r'filter\)', why)
    # the window's largest GNSS speed: the truth's within 4 sigma of the receiver's
    # velocity noise and the 0.05 m/s of the print
    top = float(np.max(np.hypot(b.imu.v_n[:, 0], b.imu.v_n[:, 1])))
    assert abs(float(m.group(1)) - top) <= 4.0 * sc.gnss.vel_sigma + 0.05
    # auto takes the moving-base filter on the same window
    _, cfg, start, why = _hand_over('seed003_car')
    assert why is None and start.cfg['fine_filter'] == cfg['auto_moving_filter']


def test_a_drive_without_gnss_cannot_start():
    _, b = _block('seed003_car')
    _, _, start, why = _hand_over('seed003_car', gnss=False)
    assert start is None
    got = float(re.search(r'changes its velocity by ([0-9.]+) m/s', why).group(1))
    assert why == NEEDS_GNSS.format(what=f'changes its velocity by {got:.1f} m/s')
    # the truth's departure from its best quadratic: a constant accelerometer bias (no turn
    # in the window) is linear in the velocity and drops out; white noise leaves
    # ~vrw sqrt(T) = 0.01 m/s; the print 0.05
    v, t = b.imu.v_n, b.imu.t
    res = v - np.column_stack([np.polyval(np.polyfit(t, v[:, i], 2), t) for i in range(3)])
    assert abs(got - float(np.max(np.linalg.norm(res, axis=1)))) <= 0.1


def test_an_external_heading_replaces_the_coarse_one_carried_with_the_gyros():
    sc, b = _block('static_tactical')
    yaw_src, var, age = math.radians(61.0), math.radians(0.5) ** 2, 0.5
    t_fix = float(b.imu.t[-1]) - age
    _, _, start, why = _hand_over('static_tactical', heading=(t_fix, yaw_src, var))
    assert why is None and start.heading_measured
    assert start.coarse_info['coarse_heading_source'] == 'external'
    # carried to the window's end by the up gyro: at rest Earth's up rate, plus the bias
    # (3 sigma of the told instability and constant part) and the angle random walk
    cfg = alignment_params(sc, 'auto')
    turn = earth.OMEGA_IE * math.sin(b.imu.pos[-1, 0]) * age
    bias = math.hypot(cfg['gyro_bias_dph'], cfg['gyro_bias_instability_dph']) * DPH
    tol = 3.0 * bias * age + 4.0 * cfg['gyro_arw_dpsh'] * DPSH * math.sqrt(age)
    assert abs(dcm_to_euler(start.fine.mech.C_b_n)[2] - (yaw_src + turn)) <= tol
    # the published heading is never narrower than the source's
    assert start.fine.attitude_cov()[2, 2] >= var
    # a heading older than COARSE_MAX_AGE_S is not taken
    old = float(b.imu.t[-1]) - COARSE_MAX_AGE_S - 1.0
    _, _, start, _ = _hand_over('static_tactical', heading=(old, yaw_src, var))
    assert not start.heading_measured and 'coarse_heading_source' not in start.coarse_info


def test_without_a_latitude_the_gyros_estimate_it_or_the_heading_is_unknown():
    sc, b = _block('static_navigation')
    _, _, start, why = _hand_over('static_navigation', gnss=False,
                                  initial_latitude_deg=float('nan'))
    assert why is None and start.position_source == 'gyro_latitude'
    lat, sigma = start.check.latitude
    assert start.position[0] == lat
    assert abs(lat - b.imu.pos[-1, 0]) <= 3.0 * sigma
    assert start.fine.heading_known
    # a tactical gyro cannot: latitude 0, said so, heading published as unknown
    _, _, start, why = _hand_over('static_tactical', gnss=False,
                                  initial_latitude_deg=float('nan'))
    assert why is None and start.position_source == 'latitude_not_set'
    assert start.position[0] == 0.0 and not start.fine.heading_known
    assert start.fine.attitude_cov()[2, 2] == ANGLE_UNKNOWN_VAR
    assert any(w.startswith('latitude unknown') for w in start.warnings)


def test_the_self_check_off_leaves_the_model_as_configured():
    _, cfg, start, why = _hand_over('seed003_car', sensor_self_check=False)
    assert why is None and start.check is None
    # the coarse stage's own word on the gyro stays (a MEMS gyro cannot see Earth rate)
    assert [w[:9] for w in start.warnings] == ['gyro bias']
    assert start.noise == noise_spec(cfg)
    for k in ('gyro_scale_factor_ppm', 'accel_scale_factor_ppm'):
        assert start.cfg[k] == cfg[k]
    # with it, the MEMS triad's scale factors are raised (widened, never narrowed)
    _, cfg, start, _ = _hand_over('seed003_car')
    assert start.cfg['gyro_scale_factor_ppm'] > cfg['gyro_scale_factor_ppm']
    assert start.noise.gyro_arw >= noise_spec(cfg).gyro_arw
    assert any('gyro_scale_factor_ppm raised' in w for w in start.warnings)
    # and its finding on the heading replaces the coarse stage's warning
    assert not start.check.heading_observable
    assert not any(w.startswith('gyro bias') for w in start.warnings)


@pytest.mark.parametrize('known', [True, False])
def test_fine_stage_for_starts_from_the_coarse_result(known):
    cfg = defaults()
    cfg.update(alignment_params(scenario('static_tactical'), 'stationary12'))
    C = euler_to_dcm(np.array([0.01, -0.02, 1.0]))
    sigma = np.array([1e-3, 1e-3, 0.1])
    start = CoarseResult(C, sigma, np.array([34.0 * DEG, 1.0, 0.0]))
    clock = Clock()
    clock.t_first = clock.t_last = 60.0
    fine, warnings = fine_stage_for(start, cfg, noise_spec(cfg), False, known, False, clock,
                                    Installation(), HeadingBuffer())
    assert fine.phase == 'fine' and fine.heading_known == known and warnings == []
    assert np.array_equal(fine.mech.C_b_n, C)
    P = np.diag(fine.attitude_cov())
    # never narrower than the coarse sigma (to the round-off of a square and a square root)
    assert np.all(P[:2] >= sigma[:2] ** 2 * (1.0 - 8.0 * EPS))
    if known:
        assert_roundoff(P[2], sigma[2] ** 2, 4)
    else:
        assert P[2] == ANGLE_UNKNOWN_VAR

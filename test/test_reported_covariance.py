"""The receiver's reported covariance in the GNSS-aided filters (issue 44).

``use_reported_gnss_covariance`` (default on) makes the filters whose R the engine sets
(seed 000's ``ckf``, ``asckf`` without adaptation, and the 15/18-state ``kf`` and ``ukf``)
take each epoch's east/north position and velocity noise from the messages. The rows are
the engine's own (seed 000: E, N position then E, N velocity; the navigation filters:
E, N, U position then E, N, U velocity); the consistency monitor's factors and the
Gauss-Markov share still apply on top, so the monitor's widening holds. Against truth: an
RTK car told only the node defaults gets a narrower heading sigma that still covers the
error, and a receiver reporting a velocity sigma ten times too small is caught.
"""
import numpy as np
import pytest

from sins_align_ros.align.inputs.gnss_fix import GnssFix, uses_reported_covariance
from sins_align_ros.align.engines.gnss_markov import white_equivalent_var
from sins_align_ros.align.engines.moving import MovingBaseAlignment
from sins_align_ros.align.engines.navigation import model_noise
from sins_align_ros.align.engines.registry import engine_class
from sins_align_ros.align import params as prm
from sins_align_ros.eval.integrity import run_integrity
from sins_align_ros.eval.run import run_pipeline
from sins_align_ros.eval.scenarios import simulate
from sins_align_ros.sim.presets import alignment_params, scenario
from sins_align_ros.units import DEG, DPH, UG
from tolerance import assert_roundoff

LAT = 34.0 * DEG
DEFAULTS = prm.defaults()
#: reported east/north variances of the fixes below: position m^2, velocity (m/s)^2
POS_VAR, VEL_VAR = (4e-4, 9e-4), (1e-4, 2.5e-5)


def _nav(method, use_reported_cov=True):
    P0, Qc = model_noise(15 if method != 'ukf' else 18, [1e-3] * 3, 0.1, 1.0, (DPH, 0.0),
                         (100 * UG, 0.0), 0.0, 0.0, 100.0, 1000.0)
    R = np.diag([1.0, 1.0, 4.0, 0.01, 0.01, 0.04])
    return engine_class(method)(np.eye(3), np.zeros(3), LAT, 0.0, 0.0, P0, Qc, R,
                                use_reported_cov=use_reported_cov)


def _moving(use_velocity):
    P0 = np.diag(np.r_[[0.1 ** 2] * 2, [2.0 ** 2] * 2, [(0.5 * DEG) ** 2] * 2,
                       (5.0 * DEG) ** 2, [(1.0 * DPH) ** 2] * 3])
    R = np.diag([1.0, 1.0, 0.01, 0.01][:4 if use_velocity else 2])
    return MovingBaseAlignment(np.eye(3), np.zeros(3), LAT, 0.0, 0.0, P0, np.zeros(10), R,
                               use_velocity=use_velocity, square_root=False, fading=False,
                               adaptive=False, use_reported_cov=True)


def _fix(t):
    return GnssFix(t, LAT, 0.0, 0.0, np.zeros(3), pos_var=np.array(POS_VAR),
                   vel_var=np.array(VEL_VAR))


@pytest.mark.parametrize('make, want', [
    # the navigation filters: position E, N, U then velocity E, N, U (U rows keep R's)
    (lambda: _nav('kf'), [*POS_VAR, 4.0, *VEL_VAR, 0.04]),
    (lambda: _nav('ukf'), [*POS_VAR, 4.0, *VEL_VAR, 0.04]),
    # seed 000: E, N position then E, N velocity; position only without velocity
    (lambda: _moving(True), [*POS_VAR, *VEL_VAR]),
    (lambda: _moving(False), [*POS_VAR]),
])
def test_R_takes_the_reported_variances_in_the_rows_that_measure_them(make, want):
    """Each row of R gets the variance of the ENU axis it measures; the consistency
    monitor's factors multiply them and the Gauss-Markov share adds to the position rows,
    so a widening by the monitor is never undone by a small reported covariance."""
    eng = make()
    eng._set_epoch_noise(_fix(10.0))
    np.testing.assert_array_equal(np.diag(eng.kf.R), want)
    assert np.count_nonzero(eng.kf.R - np.diag(np.diag(eng.kf.R))) == 0
    # the monitor inflates the east position row 4x and the last row 16x (sqrt exact)
    last = len(want) - 1
    eng.inflate_noise({0: 4.0, last: 16.0})
    # (the white-equivalent form: kf and ukf take it while their heading is unknown, and
    # carry the error as states otherwise, test_gnss_markov_states.py)
    eng.set_gnss_markov(1.5, 60.0, 'measurement')
    eng._set_epoch_noise(_fix(10.0))               # the Gauss-Markov model's first fix
    eng._set_epoch_noise(_fix(10.2))
    scaled = np.array(want, dtype=float)
    scaled[0] *= 4.0
    scaled[last] *= 16.0
    pos_rows = [r for r in range(len(want)) if eng.MEAS_ENU[r] < 3]
    assert eng.gnss_markov.dt == pytest.approx(0.2)
    scaled[pos_rows] += white_equivalent_var(1.5, 60.0, eng.gnss_markov.dt)
    # a product by 2 x 2 (exact), then one addition: 2 operations on the variances' size
    assert_roundoff(np.diag(eng.kf.R), scaled, 2)
    assert np.all(np.diag(eng.kf.R) >= want)


@pytest.mark.parametrize('method', ['vbakf', 'mvbakf'])
def test_the_vb_filters_keep_their_own_R(method):
    """vbakf and mvbakf estimate R (their posterior): the reported variances are not put
    over it."""
    eng = _nav(method)
    R_before = eng.kf.R.copy()
    assert not eng.use_reported_cov
    eng._set_epoch_noise(_fix(10.0))
    np.testing.assert_array_equal(eng.kf.R, R_before)


@pytest.mark.parametrize('ff, adaptive, used', [
    ('kf', True, True), ('ukf', True, True), ('ckf', True, True), ('asckf', False, True),
    ('asckf', True, False), ('vbakf', True, False), ('mvbakf', True, False),
    ('vbckf', True, False), ('vbch', True, False), ('auto', True, False)])
def test_which_filters_take_the_reported_covariance(ff, adaptive, used):
    """``auto`` is resolved before the engine is built (handover); until then the coarse
    stage's motion judgement uses the configured sigmas."""
    cfg = {**DEFAULTS, 'fine_filter': ff, 'asckf_adaptive': adaptive}
    assert uses_reported_covariance(cfg) == used
    assert not uses_reported_covariance({**cfg, 'use_reported_gnss_covariance': False})


def _rtk_car(seed, vel_scale=1.0, ff='kf'):
    """200 s of the RTK car (MEMS IMU, 30 s still, then town), its reported velocity
    variance times ``vel_scale``, and the node defaults with its site."""
    sc = scenario('car_rtk', duration=200.0)
    data = simulate(sc, seed)
    data.gnss.vel_cov = np.asarray(data.gnss.vel_cov) * vel_scale
    right = alignment_params(sc, ff)
    site = {k: right[k] for k in ('initial_latitude_deg', 'initial_longitude_deg',
                                  'initial_height_m')}
    return data, {'fine_filter': ff, **site}


def _end(data, cfg):
    """Heading error and published 1-sigma at the end (rad), and the integrity figures."""
    run = run_pipeline(cfg, data)
    r = run_integrity(run, 100.0)
    return abs(r['end_err'][2]), r['end_sigma'][2], r, run.pipeline.warnings


@pytest.mark.parametrize('seed, ff', [(1, 'kf'), (4, 'ukf')])
def test_a_receiver_reporting_rtk_noise_narrows_the_heading_sigma_and_it_still_covers(seed, ff):
    """RTK fixes and velocities (0.02 m, 0.02 m/s, reported so) with node defaults (1 m,
    0.1 m/s): taken from the messages, the heading 1-sigma at the end is narrower than
    with the configured noise (it was 45' against 34' told right), the error lies inside
    3 sigma at the end, and the run is not silent-wrong (eval.integrity's rule: under 5 %
    of the 1-s rows beyond 3 sigma, none beyond 5). Seeds 1 (kf) and 4 (ukf) are runs whose
    coarse stage leaves out velocity messages at the window's end: the carried velocity
    claimed 0.04 m/s there and a forced GNSS acceptance turned the pitch 6 sigma (both
    silent-wrong before the carry's sigma, coarse_stage._end_velocity)."""
    data, cfg = _rtk_car(seed, ff=ff)
    err_cfg, sig_cfg, r_cfg, _ = _end(data, {**cfg, 'use_reported_gnss_covariance': False})
    err, sig, r, _ = _end(data, cfg)
    assert r['phase'] == r_cfg['phase'] == 'aligned'
    assert sig < sig_cfg
    assert err <= 3.0 * sig and err_cfg <= 3.0 * sig_cfg
    assert not r['silent'], r['why']
    assert not r_cfg['silent'], r_cfg['why']


def test_a_reported_velocity_sigma_ten_times_too_small_is_caught():
    """The same car reporting 0.002 m/s for velocities of 0.02 m/s: the self-check sees
    the noise in the coarse window's velocities, widens gnss_vel_sigma_mps and stops using
    the reported covariances (a WARN says so); the heading then covers its error and the
    run is not silent-wrong."""
    data, cfg = _rtk_car(1, vel_scale=0.01)
    err, sig, r, warnings = _end(data, cfg)
    assert any('reported covariances no longer used' in w for w in warnings)
    assert err <= 3.0 * sig
    assert not r['silent'], r['why']

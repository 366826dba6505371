"""The time and accuracy to expect (align/expectation.py) against closed forms and outcomes."""
import math

import numpy as np
import pytest

from sins_align_ros.align.convergence import ConvergenceMonitor
from sins_align_ros.align.expectation import first_aligned, riccati
from sins_align_ros.align.pipeline import AlignmentPipeline
from sins_align_ros.eval.run import run_scenario


def test_riccati_matches_its_closed_forms_and_a_numerical_solution():
    tau = np.arange(0.0, 6000.0, 0.5)
    P0, q, r = np.array([1e-2, 4e-4, 1e-5]), np.array([0.0, 1e-8, 1e-9]), \
        np.array([50.0, 0.0, 5e3])
    P = riccati(P0, q, r, tau)
    np.testing.assert_allclose(P[:, 0], P0[0] / (1 + r[0] * P0[0] * tau), rtol=1e-12)
    np.testing.assert_allclose(P[:, 1], P0[1] + q[1] * tau, rtol=1e-12)   # no information
    assert P[-1, 2] == pytest.approx(math.sqrt(q[2] / r[2]), rel=1e-6)     # steady state
    x = P0[2]                                    # Runge-Kutta on dP/dt = q - r P^2
    f = (lambda p: q[2] - r[2] * p * p)
    for k in range(1, 400):
        h = tau[k] - tau[k - 1]
        k1 = f(x)
        k2 = f(x + h / 2 * k1)
        k3 = f(x + h / 2 * k2)
        x += h / 6 * (k1 + 2 * k2 + 2 * k3 + f(x + h * k3))
    assert P[399, 2] == pytest.approx(x, rel=1e-6)


def test_first_aligned_applies_the_convergence_monitor_rule():
    t = np.arange(100.0, 700.0, 1.0)
    sig_u = np.radians(0.05) * np.sqrt(1.0 + 400.0 / (t - 90.0))    # a gyrocompass curve
    P = np.column_stack([np.full_like(t, 1e-8), np.full_like(t, 1e-8), sig_u ** 2])
    mon = ConvergenceMonitor(30.0)
    mon.start(100.0)
    expected = next(i for i, (tk, s) in enumerate(zip(t, sig_u)) if mon.converged(tk, s))
    i_al, i_tilt = first_aligned(t, P, 100.0, False, 30.0, math.radians(1.0), math.radians(2.0))
    assert i_al == expected and i_tilt == 0
    # a bound the heading never meets: no aligned
    assert first_aligned(t, P, 100.0, False, 30.0, 1.0, math.radians(0.01))[0] is None


def _forecasts(name, duration, every=10.0, **kw):
    log = []

    def take(p):
        if p.t_last is not None and (not log or p.t_last - log[-1][0] >= every):
            log.append((p.t_last, p.phase, p.expectation()))
    run = run_scenario(name, 1000, 'auto', duration=duration, callback=take, **kw)
    al = np.flatnonzero(run.out.phase == 'aligned')
    t_al = float(run.out.t[al[0]] - run.data.imu.t[0]) if len(al) else math.inf
    return log, run, t_al, (run.out.sigma[al[0]] if len(al) else run.out.sigma[-1])


def test_still_base_forecast_from_the_first_sample_matches_the_outcome():
    """Static navigation grade, defaults = the sensors: one forecast from t = 1 s on."""
    log, run, t_al, sig = _forecasts('static_navigation', 320.0)
    assert 250.0 < t_al < 270.0                       # the outcome it must forecast
    for t, phase, e in log:
        assert e.t_aligned == pytest.approx(t_al, abs=2.0), (t, phase)
        if phase != 'aligned':                  # once aligned: the current sigma
            np.testing.assert_allclose(e.sigma, sig, rtol=0.03)
    assert log[0][1] == 'coarse' and log[-1][1] == 'aligned'


def test_still_tactical_gyro_forecasts_never_with_the_heading_limit_and_a_ready_tilt():
    log, run, t_al, sig = _forecasts('static_tactical', 200.0, every=50.0)
    assert math.isinf(t_al)
    for t, _, e in log:
        assert math.isinf(e.t_aligned) and 'aligned_max_heading_sigma_deg' in e.note
        # right after coarse alignment (a forecast made later: ready by then)
        assert e.t_tilt == pytest.approx(60.0, abs=1.0) if t < 60.0 else e.t_tilt <= t + 1.0
        # the best heading within the forecast's hour, ~5 deg: a little below this run's end
        assert 0.95 * sig[2] < e.sigma[2] <= sig[2]
    assert run.pipeline.status()['expected_aligned_at_s'] == 'never'


def test_still_mems_heading_is_never_forecast_without_a_heading_and_is_with_a_compass():
    log, _, t_al, _ = _forecasts('static_mems', 150.0, every=40.0)
    assert math.isinf(t_al)
    assert all(math.isinf(e.t_aligned) and 'unobservable' in e.note for _, _, e in log)
    log, _, t_al, sig = _forecasts('static_mems', 150.0, every=20.0, heading_sigma_deg=0.2,
                                   auto_still_filter='stationary12')
    assert t_al < 120.0
    for t, _, e in log[1:]:                     # from the first compass epoch on
        assert e.t_aligned == pytest.approx(t_al, rel=0.05), t
        assert e.sigma[2] == pytest.approx(sig[2], rel=0.05)


def test_moving_base_forecast_waits_for_the_filter_then_follows_it():
    """ship_underway (kf): unknown until 8 s of fine alignment; the outcome once aligned.

    (``aligned`` at the 2 deg heading bound, 136 s: an aided filter need not stop
    converging first. The forecast at 106 s said 249 s, at 121 s 157 s: the heading
    information comes with the acceleration that starts at 60 s, which a trend of the
    last seconds cannot know in advance.)
    """
    log, run, t_al, sig = _forecasts('ship_underway', 360.0, every=5.0)
    assert 120.0 < t_al < 160.0
    assert sig[2] == pytest.approx(math.radians(2.0), rel=0.02)
    coarse = [e for t, ph, e in log if ph == 'coarse' and t > 15.0]
    assert coarse and all(math.isnan(e.t_aligned) and 'moving base' in e.note for e in coarse)
    fine = [(t, e) for t, ph, e in log if ph == 'fine' and t > 75.0]
    assert all(math.isfinite(e.t_aligned) for _, e in fine)
    late = [e for t, e in fine if t >= 60.0 + 3.0 * (t_al - 60.0) / 4][0]
    assert abs(late.t_aligned - t_al) <= 0.3 * t_al
    done = [e for _, ph, e in log if ph == 'aligned']
    assert done and done[0].t_aligned == pytest.approx(t_al, abs=0.02)


def test_waiting_pipeline_forecasts_from_the_configured_sensors_and_latitude():
    """Before any data: a still base at initial_latitude_deg; heading grows at least as 1/cos L."""
    p = AlignmentPipeline({'initial_latitude_deg': 34.0})
    e = p.expectation()
    assert p.phase == 'waiting' and math.isfinite(e.t_aligned)
    far = AlignmentPipeline({'initial_latitude_deg': 75.0}).expectation()
    ratio = math.cos(math.radians(34.0)) / math.cos(math.radians(75.0))
    assert far.sigma[2] >= ratio * e.sigma[2]
    st = p.status()
    assert float(st['expected_aligned_at_s']) == pytest.approx(e.t_aligned)
    assert st['expectation_basis'].startswith('still-base')

"""The evaluation harness (``sins_align_ros.eval``): runs against truth, pool, cache, statistics.

Seeded, short runs: the numbers are checked against the simulated truth and the
analytic limits, not only for shape.
"""
import io
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import shared_data
from sins_align_ros.eval import cache, monte_carlo, named, run_scenario
from sins_align_ros.eval.errors import navigation_rmse, nees
from sins_align_ros.eval.evidence import limits_of
from sins_align_ros.eval.recordings import read_fog, run_fog
from sins_align_ros.eval.run import run_pipeline, without_gnss
from sins_align_ros.eval.scenarios import simulate
from sins_align_ros.eval.stats import error_summary, mean_nees, rms
from sins_align_ros.nav.frames import attitude_error, euler_error, euler_to_dcm, quat_to_dcm
from sins_align_ros.units import ARCMIN, DEG

STILL = ('static_navigation', 240.0)


def _still_final(seed):
    """One seeded run of the still navigation-grade IMU (reduced7); its final error."""
    return run_scenario(STILL[0], seed, 'reduced7', duration=STILL[1]).final


@pytest.fixture(scope='module')
def still_run():
    """Seed 2 of the still scenario, in this process."""
    return run_scenario(STILL[0], 2, 'reduced7', duration=STILL[1])


@pytest.fixture(scope='module')
def still_pool():
    """Seeds 1-3 of the still scenario over two processes, and the progress text."""
    err = io.StringIO()
    return monte_carlo(_still_final, [1, 2, 3], procs=2, stream=err), err.getvalue()


def test_run_has_the_truth_of_every_row_and_its_final_error(still_run):
    run = still_run
    n = len(run.data.imu.t)
    assert len(run.out.t) == n == 24000
    assert np.array_equal(run.rows, np.arange(n))          # a row per IMU sample
    truth = run.data.imu.euler[-1]
    phi = attitude_error(quat_to_dcm(run.out.q[-1]), euler_to_dcm(truth))
    assert np.array_equal(run.final.phi, phi)
    assert np.array_equal(run.final.euler, euler_error(run.out.euler[-1], truth))
    assert run.final.nees == pytest.approx(nees(phi, run.out.P_phi[-1]))
    # the 60-s window ends at its first check, 20 s (coarse_window.good_enough)
    assert run.final.known and run.restarts == 0 and run.t_fine == pytest.approx(20.0)
    assert run.speed > 10.0 and run.span == pytest.approx(240.0 - 0.01)
    # the series is NaN during coarse alignment (no attitude), the final error at its end
    series = run.phi(np.array([0, 100, n - 1]))
    assert np.all(np.isnan(series[:2])) and np.array_equal(series[2], phi)


@pytest.mark.exclusive       # its fixture starts a Dask cluster of two worker processes
def test_still_base_monte_carlo_reaches_the_analytic_limit_on_any_number_of_processes(
        still_run, still_pool):
    par, progress = still_pool
    # in job order, and a worker process computes the same numbers as this one
    assert np.array_equal(par[1].phi, still_run.final.phi)
    assert par[1].nees == still_run.final.nees
    assert '3/3' in progress and progress.endswith('\n')
    assert monte_carlo(abs, [-1, 2, -3], procs=1, progress=False) == [1, 2, 3]
    expected = limits_of(named(*STILL), 'reduced7')[0]        # ENU, rad
    st = error_summary([f.euler for f in par], [f.sigma for f in par])
    assert np.all(st.inside == 1.0)                           # inside 3 reported sigma
    assert mean_nees([f.nees for f in par]) < 9.0
    phi = np.array([f.phi for f in par])
    # tilt: the accelerometer-bias limit (~0.47' east, 0.13' north); heading inside 3x its
    assert np.all(rms(phi)[:2] < expected[:2] + 0.05 * ARCMIN)
    assert np.all(rms(phi)[:2] > 0.5 * expected[:2])
    assert rms(phi)[2] < 3.0 * expected[2]
    assert np.all(st.sigma[2] < 3.0 * expected[2])


def test_navigation_rmse_of_the_car_against_its_truth():
    """Seed 003's car, 15-state KF: position well inside the 10 m receiver noise."""
    run = run_scenario('seed003_car', 1, 'kf', duration=150.0)
    r = navigation_rmse(run.out, run.data.imu, 60.0)
    assert run.out.nav is not None
    assert 0.5 < r['pos_h'] < 6.0 and r['pos_h'] <= r['pos'] < 6.0
    assert 0.01 < r['vel'] < 0.2
    assert np.all(r['att'][:2] < 1.0) and r['att'][2] < 10.0          # deg


def test_navigation_rmse_of_an_alignment_only_filter_uses_the_recorded_track(still_run):
    run = still_run
    assert run.out.nav is None
    imu = run.data.imu
    k = np.arange(99, len(imu.t), 100)
    track = np.column_stack([imu.t[k], imu.pos[k, 0], imu.pos[k, 1], imu.pos[k, 2] + 3.0])
    r = navigation_rmse(run.out, imu, 60.0, track)
    assert r['pos'] == pytest.approx(3.0, abs=1e-6) and r['pos_h'] < 1e-6
    assert np.isnan(r['vel'])
    e = euler_error(run.out.euler[6000::100], imu.euler[6000::100])
    assert np.allclose(r['att'], np.sqrt(np.mean(e ** 2, axis=0)) / DEG)


def test_simulation_cache_loads_the_same_run_and_keys_on_the_profile(tmp_path, monkeypatch):
    sc = named('seed000_case1', duration=20.0)
    first = cache.simulate_cached(sc, 4, directory=tmp_path)
    monkeypatch.setattr(cache, 'simulate', lambda *a: pytest.fail('simulated twice'))
    again = cache.simulate_cached(sc, 4, directory=tmp_path)
    for k in cache.IMU_FIELDS:
        assert np.array_equal(getattr(first.imu, k), getattr(again.imu, k))
    assert np.array_equal(first.gnss.lat, again.gnss.lat) and len(first.gnss.t) == 20
    monkeypatch.undo()
    other = named('seed000_case1', duration=20.0)
    other.extra['gnss_noise_profile'] = [(0.0, 10.0), (20.0, 10.0)]      # 10x GNSS noise
    assert cache.cache_key(other, 4) != cache.cache_key(sc, 4)
    assert cache.cache_key(named('seed000_case1', duration=20.0), 4) == cache.cache_key(sc, 4)
    noisy = cache.simulate_cached(other, 4, directory=tmp_path)
    assert np.array_equal(noisy.imu.dtheta, first.imu.dtheta)            # same IMU draws
    lat = simulate(sc, 4).gnss_truth_pos[:, 0]
    assert np.allclose(noisy.gnss.lat - lat, 10.0 * (first.gnss.lat - lat), rtol=1e-6,
                       atol=1e-12)                                        # same draws x 10
    still = cache.simulate_cached(named('seed002_1deg', duration=5.0), 1, directory=tmp_path)
    assert still.gnss is None and len(still.imu.t) == 500
    assert len(list(tmp_path.glob('*.pkl'))) == 3
    cache.clear(tmp_path)
    assert not tmp_path.exists()


def test_error_summary_and_nees_on_known_numbers():
    e = np.array([[1.0, -2.0, 0.0], [3.0, 2.0, 4.0]])
    s = np.array([[1.0, 1.0, 1.0], [0.5, 1.0, 2.0]])
    st = error_summary(e, s)
    assert st.n == 2
    assert np.allclose(st.mean, [2.0, 0.0, 2.0])
    assert np.allclose(st.rms, [np.sqrt(5.0), 2.0, np.sqrt(8.0)])
    assert np.allclose(st.sigma, [0.75, 1.0, 1.5])
    assert np.allclose(st.inside, [0.5, 1.0, 1.0])
    assert np.all(np.isnan(error_summary(np.zeros((0, 3)), np.zeros((0, 3))).rms))
    assert nees(np.array([1.0, 2.0, 0.0]), np.diag([1.0, 4.0, 9.0])) == pytest.approx(2.0)
    assert mean_nees([1.0, np.nan, 3.0]) == 2.0 and np.isnan(mean_nees([np.nan]))


def test_fog_recording_heading_against_the_fog_reference():
    rec = read_fog(shared_data('fog_mems_imu.csv').parent)
    run, e = run_fog(rec, 'ckf')
    assert run.out.phase[-1] in ('fine', 'aligned') and run.speed > 1.0
    assert abs(e['heading']) < 3.0 * e['sigma_yaw'] and abs(e['heading']) < 5.0    # deg
    assert abs(e['roll']) < 0.5 and abs(e['pitch']) < 0.5


def test_harness_imports_neither_ros_nor_pyins():
    code = ('import sys, sins_align_ros.eval as e\n'
            'from sins_align_ros.eval import (cache, errors, evidence, markdown, pool, '
            'pyins_sim, recordings, report, run, scenarios, stats)\n'
            "print(sorted(m for m in ('rclpy', 'pyins') if m in sys.modules))")
    r = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == '[]'


def test_run_pipeline_without_gnss_in_one_call():
    sc = named('seed002_1deg', duration=90.0)
    data = simulate(sc, 1)
    params = {'initial_latitude_deg': 34.0, 'initial_longitude_deg': 75.0,
              'initial_height_m': 100.0, 'fine_filter': 'reduced7'}
    one = run_pipeline(params, without_gnss(data), block=None)
    assert len(one.out.t) == 9000 and one.final.known
    assert np.all(np.abs(one.final.phi[:2]) < 1.0 * ARCMIN)
    with pytest.raises(ValueError):
        run_pipeline(params, SimpleNamespace(imu=data.imu, gnss=object()), block=None)

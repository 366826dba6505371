"""The external heading (heading/in): its measurement, its input checks, and runs against truth."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from sins_align_ros.align.inputs.heading import (HeadingBuffer, take_heading, yaw_of, yaw_row,
                                                 yaw_update)
from sins_align_ros.align.session import AlignmentSession
from sins_align_ros.eval.integrity import published_sigma
from sins_align_ros.eval.run import run_pipeline, run_scenario
from sins_align_ros.eval.scenarios import named, simulate
from sins_align_ros.models import large_misalignment as lm
from sins_align_ros.nav.frames import dcm_to_euler, euler_to_dcm, rotvec_to_dcm
from sins_align_ros.sim.gnss import heading_measurements
from sins_align_ros.sim.presets import alignment_params
from sins_align_ros.units import DEG
from tolerance import assert_roundoff


@pytest.mark.parametrize('correct', ['rotation_vector', 'large_misalignment'])
def test_yaw_row_is_the_derivative_of_the_yaw_for_either_feedback(correct):
    C = euler_to_dcm(np.radians([12.0, -25.0, 140.0]))        # pitched: the tilts count
    fb = {'rotation_vector': lambda p: rotvec_to_dcm(p) @ C,
          'large_misalignment': lambda p: lm.C_n_nprime(p).T @ C}[correct]
    h, d = yaw_row(C), 1e-6
    num = [(yaw_of(fb(d * e)) - yaw_of(fb(-d * e))) / (2 * d) for e in np.eye(3)]
    np.testing.assert_allclose(h, num, atol=1e-6)
    assert abs(h[0]) > 0.1 and abs(h[1]) > 0.1


def test_taking_a_heading_keeps_roll_and_pitch_and_clears_the_heading_row():
    C = euler_to_dcm(np.radians([3.0, -4.0, 100.0]))
    P = np.full((5, 5), 0.01) + np.eye(5)
    C2, P2 = take_heading(C, P, 2, math.radians(-170.0), 1e-4)
    # Euler -> DCM -> heading swapped -> Euler: ~50 operations, conditioned 1 / cos(pitch)
    assert_roundoff(dcm_to_euler(C2), np.radians([3.0, -4.0, -170.0]), 50, 1.0,
                    1.0 / math.cos(math.radians(4.0)))
    assert P2[2, 2] == 1e-4 and not np.any(P2[2, [0, 1, 3, 4]]) and P2[0, 1] == P[0, 1]


def test_yaw_update_pulls_the_heading_and_gates_an_outlier():
    C = euler_to_dcm([0.0, 0.0, 0.3])
    x, P = np.zeros(4), np.diag([1e-4, 1e-4, 1e-2, 1.0])
    x2, P2, y, S, ok = yaw_update(x, P, slice(0, 3), C, 0.31, 1e-4, max_nis=15.0)
    assert ok and y == pytest.approx(0.01) and S == pytest.approx(1e-2 + 1e-4)
    assert x2[2] == pytest.approx(0.01 * 1e-2 / (1e-2 + 1e-4))
    assert P2[2, 2] == pytest.approx(1e-2 * 1e-4 / (1e-2 + 1e-4))
    assert P2[3, 3] == pytest.approx(1.0)                       # uncorrelated: untouched
    *_, ok = yaw_update(x, P, slice(0, 3), C, 0.3 + math.radians(60.0), 1e-4, max_nis=15.0)
    assert not ok


def test_heading_input_checks_and_offset():
    s = AlignmentSession({'heading_offset_deg': 90.0, 'heading_sigma_deg': 0.5})
    s.heading(1.0, float('nan'), 1e-4)
    s.heading(2.0, 0.5, 1e-4, has_orientation=False)
    s.heading(3.0, math.radians(100.0), -1.0)                 # implausible: configured sigma
    s.heading(3.0, math.radians(100.0), 1e-4)                 # stamp repeated
    counts = s.gnss_input.counts
    assert counts['nan'] == 1 and counts['no_orientation'] == 1
    assert counts['covariance_implausible'] == 1 and counts['stamp_not_increasing'] == 1
    assert counts['accepted_heading'] == 1
    (fix,) = s.pipeline.headings.history
    assert fix.yaw == pytest.approx(math.radians(10.0))        # 100 deg source - 90 deg offset
    assert fix.var == pytest.approx(math.radians(0.5) ** 2)


def test_heading_buffer_drops_late_and_early_epochs():
    b = HeadingBuffer()
    for t in (1.0, 5.0, 9.5):
        b.add(t, 0.1, 1e-4, t_imu=0.0, queue=True)
    b.add(30.0, 0.1, 1e-4, t_imu=0.0, queue=True)              # 30 s ahead of the IMU
    assert b.pop_due(10.0, t_start=2.0).t == 9.5               # 1 s before start, 5 s late
    assert b.counts == {**b.counts, 'before_start': 1, 'late': 1, 'ahead_of_imu': 1}


def test_heading_buffer_requeues_a_reprocessed_span_before_the_later_epochs():
    b = HeadingBuffer()
    for t in (1.0, 2.0, 3.0, 4.0):
        b.add(t, 0.1 * t, 1e-4, t_imu=4.0, queue=True)
    b.drop_pending(3.0)                                        # coarse: 1-3 s are history
    b.add(5.0, 0.5, 1e-4, t_imu=4.0, queue=True)
    b.requeue(1.0, 3.0)                                        # a stage reprocesses (1, 3]
    assert [fix.t for fix in b.pending] == [2.0, 3.0, 4.0, 5.0]


def test_a_reprocessing_prior_claims_a_ninth_of_the_heading_that_set_it():
    """The compass message that set the coarse heading is taken again: its prior is 3x wider."""
    from sins_align_ros.align.stages.coarse_stage import CoarseResult
    from sins_align_ros.align.stages.reprocess import measured_heading_prior
    start = CoarseResult(C_b_n=np.eye(3), sigma=np.array([1e-3, 1e-3, 0.5]),
                         position=np.zeros(3))
    res = measured_heading_prior(start, 3.5e-3)
    assert res.sigma.tolist() == [1e-3, 1e-3, 3.0 * 3.5e-3]
    assert start.sigma[2] == 0.5                                 # the input is not changed


def _final(run):
    err = np.degrees(run.phi(np.array([len(run.out.t) - 1]))[0])
    return err, np.degrees(published_sigma(run.out.P_phi[-1]))


def _t_aligned(run):
    k = np.flatnonzero(run.out.phase == 'aligned')
    return float(run.out.t[k[0]]) if len(k) else math.inf


@pytest.mark.parametrize('fine_filter', ['auto', 'ckf'])
def test_mems_car_with_a_gnss_compass_reaches_the_compass_accuracy(fine_filter):
    """Seed 003's MEMS car: 0.2 deg heading at 1 Hz against the GNSS-aided filter alone."""
    without = run_scenario('seed003_car', 1000, fine_filter, duration=200.0, cached=True)
    run = run_scenario('seed003_car', 1000, fine_filter, duration=200.0, cached=True,
                       heading_sigma_deg=0.2)
    err, sig = _final(run)
    err0, sig0 = _final(without)
    assert abs(err[2]) < 0.3 and sig[2] < 0.2 and abs(err[2]) < 3.0 * sig[2]
    assert sig0[2] > 5.0 * sig[2]                              # the compass is what helps
    assert run.pipeline.headings.counts['used'] > 100
    assert run.out.phase[-1] == 'aligned' and _t_aligned(run) <= _t_aligned(without)


def test_a_compass_run_reprocesses_its_window_and_is_aligned_no_later():
    """Issue 46: with the aided reprocessing a compass no longer delays `aligned` (59 -> 37 s).

    The window's compass messages are queued again and taken as the stored samples pass
    them (every message used once); the coarse heading they set only linearises.
    """
    kw = dict(duration=200.0, cached=True, coarse_reprocess_aided=True)
    run = run_scenario('seed003_car', 1000, 'auto', heading_sigma_deg=0.2, **kw)
    plain = run_scenario('seed003_car', 1000, 'auto', heading_sigma_deg=0.2, duration=200.0,
                         cached=True, coarse_reprocess_aided=False)
    without = run_scenario('seed003_car', 1000, 'auto', **kw)
    assert run.pipeline.coarse_info['reprocessed_s'] > 20.0
    assert run.pipeline.headings.counts['used'] == 200         # one a second, 1-200 s
    assert _t_aligned(run) <= _t_aligned(without) < _t_aligned(plain)
    err, sig = _final(run)
    assert abs(err[2]) < 0.3 and abs(err[2]) < 3.0 * sig[2]
    rows = np.arange(np.argmax(run.out.phase == 'aligned'), len(run.out.t), 100)
    z = np.abs(run.phi(rows)[:, 2]) / published_sigma(run.out.P_phi[rows])[:, 2]
    assert (z < 3.0).mean() >= 0.95 and z.max() < 5.0


def test_an_outlying_heading_is_rejected_by_the_gate():
    sc = named('seed003_car', 160.0)
    data = simulate(sc, 1001)
    rng = np.random.default_rng(5)
    hd = heading_measurements(data.imu.t, data.imu.euler[:, 2], 0.2 * DEG, 1.0, rng)
    yaw = hd.yaw.copy()
    k = int(np.searchsorted(hd.t, 120.0))
    yaw[k] += math.radians(40.0)                               # a wrong compass epoch
    run = run_pipeline(alignment_params(sc, 'kf'), data,
                       heading=SimpleNamespace(t=hd.t, yaw=yaw, var=hd.var))
    err, sig = _final(run)
    assert run.pipeline.headings.counts['rejected'] == 1
    assert abs(err[2]) < 0.3 and abs(err[2]) < 3.0 * sig[2]


def test_a_still_mems_imu_takes_its_heading_from_the_compass():
    """At rest a MEMS gyro cannot find north: the compass's heading is what it publishes."""
    run = run_scenario('static_mems', 1000, 'stationary12', duration=150.0, cached=True,
                       heading_sigma_deg=0.2)
    without = run_scenario('static_mems', 1000, 'stationary12', duration=150.0, cached=True)
    err, sig = _final(run)
    assert abs(err[2]) < 0.5 and 0.05 < sig[2] < 0.3
    assert np.isnan(_final(without)[1][2])                     # heading declared unknown
    assert run.pipeline.coarse_info['coarse_heading_source'] == 'external'

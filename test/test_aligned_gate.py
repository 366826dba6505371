"""``aligned`` as soon as it is true, left only on a clear failure (issue 46, aligned_gate).

The pieces against closed-form cases (the settle test's sums, the hysteresis bounds, the
consistency monitor's run of failures), and the whole rule on the MEMS car with RTK that
stands still and then drives: at most one ``aligned`` -> ``fine`` switch per run over
10 seeds, every ``aligned`` row inside 3 sigma, and (with the coarse window ended by the
motion, ``inputs/motion.Onset``) ``aligned`` within 20 s of the start of motion.
"""
import math

import numpy as np
import pytest

from sins_align_ros.align.output import ANGLE_UNKNOWN_VAR
from sins_align_ros.align.stages.aligned_gate import (LEAVE_FACTOR, SETTLE_S, AlignedGate,
                                                      SettleTest, rotation_vector)
from sins_align_ros.align.stages.consistency import WINDOW, ConsistencyMonitor
from sins_align_ros.eval.errors import attitude_errors
from sins_align_ros.eval.run import run_scenario
from sins_align_ros.nav.frames import euler_to_dcm

DEG = math.radians(1.0)


def test_rotation_vector_is_the_small_rotation_between_two_attitudes():
    C0 = euler_to_dcm(np.array([0.1, -0.2, 1.0]))
    phi = np.array([1e-4, -2e-4, 3e-4])
    skew = np.array([[0, -phi[2], phi[1]], [phi[2], 0, -phi[0]], [-phi[1], phi[0], 0]])
    C1 = (np.eye(3) - skew) @ C0
    # second order in phi: 1e-8 rad against corrections of 1e-4
    np.testing.assert_allclose(rotation_vector(C0, C1), phi, atol=1e-7)


def test_a_steady_correction_is_settled_after_two_spans():
    """1 mrad at every 5-Hz update (a drift the engine compensates at its epochs, as seed
    000's does): each span moves 25 mrad, more than the 10-mrad sigma, but the same in
    both, so the estimate has settled, and not before two spans."""
    st = SettleTest(t0=100.0)
    sigma = np.full(3, 0.01)
    for k in range(60):
        st.add(100.2 + 0.2 * k, np.array([0.001, -0.001, 0.0]))
    assert not st.settled(100.0 + 2 * SETTLE_S - 0.2, sigma)     # too early
    assert st.settled(100.0 + 2 * SETTLE_S, sigma)
    np.testing.assert_allclose(np.abs(st.net(100.0 + 2 * SETTLE_S)), [0.025, 0.025, 0.0],
                               atol=1e-12)


def test_a_converging_correction_is_not_settled_until_it_has_died_down():
    """Corrections 10 mrad e^(-t/3 s) at 5 Hz: the span sums are 5 Hz x 30 mrad s x
    (e^(-a/3) - e^(-b/3)): (0, 5] 122 mrad, (5, 10] 23: they differ by 99 mrad, not
    settled at 10 s; (10, 15] 4.3, (15, 20] 0.8: 3.5 mrad apart, settled at 20 s."""
    st = SettleTest(t0=0.0)
    sigma = np.full(3, 0.01)
    for k in range(1, 101):
        t = 0.2 * k
        st.add(t, np.full(3, 0.01 * math.exp(-t / 3.0)))
        if t == pytest.approx(10.0):
            assert not st.settled(t, sigma)
    assert st.settled(20.0, sigma)


def test_settle_ignores_an_axis_published_as_unknown():
    st = SettleTest(t0=0.0)
    st.add(9.0, np.array([0.0, 0.0, 2.0]))
    assert st.settled(10.0, np.array([0.01, 0.01, math.sqrt(ANGLE_UNKNOWN_VAR)]))
    assert not st.settled(10.0, np.array([0.01, 0.01, 1.0]))


class _Monitor:
    def __init__(self, clear):
        self.clearly_inconsistent = clear
        self.ratio, self.bound, self.failed_in_row, self.remedy = 1.9, 1.66, 2, 'inflated'


def test_the_thresholds_enter_at_the_bound_and_leave_above_its_multiple():
    g = AlignedGate(1.0 * DEG, 2.0 * DEG)
    assert g.ready(1.0 * DEG, 2.0 * DEG) == (True, True)
    assert g.ready(1.01 * DEG, 2.01 * DEG) == (False, False)
    calm = _Monitor(False)
    assert g.leave_reason(LEAVE_FACTOR * DEG, LEAVE_FACTOR * 2 * DEG, calm) == ''
    why = g.leave_reason(1.0 * DEG, (LEAVE_FACTOR * 2 + 0.01) * DEG, calm)
    assert why.startswith('heading 1-sigma above 1.2 x 2 deg')
    assert 'tilt' in g.leave_reason((LEAVE_FACTOR + 0.01) * DEG, DEG, calm)
    assert 'innovations inconsistent' in g.leave_reason(DEG, DEG, _Monitor(True))


def _window(mon, ratio, dof=2):
    for _ in range(WINDOW):
        mon.add(ratio * dof, dof)


def test_one_failure_is_not_clear_a_second_in_a_row_is():
    mon = ConsistencyMonitor()
    _window(mon, 1.0)
    assert mon.consistent and not mon.clearly_inconsistent
    bound = mon.bound                       # chi2 0.999 quantile / dof, 20 dof: 2.27
    _window(mon, bound * 1.05)              # fails by 5 %
    assert not mon.consistent and mon.failed_in_row == 1 and not mon.clearly_inconsistent
    _window(mon, bound * 1.05)              # again, on the innovations after the remedy
    assert mon.failed_in_row == 2 and mon.clearly_inconsistent
    _window(mon, 1.0)
    assert mon.consistent and mon.failed_in_row == 0 and not mon.clearly_inconsistent


SEEDS = range(1000, 1010)


@pytest.fixture(scope='module')
def car_runs():
    """The MEMS car with RTK (still 30 s, then driving), node defaults, ``auto``, 10 seeds.

    The first 300 s of its 518: the junction turns, stops and bends where its phase used
    to switch (at 127 s in one seed; the rest of the run keeps the test under a minute).
    """
    return [run_scenario('car_rtk', seed, 'auto', duration=300.0, cached=True)
            for seed in SEEDS]


def test_the_mems_car_leaves_aligned_at_most_once_per_run(car_runs):
    """Before issue 46: up to 2 switches a run (NIS/dof 1.69-1.85 against 1.66, each answered
    by its remedy) and ``aligned`` at 90 s; now none of them leave, and ``aligned`` comes
    as soon as the estimate has settled inside the thresholds (about 66 s)."""
    for seed, run in zip(SEEDS, car_runs):
        al = np.asarray(run.out.phase) == 'aligned'
        assert al.any(), f'seed {seed} never aligned'
        assert int(np.sum(al[:-1] & ~al[1:])) <= 1, f'seed {seed}'
        assert al[-1], f'seed {seed} does not end aligned'


def test_every_aligned_row_of_the_mems_car_lies_inside_3_sigma(car_runs):
    """Earlier ``aligned`` is no looser claim: the rows it marks are covered (heading within
    3 sigma of the yaw 1-sigma, tilt of the roll/pitch ones; the ENU misalignment against
    the Euler sigmas, which agree to first order for a level car)."""
    for seed, run in zip(SEEDS, car_runs):
        al = np.flatnonzero(np.asarray(run.out.phase) == 'aligned')
        err = attitude_errors(run.out, run.truth_euler, al)
        inside = np.abs(err) <= 3.0 * run.out.sigma[al]
        assert inside.mean() >= 0.99, (seed, inside.mean(axis=0))


def test_the_mems_car_is_aligned_within_20_s_of_starting_to_drive(car_runs):
    """Issue 46's target for this car. The coarse window ends ``coarse_motion_s`` (5 s) after
    GNSS shows the motion (a 5 Hz receiver: within one epoch and the 1-s motion test of
    the truth's start), and the aided filter is ``aligned`` once settled inside the
    thresholds: measured 16-18 s after the motion starts (was 60 s: the fixed 60-s window
    and a 30-s stage minimum), bench/results/time_to_align.md."""
    for seed, run in zip(SEEDS, car_runs):
        t = run.out.t - run.data.imu.t[0]
        speed = np.linalg.norm(run.data.imu.v_n[run.rows][:, :2], axis=1)
        t_move = t[np.argmax(speed > 0.2)]
        ph = np.asarray(run.out.phase)
        t_fine = t[np.argmax(ph != 'coarse')]
        assert t_move + 5.0 <= t_fine <= t_move + 5.0 + 1.5, (seed, t_move, t_fine)
        t_al = t[np.argmax(ph == 'aligned')]
        assert t_al - t_move <= 20.0, (seed, t_move, t_al)

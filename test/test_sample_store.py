"""A restart reuses the stored rest before the motion (issue 46, inputs/sample_store.py).

The store against closed-form stamps (what it keeps, what it hands back, the interval of
the first sample), and the whole flow on a car that stood 90 s (longer than the coarse
window: a still-base filter runs when it starts to drive) and then drives.
"""
import numpy as np
import pytest

from sins_align_ros.align.inputs.sample_store import SampleStore
from sins_align_ros.eval.cache import simulate_cached
from sins_align_ros.eval.errors import attitude_errors
from sins_align_ros.eval.run import run_pipeline
from sins_align_ros.sim.presets import alignment_params, scenario, starting_still

DT = 0.01


def _push(store, t0, t1):
    t = np.arange(t0 + DT, t1 + DT / 2, DT)
    store.push(t, np.full((len(t), 3), 1e-5), np.full((len(t), 3), 0.098))
    return t


def test_the_store_keeps_its_span_and_hands_back_what_follows_a_stamp():
    st = SampleStore(keep_s=10.0)
    for k in range(30):                          # 30 blocks of 1 s
        _push(st, float(k), float(k + 1))
    t_before, t, dth, dv = st.since(25.005)       # between two stamps
    assert t_before == pytest.approx(25.0) and t[0] == pytest.approx(25.01)
    assert len(t) == 500 and dth.shape == dv.shape == (500, 3)
    # 10 s kept (whole blocks: the oldest one ending 10 s before the newest is dropped)
    t_before, t, _, _ = st.since(0.0)
    assert t[0] >= 30.0 - 10.0 - 1.0 and t[-1] == pytest.approx(30.0)
    # nothing kept before the first: its interval is taken like the next one
    assert t_before == pytest.approx(t[0] - DT)
    assert st.since(30.005) is None               # nothing after the last


@pytest.fixture(scope='module')
def long_rest_runs():
    """The MEMS car with RTK standing 90 s, then driving; node defaults, ``auto``, 3 seeds."""
    out = []
    for seed in (1000, 1001, 1002):
        sc = starting_still(scenario('car_rtk', duration=150.0), 60.0)   # 30 + 60 s of rest
        data = simulate_cached(sc, seed)
        out.append(run_pipeline(alignment_params(sc, 'auto'), data))
    return out


def test_a_car_that_stood_past_the_coarse_window_is_aligned_soon_after_it_drives(long_rest_runs):
    """The still-base filter runs from 60 s; the drive at 90 s restarts it. Before the store,
    the new window was all motion and waited out its 60 s: ``aligned`` 89 s after the car
    started. Now the window begins with the stored rest, ends 5 s after GNSS shows the
    motion, and ``aligned`` comes within 20 s of the start (measured 16-18 s), every
    ``aligned`` row inside 3 sigma."""
    for run in long_rest_runs:
        t = run.out.t - run.data.imu.t[0]
        speed = np.linalg.norm(run.data.imu.v_n[run.rows][:, :2], axis=1)
        t_move = t[np.argmax(speed > 0.2)]
        ph = np.asarray(run.out.phase)
        assert run.pipeline.n_restarts == 1
        restart = np.flatnonzero((ph[1:] == 'coarse') & (ph[:-1] != 'coarse'))
        assert len(restart) == 1
        t_fine = t[restart[0] + 1 + np.argmax(ph[restart[0] + 1:] != 'coarse')]
        assert t_move + 5.0 <= t_fine <= t_move + 5.0 + 1.5, (t_move, t_fine)
        al = np.flatnonzero(ph == 'aligned')
        assert len(al) and t[al[0]] - t_move <= 20.0, (t_move, t[al[0]])
        err = attitude_errors(run.out, run.truth_euler, al)
        assert np.mean(np.abs(err) <= 3.0 * run.out.sigma[al]) >= 0.99

"""Store and reprocess (issue 46) for the GNSS-aided filters: the stage runs over the window.

On by default (``coarse_reprocess_aided``, since session 47); the reprocess module
docstring says what it gives and what it cost.
The window's IMU samples and GNSS fixes go through the fine filter from the window's first
sample (:func:`~sins_align_ros.align.stages.reprocess.aided_start`,
:meth:`~sins_align_ros.align.inputs.gnss_buffer.GnssBuffer.requeue`); what is published
is causal: the window's rows stay ``coarse``.
"""
import numpy as np
import pytest

from sins_align_ros.align.inputs.gnss_buffer import QUEUE, GnssBuffer
from sins_align_ros.align.pipeline import COARSE, AlignmentPipeline
from sins_align_ros.align.stages import reprocess
from sins_align_ros.eval.errors import attitude_errors
from sins_align_ros.eval.run import run_scenario
from sins_align_ros.eval.scenarios import named
from sins_align_ros.nav import earth
from sins_align_ros.nav.frames import attitude_error, euler_to_dcm
from sins_align_ros.sim.presets import alignment_params
from sins_align_ros.sim.scenario import ScenarioStream

#: the ship under way (navigation grade, GNSS position and velocity at 1 Hz), 60-s window
SHIP, SEED, SPAN = 'ship_underway', 1000, 75.0
#: the reprocessing of GNSS-aided stages, on by default (reprocess module docstring), and off
ON, OFF = {'coarse_reprocess_aided': True}, {'coarse_reprocess_aided': False}
#: a whole 60-s window (the ship moves from the start: since session 52 its window ends after
#: coarse_min_duration, 20 s); the fixture and the catch-up test run over the longer one
LONG = {'coarse_min_duration': 60.0}


def test_requeue_puts_the_windows_fixes_ahead_of_the_waiting_ones():
    """Fixes of the history in (t0, t1] are queued again, in order, before those already
    waiting (stamped after t1); the queue grows to hold them all, and shrinks back to its
    bound for live fixes once the stage has taken them."""
    g = GnssBuffer()
    for k in range(300):                             # 300 fixes of history, 1 Hz
        g.position_fix(float(k), 30.0, 120.0, 0.0, None, None, queue=False)
    for k in range(300, 303):                        # three waiting behind the window
        g.position_fix(float(k), 30.0, 120.0, 0.0, None, None, queue=True)
    assert g.requeue(9.5, 299.0) == 290
    stamps = [f[0] for f in g.pending]
    assert stamps == [float(k) for k in range(10, 303)]
    assert g.pending.maxlen == QUEUE + 290
    assert g.fix_nearest(41.4)[0] == 41.0
    for k in range(10, 204):                         # the stage takes them, one a second
        assert g.pop_due(float(k), 0.0).t == float(k)
    assert len(g.pending) == 99 and g.pending.maxlen == QUEUE


@pytest.fixture(scope='module')
def ship_runs():
    """The ship with and without reprocessing, and the aided start it was given."""
    seen = []
    original = reprocess.aided_start

    def spy(res, window, gnss, cfg, install=None):
        out = original(res, window, gnss, cfg, install)
        seen.append((out, window[0][0] - window[3][0]))
        return out

    reprocess.aided_start = spy
    try:
        on = run_scenario(SHIP, SEED, 'asckf', duration=SPAN, cached=True, **ON, **LONG)
    finally:
        reprocess.aided_start = original
    off = run_scenario(SHIP, SEED, 'asckf', duration=SPAN, cached=True, **OFF, **LONG)
    return on, off, seen


def test_the_aided_start_is_the_truth_at_the_windows_start(ship_runs):
    """The attitude turned back to the window's start, the window's first GNSS velocity and
    the nearest fix moved to the start: each inside 3 of its sigmas of the simulated truth
    at the first sample (attitude: the coarse sigma; velocity: the coarse velocity sigma;
    position: 3 x the ship's 1-m GNSS sigma plus 1 s of its 0.1 m/s velocity noise)."""
    on, _, seen = ship_runs
    assert len(seen) == 1 and seen[0][0] is not None
    res, t0 = seen[0]
    imu = on.data.imu
    k = 0                                            # the first sample (its interval's end)
    e = attitude_error(res.C_b_n, euler_to_dcm(imu.euler[k]))
    assert np.all(np.abs(e) <= 3.0 * res.sigma), (np.degrees(e), np.degrees(res.sigma))
    assert np.all(np.abs(res.v_n - imu.v_n[k]) <= 3.0 * res.sigma_v + 0.1 * 1.0)
    lat, lon, h = imu.pos[k]
    R_M, R_N = earth.radii(lat)
    d_n = (res.position[0] - lat) * (R_M + h)
    d_e = (res.position[1] - lon) * (R_N + h) * np.cos(lat)
    assert np.hypot(d_e, d_n) <= 3.0 * np.sqrt(2.0) * 1.0 + 0.3, (d_e, d_n)
    assert t0 == pytest.approx(on.pipeline.fine.t0)


def test_the_window_is_reprocessed_with_its_fixes_and_not_republished(ship_runs):
    """The stage started at the window's first sample and took the window's fixes (1 Hz:
    59 or 60 of them before its end, none dropped as before its start or late); the
    window's rows are coarse, as they were published; from the first fine row on, the
    heading is inside 3 sigma, and narrower than the stage started at the window's end
    (the same samples, used once more)."""
    on, off, _ = ship_runs
    assert 'reprocessed_s' not in off.pipeline.coarse_info     # turned off
    assert on.pipeline.coarse_info['reprocessed_s'] == pytest.approx(60.0, abs=0.02)
    p = on.pipeline
    counts = p.gnss.counts
    assert counts['before_start'] == 0 and counts['late'] == 0
    assert counts['used'] >= 59 + int(SPAN - 61.0)
    first_on = np.flatnonzero(on.out.phase != COARSE)[0]
    first_off = np.flatnonzero(off.out.phase != COARSE)[0]
    assert abs(first_on - first_off) <= 1             # the same window end, same rows coarse
    rows = np.arange(first_on, len(on.out.t))
    e = attitude_errors(on.out, on.truth_euler, rows)
    assert np.all(np.abs(e) <= 3.0 * on.out.sigma[rows])
    assert on.out.sigma[first_on, 2] < 0.6 * off.out.sigma[first_off, 2]


@pytest.mark.parametrize('scen, filt, span', [(SHIP, 'asckf', 62.0), ('car_rtk', 'auto', 40.0)])
def test_the_first_published_attitude_is_covered_by_its_sigma(scen, filt, span):
    """The prior does not count the window twice (reprocess.aided_start: the coarse sigma
    is three times the window's own 1-sigma in each term, so it claims at most a ninth of
    what the fit took from the samples the filter then runs over). What that must give,
    tested against truth: at the first published row after the window (the ship under
    way; the MEMS car with RTK 5 s after it starts to drive) the error over its sigma,
    over 8 seeds, has a mean square per axis within the chi-square bound of 8 degrees of
    freedom (17.53 / 8 at 97.5 %), and no seed beyond 3 sigma. (A sigma that took the
    window's information twice would be about sqrt(2) too narrow: mean squares near 2.)"""
    z = []
    for seed in range(8):
        r = run_scenario(scen, seed, filt, duration=span, cached=True, **ON)
        k = np.flatnonzero(r.out.phase != COARSE)[0]
        assert r.pipeline.coarse_info.get('reprocessed_s', 0.0) > 0.0
        z.append(attitude_errors(r.out, r.truth_euler, [k])[0] / r.out.sigma[k])
    z = np.array(z)
    assert np.all(np.mean(z ** 2, axis=0) <= 17.53 / 8.0), np.mean(z ** 2, axis=0)
    assert np.all(np.abs(z) <= 3.0), z


def test_fixes_that_come_while_the_stage_catches_up_are_queued_behind_the_window():
    """A live node at 1 kHz: the window's 60 000 samples are run over in pieces of
    CATCH_UP_SAMPLES, one per IMU call, while new samples and fixes keep coming. A fix
    that comes meanwhile is stamped a minute after the sample the stage has reached: it is
    queued behind the window (not dropped as ahead of the IMU's clock, which is the last
    queued sample's), and every fix from the window's start on is used once."""
    sc = named(SHIP, 66.0)
    b = ScenarioStream(sc, seed=2, imu_rate_hz=1000.0).next_block(66000)
    p = AlignmentPipeline({**alignment_params(sc, 'asckf'), **ON, **LONG})
    p.start_clock(0.0)
    imu, g = b.imu, b.gnss
    gi, catching = 0, 0
    for k in range(0, len(imu.t), 10):
        while gi < len(g.t) and g.t[gi] <= imu.t[k]:
            p.position_fix(g.t[gi], np.degrees(g.lat[gi]), np.degrees(g.lon[gi]), g.h[gi])
            p.velocity_fix(g.t[gi], g.v_n[gi])
            gi += 1
        p.process(imu.t[k:k + 10], imu.dtheta[k:k + 10], imu.dv[k:k + 10])
        catching += p.catch_up is not None
    counts = p.gnss.counts
    assert catching >= 2                     # the catch-up took more than one call
    assert counts['ahead_of_imu'] == 0 and counts['late'] == 0
    assert counts['before_start'] == 0 and counts['queue_full'] == 0
    assert counts['used'] + len(p.gnss.pending) == gi          # every fix given

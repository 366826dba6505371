"""The fine stage's GNSS and external-heading epochs (align/stages/fine_epochs.py).

Through the pipeline's input calls and the fine stage's public read-outs only (the stage's
epoch mixin is reached by stepping it): simulated runs (seeded) of a ship underway with the
15-state ``kf`` and of a still MEMS IMU with ``stationary12`` and an external heading.
Checked: an epoch goes to the engine at the first IMU sample that passes its stamp, a
stale one is counted late, a heading measured makes the heading known and its sigma lies
between the information bound of the epochs and one epoch's, an outlier is rejected, and
the estimates stay within 3 sigma of the simulator's truth.
"""
import functools
import math

import numpy as np

from sins_align_ros.align.inputs.gnss_buffer import MAX_LAG_S
from sins_align_ros.align.output import ANGLE_UNKNOWN_VAR
from sins_align_ros.align.pipeline import AlignmentPipeline
from sins_align_ros.nav.frames import attitude_error, dcm_to_euler, euler_to_dcm
from sins_align_ros.sim.gnss import heading_measurements
from sins_align_ros.sim.presets import alignment_params, scenario
from sins_align_ros.sim.scenario import ScenarioStream
from sins_align_ros.units import DEG

RATE = 100            # IMU samples per second of the scenarios used
T_RUN = 90.0          # 60 s coarse window, 30 s fine
HEADING_SIGMA = 0.5 * DEG
SEED = 5


@functools.lru_cache(maxsize=None)
def _block(name, seconds):
    """The first ``seconds`` of scenario ``name`` (seed :data:`SEED`)."""
    return ScenarioStream(scenario(name), seed=SEED).next_block(int(round(seconds * RATE)))


def _feed(p, b, i, j, gnss=True, heading=None):
    """Give ``p`` samples ``i:j`` of ``b``, each GNSS / heading epoch before the block it is in."""
    t_end = b.imu.t[j - 1] + 1e-9
    if gnss:
        G = b.gnss
        t_prev = (b.imu.t[i - 1] if i else -1.0) + 1e-9
        for k in np.flatnonzero((G.t > t_prev) & (G.t <= t_end)):
            p.position_fix(G.t[k], G.lat[k] / DEG, G.lon[k] / DEG, G.h[k], pos_var=G.pos_cov[:2])
            p.velocity_fix(G.t[k], G.v_n[k], vel_var=G.vel_cov[:2])
    if heading is not None:
        for k in np.flatnonzero((heading.t > (b.imu.t[i - 1] if i else -1.0) + 1e-9)
                                & (heading.t <= t_end)):
            p.heading_fix(heading.t[k], heading.yaw[k], heading.var[k])
    p.feed(b.imu.t[i:j], b.imu.dtheta[i:j], b.imu.dv[i:j])


def _run(name, fine_filter, seconds, gnss=True, heading=None):
    """A pipeline fed the first ``seconds`` of ``name`` in 1 s blocks; returns it and the block."""
    b = _block(name, seconds + 2.0)       # and 2 s more for the test to step on
    p = AlignmentPipeline(alignment_params(scenario(name), fine_filter))
    n = int(round(seconds * RATE))
    for i in range(0, n, RATE):
        _feed(p, b, i, min(n, i + RATE), gnss, heading)
    return p, b


def _within_3_sigma(p, b, k):
    """Assert the fine stage's attitude within 3 sigma of the truth at sample ``k``."""
    phi = attitude_error(p.fine.mech.C_b_n, euler_to_dcm(b.imu.euler[k]))
    sig = np.sqrt(np.diag(p.fine.attitude_cov()))
    assert np.all(np.abs(phi) <= 3.0 * sig), phi / sig


def test_gnss_epochs_go_to_the_engine_at_the_sample_that_passes_their_stamp():
    p, b = _run('ship_underway', 'kf', T_RUN)
    # the stage started at the 60-s window's start and ran over it (coarse_reprocess_aided)
    assert p.phase in ('fine', 'aligned') and p.aided and p.fine.t0 == 0.0
    counts = dict(p.gnss.counts)
    # every fix stamped after the fine start, up to the last sample: 1 .. 90 s
    assert counts['used'] == 90 and p.gnss.t_used == T_RUN
    assert counts['late'] == counts['before_start'] == counts['ahead_of_imu'] == 0
    n = int(T_RUN * RATE)
    _within_3_sigma(p, b, n - 1)
    # the 91 s fix waits through the samples before 91 s and is taken at 91 s itself
    G = b.gnss
    k91 = int(np.flatnonzero(G.t == 91.0)[0])
    p.position_fix(G.t[k91], G.lat[k91] / DEG, G.lon[k91] / DEG, G.h[k91],
                   pos_var=G.pos_cov[:2])
    p.velocity_fix(G.t[k91], G.v_n[k91], vel_var=G.vel_cov[:2])
    p.feed(b.imu.t[n:n + RATE - 1], b.imu.dtheta[n:n + RATE - 1], b.imu.dv[n:n + RATE - 1])
    assert b.imu.t[n + RATE - 2] < 91.0 and p.gnss.counts['used'] == 90
    p.feed(b.imu.t[n + RATE - 1:n + RATE], b.imu.dtheta[n + RATE - 1:n + RATE],
           b.imu.dv[n + RATE - 1:n + RATE])
    assert p.gnss.counts['used'] == 91 and p.gnss.t_used == 91.0
    # a fix stamped more than MAX_LAG_S before the sample it would be applied at: late
    k = n + RATE
    t_old = b.imu.t[k] - MAX_LAG_S - 0.2
    p.position_fix(t_old, G.lat[k91] / DEG, G.lon[k91] / DEG, G.h[k91])
    p.feed(b.imu.t[k:k + 1], b.imu.dtheta[k:k + 1], b.imu.dv[k:k + 1])
    assert p.gnss.counts['late'] == 1 and p.gnss.counts['used'] == 91
    _within_3_sigma(p, b, k)


def test_monitor_read_outs_of_an_aided_and_a_still_stage():
    p, _ = _run('ship_underway', 'kf', T_RUN)
    status = p.fine.monitor_status()
    # the aided stage's three monitors each report; the motion check judged a window
    for prefix in ('slow_monitor_', 'motion_check_', 'course_heading_'):
        assert any(k.startswith(prefix) for k in status), prefix
    assert status['motion_check_windows'] >= 1
    first = p.fine.monitor_findings()
    assert isinstance(first, list) and p.fine.monitor_findings() == []   # each said once
    p, _ = _run('static_mems', 'stationary12', 61.0, gnss=False)
    assert p.fine.monitor_status() == {} and p.fine.monitor_findings() == []


def test_an_external_heading_makes_the_heading_known_and_an_outlier_is_rejected():
    name = 'static_mems'
    b = _block(name, T_RUN + 2.0)
    H = heading_measurements(b.imu.t, b.imu.euler[:, 2], HEADING_SIGMA, 1.0,
                             np.random.default_rng(SEED), t_start=61.0)
    # a MEMS gyro cannot find north: published as unknown until a heading comes
    p, _ = _run(name, 'stationary12', 61.0, gnss=False)
    assert not p.fine.heading_known
    assert p.fine.attitude_cov()[2, 2] == ANGLE_UNKNOWN_VAR
    p, _ = _run(name, 'stationary12', T_RUN, gnss=False, heading=H)
    counts = p.headings.counts
    n_epochs = int(np.count_nonzero((H.t > p.fine.t0) & (H.t <= T_RUN + 1e-9)))
    assert counts['used'] + counts['taken'] == n_epochs and counts['rejected'] == 0
    assert counts['taken'] == 1               # the first, beyond the linear range: taken
    assert p.fine.heading_known
    # between the information of the n epochs (sigma / sqrt(n): no filter knows more)
    # and one epoch's (each is used, so it cannot know less)
    s_h = math.sqrt(p.fine.attitude_cov()[2, 2])
    assert HEADING_SIGMA / math.sqrt(n_epochs) <= s_h <= HEADING_SIGMA
    n = int(T_RUN * RATE)
    _within_3_sigma(p, b, n - 1)
    # a heading 20 deg off (40 sigma): rejected, the yaw stays
    yaw = dcm_to_euler(p.fine.mech.C_b_n)[2]
    p.heading_fix(b.imu.t[n], b.imu.euler[n, 2] + math.radians(20.0), HEADING_SIGMA ** 2)
    p.feed(b.imu.t[n:n + 1], b.imu.dtheta[n:n + 1], b.imu.dv[n:n + 1])
    assert p.headings.counts['rejected'] == 1
    assert abs(dcm_to_euler(p.fine.mech.C_b_n)[2] - yaw) <= 3.0 * s_h
    _within_3_sigma(p, b, n)

"""The alignment session's increments entry and read-outs (align/session.py), no ROS."""
import numpy as np

from sins_align_ros.align import AlignmentPipeline, AlignmentSession, Output
from sins_align_ros.eval.feed import feed_arrays
from sins_align_ros.nav.frames import euler_to_dcm
from sins_align_ros.sim.presets import alignment_params, scenario
from sins_align_ros.sim.scenario import ScenarioStream
from sins_align_ros.units import DEG

FIELDS = ('t', 'q', 'euler', 'sigma', 'P_phi', 'phase')


def _still(seconds=20.0):
    sc = scenario('static_navigation', duration=seconds)
    return sc, ScenarioStream(sc, seed=7).next_block(int(seconds * sc.imu_rate_hz))


def _same(a, b):
    """Tell whether two outputs hold the same rows, bit for bit."""
    return (len(a) == len(b) and np.array_equal(a.phase, b.phase)
            and all(np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True)
                    for f in FIELDS[:-1]))


def test_increments_reach_the_pipeline_as_they_are():
    """The session's increments entry is the pipeline's feed: the same floats, no checks."""
    sc, b = _still()
    params = alignment_params(sc, 'reduced7', coarse_duration=5.0)
    p = AlignmentPipeline(params)
    p.start_clock(0.0)
    direct = Output.concat([p.feed(b.imu.t, b.imu.dtheta, b.imu.dv), p.flush()])
    session = AlignmentSession(params)
    session.start_clock(0.0)
    via = Output.concat([session.increments(b.imu.t, b.imu.dtheta, b.imu.dv),
                         session.finish()])
    assert np.count_nonzero(np.isin(direct.phase, ('fine', 'aligned'))) > 1000
    assert _same(direct, via)
    # the session has no IMU input checks on this path: nothing counted as accepted
    assert session.imu_accepted == 0 and session.imu_rejected == 0
    # feed_arrays around a pipeline the caller built, in one block: the same rows again
    q = AlignmentPipeline(params)
    q.start_clock(0.0)
    assert _same(direct, feed_arrays(q, b.imu, None, block=len(b.imu.t)))


def test_read_outs_show_counts_mounting_and_phase():
    """What the node shows, read from the session: phase, counts, the mounting rotation."""
    session = AlignmentSession({'imu_mounting_rpy_deg': [0.0, 0.0, 90.0],
                                'initial_latitude_deg': 34.0, 'coarse_duration': 1.0})
    assert session.phase == 'waiting' and session.C_s_v is not None
    assert np.array_equal(session.C_s_v, euler_to_dcm(np.array([0.0, 0.0, 90.0]) * DEG))
    n = 50
    t = 0.01 * np.arange(1, n + 1)
    w_b = np.tile([0.0, 0.0, 7.292115e-5 * np.sin(34.0 * DEG)], (n, 1))
    f_b = np.tile([0.0, 0.0, 9.79], (n, 1))
    session.imu_block(t, w_b, f_b)
    # the first sample starts the clock; the others pass the checks
    assert session.imu_accepted == n - 1 and session.imu_rejected == 0
    assert session.phase == 'coarse' and session.status()['phase'] == 'coarse'
    session.reject_imu('wrong_frame', 'test: wrong frame')
    session.fix(t[-1], -1, 34.0, 108.0, 10.0)            # NavSatFix STATUS_NO_FIX
    assert session.imu_rejected == 1 and session.gnss_rejected == 1
    imu_counts, gnss_counts = session.input_counts()
    assert imu_counts['wrong_frame'] == 1 and gnss_counts['no_fix'] == 1
    assert session.warnings is session.pipeline.warnings
    session.restart('test')
    assert session.phase == 'waiting' and session.warnings is session.pipeline.warnings


def test_navigation_read_out_gives_the_rate_noise_of_the_configured_gyro():
    """``~/odom``'s twist noise: ARW^2 / dt, with the input's nominal interval (0.01 s here)."""
    sc, b = _still(30.0)
    params = alignment_params(sc, 'kf', coarse_duration=5.0)
    session = AlignmentSession(params)
    rates = b.imu.dtheta / 0.01
    forces = b.imu.dv / 0.01
    session.imu_block(b.imu.t, rates, forces)
    assert session.phase in ('fine', 'aligned')
    nav = session.navigation()
    arw = params['gyro_arw_dpsh'] * DEG / 60.0                  # deg/sqrt(h) -> rad/sqrt(s)
    assert np.isclose(nav.rate_var, arw ** 2 / 0.01, rtol=1e-9)
    assert nav.gyro_bias.shape == (3,) and np.all(np.isfinite(nav.gyro_bias))
    assert nav.P_nav.shape == (9, 9) and np.all(np.diag(nav.P_nav) > 0.0)

"""Property-based test (hypothesis): random message sequences through the pipeline.

The sequences mix good IMU samples with non-finite values, repeated, backward and
jumping stamps, gaps and saturated values, and GNSS fixes and velocities that are
good, absurd or non-finite. They go through the same input checks as the node and
the replay tool (:class:`~sins_align_ros.align.inputs.imu_input.ImuInput`). Whatever
arrives: no exception escapes, and every attitude the pipeline gives is finite,
a unit quaternion, with a finite covariance.
"""
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from sins_align_ros.align.inputs.gnss_input import GnssInput
from sins_align_ros.align.inputs.imu_input import OK, RESET, START, ImuInput
from sins_align_ros.align.pipeline import AlignmentPipeline
from sins_align_ros.units import G0

BAD = st.sampled_from([math.nan, math.inf, -math.inf, 1e9, -1e9, 0.0])
DT = st.sampled_from([0.01] * 12 + [0.0, -0.004, -3.0, 0.8, 0.02, 1e-6])


def _vec(good):
    return st.one_of(good, st.tuples(BAD, BAD, BAD), st.tuples(good.map(lambda v: v[0]), BAD,
                                                               BAD))


GYRO = st.tuples(*[st.floats(-2e-4, 2e-4)] * 3)
ACC = st.tuples(st.floats(-0.2, 0.2), st.floats(-0.2, 0.2), st.floats(G0 - 0.2, G0 + 0.2))
IMU = st.tuples(st.just('imu'), DT, st.one_of(GYRO, GYRO, GYRO, _vec(GYRO)),
                st.one_of(ACC, ACC, ACC, _vec(ACC)))
FIX = st.tuples(st.just('fix'), st.one_of(st.floats(30.0, 30.001), BAD, st.just(95.0)),
                st.one_of(st.floats(120.0, 120.001), BAD), st.one_of(st.floats(0, 10), BAD))
VEL = st.tuples(st.just('vel'), st.one_of(st.floats(-0.1, 0.1), BAD), st.floats(-0.1, 0.1))
EVENTS = st.lists(st.one_of(IMU, IMU, IMU, IMU, IMU, IMU, IMU, IMU, FIX, VEL),
                  min_size=50, max_size=400)


def _run(events, fine_filter):
    p = AlignmentPipeline({'fine_filter': fine_filter, 'coarse_duration': 1.0,
                           'initial_latitude_deg': 30.0, 'initial_longitude_deg': 120.0})
    conv = ImuInput(0.5, gyro_range=np.radians(2000.0), accel_range=160.0)
    gnss = GnssInput()
    t = 1000.0
    outs = []
    for ev in events:
        if ev[0] == 'imu':
            t += ev[1]
            action, dth, dv = conv.push(t, ev[2], ev[3])
            if action == OK:
                if conv.bridge is not None:
                    p.widen(*conv.bridge)
                outs.append(p.process(np.array([t]), dth[None, :], dv[None, :]))
            elif action in (RESET, START):
                if action == RESET:
                    p.reset()
                p.start_clock(t)
        elif ev[0] == 'fix':
            var = gnss.fix(t, 0, ev[1], ev[2], ev[3])
            if var is not False:
                p.position_fix(t, ev[1], ev[2], ev[3], pos_var=var)
        else:
            v = np.array([ev[1], ev[2], 0.0])
            var = gnss.velocity(t, v)
            if var is not False:
                p.velocity_fix(t, v, vel_var=var)
    return outs, p


@pytest.mark.parametrize('fine_filter', ['reduced7', 'asckf', 'mvbakf', 'ukf'])
@settings(max_examples=40, deadline=None, derandomize=True,
          phases=[Phase.explicit, Phase.reuse, Phase.generate],
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(events=EVENTS)
def test_random_message_sequences_never_raise_and_attitudes_stay_valid(fine_filter, events):
    for out in _run(events, fine_filter)[0]:
        have = ~np.isnan(out.q[:, 3])
        assert np.all(have[out.phase != 'coarse'])     # past coarse, always an attitude
        q = out.q[have]
        assert np.all(np.isfinite(q))
        np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-9)
        assert np.all(np.isfinite(out.P_phi[have]))
        if out.nav is not None:                        # navigation rows: finite or all NaN
            nav = out.nav[~np.isnan(out.nav[:, 0])]
            assert np.all(np.isfinite(nav))


@pytest.mark.parametrize('fine_filter', ['reduced7', 'asckf', 'mvbakf', 'ukf'])
def test_the_harness_reaches_fine_alignment_on_good_input(fine_filter):
    """The random sequences above are as long as this one: the fine phase is exercised."""
    lat = math.radians(30.0)
    w_ie = 7.292115e-5 * np.array([0.0, math.cos(lat), math.sin(lat)])
    good = [('imu', 0.01, tuple(w_ie), (0.0, 0.0, G0))] * 99 + [
        ('fix', 30.0, 120.0, 5.0), ('vel', 0.0, 0.0)]
    outs, _ = _run(good * 4, fine_filter)
    phases = set(np.concatenate([o.phase for o in outs]))
    assert 'fine' in phases
    assert np.all(np.isfinite(outs[-1].q[-1]))


def test_zero_gyro_output_restarts_coarse_with_a_reason_not_a_nan_attitude():
    """A dead gyro (exact zeros) leaves the analytic coarse alignment without a heading."""
    dead = [('imu', 0.01, (0.0, 0.0, 0.0), (0.0, 0.0, G0))] * 250
    with np.errstate(invalid='ignore'):
        outs, p = _run(dead, 'reduced7')
    phases = np.concatenate([o.phase for o in outs])
    assert set(phases) == {'coarse'}
    assert any('coarse alignment degenerate' in w for w in p.warnings)

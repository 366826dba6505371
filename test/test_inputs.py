"""The input rules (align/inputs/imu_input.py, gnss_input.py) and the GNSS gate, no ROS."""
from types import SimpleNamespace

import numpy as np
import pytest

from sins_align_ros.align.inputs.gnss_input import GnssInput
from sins_align_ros.align.inputs.imu_input import OK, RATE_WINDOW, RESET, SKIP, START, ImuInput
from sins_align_ros.align.engines.moving import MovingBaseAlignment
from sins_align_ros.align.pipeline import AlignmentPipeline
from sins_align_ros.eval.feed import feed_arrays
from sins_align_ros.nav.frames import attitude_error, euler_to_dcm, quat_to_dcm
from sins_align_ros.sim.faults import MessageStream, inject
from sins_align_ros.sim.presets import scenario
from sins_align_ros.sim.scenario import ScenarioStream
from sins_align_ros.units import ARCMIN
from tolerance import roundoff  # noqa: E402


def _feed(conv, t, w):
    return [conv.push(tk, wk, (0.0, 0.0, 9.8)) for tk, wk in zip(t, w)]


def test_a_bridge_over_missing_samples_is_exact_for_a_linear_rate_and_widens_by_its_bound():
    dt = 0.01
    t = np.arange(1, 301) * dt
    w = np.column_stack([0.1 * t, np.zeros_like(t), np.zeros_like(t)])   # rate ramp
    keep = np.ones(len(t), bool)
    keep[200:210] = False                                                  # 0.1 s missing
    conv = ImuInput(0.5)
    res = _feed(conv, t[keep], w[keep])
    k = int(np.flatnonzero(~keep)[-1]) + 1 - 10                            # index after gap
    action, dth, _ = res[k]
    assert action == OK and conv.counts['bridged'] == 1
    # mean rate over (t[199], t[210]] of a linear ramp: exactly the trapezoid of the ends
    assert dth[0] == pytest.approx(0.1 * (t[210] ** 2 - t[199] ** 2) / 2.0, rel=1e-12)
    conv2 = ImuInput(0.5)
    _feed(conv2, t[keep][:k], w[keep][:k])
    conv2.push(t[210], w[210], (0.0, 0.0, 9.8))
    dw = w[210, 0] - w[199, 0]
    assert conv2.bridge[0] == pytest.approx((dw * 0.11 / 2.0) ** 2, rel=1e-9)
    assert conv2.bridge[1] == 0.0


def test_imu_rules_skip_reset_and_rate_change():
    conv = ImuInput(0.5, gyro_range=np.radians(300.0), accel_range=50.0)
    assert conv.push(0.0, (0, 0, 0), (0, 0, 9.8))[0] == START
    assert conv.push(0.01, (np.nan, 0, 0), (0, 0, 9.8))[0] == SKIP
    assert conv.push(0.01, (np.radians(300.0), 0, 0), (0, 0, 9.8))[0] == SKIP
    assert conv.push(0.01, (0, 0, 0), (0, 0, 60.0))[0] == SKIP
    assert conv.push(0.01, (0, 0, 0), (0, 0, 9.8))[0] == OK
    assert conv.push(0.01, (0, 0, 0), (0, 0, 9.8))[0] == SKIP            # repeated stamp
    assert conv.push(0.005, (0, 0, 0), (0, 0, 9.8))[0] == SKIP           # out of order
    assert conv.push(1.0, (0, 0, 0), (0, 0, 9.8))[0] == RESET            # gap
    assert conv.push(0.2, (0, 0, 0), (0, 0, 9.8))[0] == RESET            # clock back
    assert dict(conv.counts) == {'clock_start': 1, 'nan': 1, 'saturated': 2, 'accepted': 1,
                                 'stamp_not_increasing': 2, 'gap': 1, 'clock_jump_back': 1}
    assert conv.rejected == 5 and len(conv.pop_notices()) == 7 and not conv.notices
    conv = ImuInput(0.5)
    t = np.r_[np.arange(0, 2.0, 0.01), 2.0 + np.arange(1, 201) * 0.02]
    _feed(conv, t, np.zeros((len(t), 3)))
    assert conv.counts['rate_change'] == 1 and conv.dt_nominal == pytest.approx(0.02)
    assert any('from 100.0 to 50.0 Hz' in txt for _, txt in conv.pop_notices())


def test_gnss_rules():
    g = GnssInput()
    assert g.fix(1.0, -1, np.nan, np.nan, np.nan) is False
    assert g.fix(1.0, -2, 30.0, 120.0, 0.0) is False
    assert g.fix(1.0, 0, 95.0, 120.0, 0.0) is False
    assert g.fix(1.0, 0, 30.0, 120.0, 0.0, (1e12, 1e12)) is False
    assert g.fix(1.0, 0, 30.0, 120.0, 0.0, (0.0, 0.0)) is None           # implausible: config
    assert g.fix(1.0, 0, 30.0, 120.0, 0.0, (0.04, 0.04)) is False        # repeated stamp
    np.testing.assert_allclose(g.fix(2.0, 0, 30.0, 120.0, 0.0, (0.04, 0.05)), [0.04, 0.05])
    assert g.fix(1.5, 0, 30.0, 120.0, 0.0) is False                      # out of order
    assert g.fix(-10.0, 0, 30.0, 120.0, 0.0) is None                     # clock jumped back
    assert g.velocity(1.0, (0.0, 0.0, 0.0), (0.0, 0.0)) is None          # all zero: unknown
    assert g.velocity(2.0, (600.0, 0.0, 0.0)) is False
    assert g.velocity(3.0, (np.inf, 0.0, 0.0)) is False
    assert g.velocity(4.0, (1.0, 0.0, 0.0), (1e6, 1e6)) is False
    keys = ('no_fix', 'status_unknown', 'out_of_range', 'covariance_too_large',
            'covariance_implausible', 'stamp_not_increasing', 'clock_jump_back', 'nan')
    assert all(g.counts[k] >= 1 for k in keys), dict(g.counts)
    assert g.rejected == 9


def test_gnss_variance_and_speed_checks_at_their_edges():
    """The scalar checks of the reported variances and the speed: non-finite, zero and
    negative variances are implausible, a finite velocity whose square overflows is out of
    range (not a non-finite value), and 500 m/s itself is in range."""
    from sins_align_ros.align.inputs.gnss_input import reported_variances
    for bad in ((np.nan, 1.0), (1.0, np.inf), (-np.inf, 1.0), (0.0, 1.0), (1.0, -2.0), (1.0,)):
        assert reported_variances(bad) is None
    np.testing.assert_array_equal(reported_variances([0.5, 2.0, 9.0]), [0.5, 2.0])
    assert reported_variances((1e-6, 1.0), lo=1e-6) is None
    g = GnssInput()
    assert g.velocity(1.0, (1e200, 0.0, 0.0)) is False
    assert g.velocity(2.0, (np.nan, 0.0, 0.0)) is False
    assert g.velocity(3.0, (300.0, 400.0, 0.0)) is None
    assert g.velocity(4.0, (0.0, 0.0, 0.0), (np.nan, 0.0)) is None      # implausible: config
    assert g.fix(1.0, 0, 30.0, np.inf, 0.0) is False
    assert dict(g.counts) == {'out_of_range': 1, 'nan': 2, 'accepted_vel': 2,
                              'covariance_implausible': 1}


def _ship_stream(seconds=300.0, seed=1):
    sc = scenario('seed000_case1', duration=seconds)
    return MessageStream(ScenarioStream(sc, seed=seed, imu_rate_hz=50.0).next_block(
        int(seconds * 50)))


def _run_pipeline(s, **params):
    """Feed a message stream through the input checks and the pipeline (the node's rules)."""
    p = AlignmentPipeline({'fine_filter': 'asckf', 'gnss_pos_sigma_m': 0.2,
                           'gnss_vel_sigma_mps': 0.02, **params})
    conv, gi, g = ImuInput(0.5), GnssInput(), s.gnss
    for kind, i in s.events():
        if kind == 'gnss':
            var = gi.fix(g['t'][i], g['status'][i], g['lat_deg'][i], g['lon_deg'][i],
                         g['h'][i], g['pos_var'][i])
            if var is not False:
                p.position_fix(g['t'][i], g['lat_deg'][i], g['lon_deg'][i], g['h'][i], var)
            if g['has_vel'][i] and gi.velocity(g['t'][i], g['vel'][i]) is not False:
                p.velocity_fix(g['t'][i], g['vel'][i], g['vel_var'][i])
            continue
        a, dth, dv = conv.push(s.imu['t'][i], s.imu['w'][i], s.imu['f'][i])
        if a == START:
            p.start_clock(s.imu['t'][i])
        elif a == OK:
            if conv.bridge is not None:
                p.widen(*conv.bridge)
            p.process(s.imu['t'][i], dth, dv)
    return p


def test_gate_rejects_outliers_and_re_anchors_after_a_jump():
    base = _ship_stream()
    ref = _run_pipeline(_ship_stream())
    st = ref.status()
    assert st['gnss_rejected'] <= 3 and st['gnss_forced'] == 0
    s = _ship_stream()
    inject(s, 'gnss_outliers', 150.0, 158.0, size=30.0)
    p = _run_pipeline(s)
    st = p.status()
    assert st['gnss_rejected'] >= 8 and st['gnss_forced'] == 0
    conds = [c for _, c in p.conditions()]
    assert any('rejected by the innovation gate' in c for c in conds)
    s = _ship_stream()
    inject(s, 'gnss_jump', 150.0, 300.0, size=50.0)
    p = _run_pipeline(s)
    st = p.status()
    assert st['gnss_forced'] >= 1 and st['gnss_consecutive_rejects'] == 0
    assert any('re-anchored' in c for _, c in p.conditions())
    for pipe in (ref, p):
        err = attitude_error(pipe.mech.C_b_n, euler_to_dcm(base.truth.euler[-1]))
        sig = np.sqrt(np.diag(pipe.attitude_cov()))
        assert np.all(np.abs(err) <= 3 * sig + np.r_[0.2, 0.2, 3.0] * ARCMIN), (
            err / ARCMIN, sig / ARCMIN)


def test_without_gate_an_outlier_burst_pulls_the_attitude_further():
    """The gate is what keeps 30 m outliers out: without it the tilt moves more."""
    s = _ship_stream()
    inject(s, 'gnss_outliers', 150.0, 158.0, size=30.0)
    on = _run_pipeline(s)
    s = _ship_stream()
    inject(s, 'gnss_outliers', 150.0, 158.0, size=30.0)
    off = _run_pipeline(s, gnss_gate_probability=1.0)
    assert 'gnss_rejected' not in off.status()
    truth = _ship_stream().truth.euler[-1]
    e_on = attitude_error(on.mech.C_b_n, euler_to_dcm(truth))
    e_off = attitude_error(off.mech.C_b_n, euler_to_dcm(truth))
    assert np.all(np.isfinite(e_off)) and np.linalg.norm(e_on) <= np.linalg.norm(e_off) + 1e-6


def test_forced_acceptances_without_recovery_restart_alignment():
    eng = MovingBaseAlignment(np.eye(3), np.zeros(3), 0.5, 2.0, 0.0, np.eye(10) * 1e-4,
                              np.zeros(10), np.eye(2) * 0.04, gate_probability=0.9999,
                              gate_max_rejects=2)
    from sins_align_ros.align.inputs.gnss_fix import GnssFix
    from sins_align_ros.align.engines.moving import FilterDiverged
    eng.step_imu(np.zeros(3), np.array([0.0, 0.0, 9.8 * 0.01]), 0.01)
    with pytest.raises(FilterDiverged, match='disagree'):
        for k in range(1, 20):
            # a fix that walks away 1 km per epoch: never consistent again
            eng.update(GnssFix(0.01 * k, 0.5 + k * 1.6e-4, 2.0, 0.0), 0.01 * k)
    assert eng.gate.n_forced == 2


def test_feed_arrays_and_message_stream_agree():
    """The message columns carry the simulation unchanged (rates = increments / dt)."""
    sc = scenario('seed000_case1', duration=120.0)
    b = ScenarioStream(sc, seed=3, imu_rate_hz=50.0).next_block(6000)
    p1 = AlignmentPipeline({'fine_filter': 'asckf'})
    p1.start_clock(b.imu.t[0])              # the message path starts the clock at sample 0
    imu = SimpleNamespace(t=b.imu.t[1:], dtheta=b.imu.dtheta[1:], dv=b.imu.dv[1:])
    out = feed_arrays(p1, imu, b.gnss)
    p2 = _run_pipeline(MessageStream(b), gnss_pos_sigma_m=1.0, gnss_vel_sigma_mps=0.1)
    a1 = quat_to_dcm(out.q[-1])
    assert np.abs(attitude_error(a1, p2.mech.C_b_n)).max() < 1e-3 * ARCMIN


def test_gnss_epochs_beyond_the_pending_queue_are_counted_and_reported():
    s = _ship_stream(120.0)
    p = _run_pipeline(s)
    assert p.engine is not None
    t = p.t_last
    for k in range(105):                    # stamped ahead of the IMU, within 10 s
        p.position_fix(t + 0.05 * (k + 1), 45.7796, 126.6705, 0.0)
    assert p.gnss_counts['queue_full'] == 5
    assert any('5 GNSS epoch(s) dropped' in c for _, c in p.conditions())


def _faulty_ship_stream():
    """120 s of the seed 000 ship at 50 Hz with every IMU fault in its own window."""
    s = _ship_stream(120.0, seed=5)
    faults = ('imu_nan', 'imu_inf', 'imu_repeated', 'imu_out_of_order', 'imu_dropped',
              'imu_saturated', 'imu_missing_field', 'imu_gap', 'imu_rate_change')
    for k, fault in enumerate(faults):
        t0 = 8.0 + 10.0 * k
        inject(s, fault, t0, t0 + (0.3 if fault in ('imu_dropped', 'imu_gap') else 2.0),
               gyro_range=np.radians(300.0))
    return s


def test_push_run_leaves_the_checker_as_push_does_sample_by_sample():
    s = _faulty_ship_stream()
    t, w, f = s.imu['t'], s.imu['w'], s.imu['f']
    a, b = ImuInput(0.5, gyro_range=np.radians(300.0)), ImuInput(0.5, gyro_range=np.radians(300.0))
    one = [a.push(t[k], w[k], f[k]) for k in range(len(t))]
    k, runs, got = 0, [], []
    while k < len(t):
        n, dth, dv = b.push_run(t[k:], w[k:], f[k:])
        if n:
            runs.append(n)
            got += [(OK, dth[i], dv[i]) for i in range(n)]
            k += n
        else:
            got.append(b.push(t[k], w[k], f[k]))
            k += 1
    # runs cross rate windows (the nominal rate re-estimated inside them) and the rate
    # change (its notice) as push sample by sample does
    assert len(runs) > 9 and max(runs) > 10 * RATE_WINDOW
    assert a.counts == b.counts and a.t_last == b.t_last and a.counts['rate_change'] >= 1
    assert a.dt_nominal == b.dt_nominal and list(a._dts) == list(b._dts)
    assert a.notices == b.notices
    assert [g[0] for g in got] == [o[0] for o in one]
    for g, o in zip(got, one):
        if o[0] == OK:
            assert np.array_equal(g[1], o[1]) and np.array_equal(g[2], o[2])


def test_push_run_stops_at_a_non_finite_stamp_or_value_without_a_gap_limit():
    """With no gap limit an infinite interval is no gap: the run still ends where push
    would skip a sample (an infinite stamp, an infinite rate)."""
    for bad in ('t', 'w'):
        conv = ImuInput(max_gap=np.inf)
        t = 0.01 * np.arange(2 * RATE_WINDOW + 10)
        w, f = np.zeros((len(t), 3)), np.tile([0.0, 0.0, 9.8], (len(t), 1))
        for k in range(RATE_WINDOW + 1):               # the clock and the nominal rate
            conv.push(t[k], w[k], f[k])
        k0 = RATE_WINDOW + 1
        if bad == 't':
            t[-1] = np.inf
        else:
            w[-3, 1] = np.inf
        n, _, _ = conv.push_run(t[k0:], w[k0:], f[k0:])
        k_bad = len(t) - (1 if bad == 't' else 3)
        assert n == k_bad - k0
        assert conv.push(t[k_bad], w[k_bad], f[k_bad])[0] == SKIP


def test_imu_block_gives_the_rows_and_counts_of_imu_sample_by_sample():
    """The replay's block path against the node's one-sample path, faults included."""
    from sins_align_ros.align.output import Output
    from sins_align_ros.align.session import AlignmentSession
    s = _faulty_ship_stream()
    params = {'fine_filter': 'asckf', 'gnss_pos_sigma_m': 1.0, 'gyro_range_dps': 300.0,
              'coarse_duration': 5.0}
    one, blk = AlignmentSession(params, block=500), AlignmentSession(params, block=500)
    outs1, outs2, pending = [], [], []
    imu, g = s.imu, s.gnss

    def flush():
        if pending:
            k = np.array(pending)
            outs2.append(blk.imu_block(imu['t'][k], imu['w'][k], imu['f'][k], imu['missing'][k]))
            pending.clear()

    for kind, i in s.events():
        if kind == 'imu':
            outs1.append(one.reject_missing_field() if imu['missing'][i]
                         else one.imu(imu['t'][i], imu['w'][i], imu['f'][i]))
            pending.append(i)
            continue
        flush()
        for sess, outs in ((one, outs1), (blk, outs2)):
            outs.append(sess.fix(g['t'][i], g['status'][i], g['lat_deg'][i], g['lon_deg'][i],
                                 g['h'][i], g['pos_var'][i]))
    flush()
    o1 = Output.concat(outs1 + [one.finish()])
    o2 = Output.concat(outs2 + [blk.finish()])
    assert one.input_counts() == blk.input_counts()
    c = one.input_counts()[0]
    assert min(c['field_missing'], c['gap'], c['bridged'], c['nan'], c['saturated']) > 0, c
    assert np.array_equal(o1.t, o2.t) and list(o1.phase) == list(o2.phase)
    ok = np.isfinite(o1.q[:, 0])
    assert ok.sum() > 1000 and np.array_equal(ok, np.isfinite(o2.q[:, 0]))
    # one session fed message by message, one by blocks: the same arithmetic grouped
    # otherwise over the run's samples, n x 150 operations (test_pipeline, test/tolerance.py)
    assert np.abs(o1.q[ok] - o2.q[ok]).max() <= roundoff(len(o1.t) * 150)

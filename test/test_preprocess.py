"""Seed 004 pre-processing: resampling that keeps the increments, wavelet denoising, and
the delay compensation (no lag against truth), measured on simulated severe-sea data."""
import numpy as np
import pytest

from sins_align_ros.align.inputs.preprocess import Preprocessor, preprocess, upsample_increments
from sins_align_ros.sim.presets import scenario
from sins_align_ros.sim.scenario import ScenarioStream
from tolerance import roundoff

pytest.importorskip('pywt')


def _sea(seed=3, duration=60.0, clean=False):
    sc = scenario('seed004_low', duration=duration)
    if clean:
        sc.imu = sc.imu.with_(gyro_arw_dpsh=0.0, accel_vrw_ug_rthz=0.0, gyro_bias_dph=0.0,
                              accel_bias_ug=0.0, gyro_markov_dph=0.0, accel_markov_ug=0.0)
    return ScenarioStream(sc, seed=seed).next_block(int(duration * 100)).imu


def test_resampling_keeps_every_increment_and_is_exact_for_a_cubic():
    t = np.linspace(0.0, 2.0, 201)
    rng = np.random.default_rng(0)
    inc = rng.standard_normal((201, 3))
    t_f, inc_f = upsample_increments(t, inc, 10)
    assert len(t_f) == 2000 and t_f[9] == pytest.approx(t[1])
    # 10 fine increments summed (10 additions) after the interpolation's weights (~10
    # operations) on increments of size |inc|
    np.testing.assert_allclose(inc_f.reshape(200, 10, 3).sum(axis=1), inc[1:], rtol=0,
                               atol=roundoff(20, np.abs(inc).max()))
    # a cubic cumulative signal (rate quadratic in t) is reproduced at the fine rate
    cum = lambda s: 0.3 * s ** 3 - s ** 2 + 2.0 * s          # noqa: E731
    inc_c = np.diff(cum(np.r_[-0.01, t]))[:, None]
    _, fine = upsample_increments(t, inc_c, 10)
    # the cubic's values (~2.4) differenced on both sides (cancellation: the operands'
    # size is the scale), through a 4-point cubic fit (weights up to ~10 in sum: cond)
    np.testing.assert_allclose(fine[:, 0], np.diff(cum(np.r_[0.0, t_f])), rtol=0,
                               atol=roundoff(40, np.abs(cum(t)).max(), 10.0))


def test_streaming_in_any_chunks_equals_the_batch_and_keeps_the_stamps():
    imu = _sea(duration=20.0)
    t_b, th_b, v_b = preprocess(imu.t, imu.dtheta, imu.dv)
    np.testing.assert_array_equal(t_b, imu.t)               # every sample, its own stamp
    p = Preprocessor()
    rng = np.random.default_rng(1)
    outs, i, lag = [], 0, 0
    while i < len(imu.t):
        k = int(rng.integers(1, 40))
        o = p.push(imu.t[i:i + k], imu.dtheta[i:i + k], imu.dv[i:i + k])
        i += k
        outs.append(o)
        done = sum(len(x[0]) for x in outs)
        lag = max(lag, i - done)
    outs.append(p.flush())
    np.testing.assert_array_equal(np.concatenate([o[0] for o in outs]), imu.t)
    # chunks against the batch: each output a weighted sum over the filter's window (at
    # most 2 delay + 1 taps, 2 operations each), on the inputs' size
    taps = 2 * p.delay_samples + 1
    np.testing.assert_allclose(np.vstack([o[1] for o in outs]), th_b, rtol=0,
                               atol=roundoff(2 * taps, np.abs(imu.dtheta).max()))
    np.testing.assert_allclose(np.vstack([o[2] for o in outs]), v_b, rtol=0,
                               atol=roundoff(2 * taps, np.abs(imu.dv).max()))
    assert lag <= p.delay_samples + 40


def test_denoising_reduces_the_noise_without_lag_and_keeps_the_motion():
    """Against the noise-free truth of the same motion: the per-sample gyro error falls
    by more than a third, the accelerometer's too; the cross-correlation with the truth
    peaks at zero lag (the delay is compensated); the integral (the motion) is kept."""
    noisy, truth = _sea(), _sea(clean=True)
    _, th, dv = preprocess(noisy.t, noisy.dtheta, noisy.dv)
    s = slice(100, -100)
    bias_th = (noisy.dtheta[s] - truth.dtheta[s]).mean(axis=0)
    bias_v = (noisy.dv[s] - truth.dv[s]).mean(axis=0)
    for raw, out, tru, b, gain in ((noisy.dtheta, th, truth.dtheta, bias_th, 0.65),
                                   (noisy.dv, dv, truth.dv, bias_v, 0.9)):
        e_raw = np.sqrt(np.mean((raw[s] - tru[s] - b) ** 2))
        e_out = np.sqrt(np.mean((out[s] - tru[s] - b) ** 2))
        assert e_out < gain * e_raw, (e_out, e_raw)
        x = out[s, 0] - out[s, 0].mean()
        y = tru[s, 0] - tru[s, 0].mean()
        lags = np.arange(-20, 21)
        cc = [np.dot(np.roll(x, k), y) for k in lags]
        assert lags[int(np.argmax(cc))] == 0
        # the motion's integral over the run is unchanged (to the noise's own share)
        np.testing.assert_allclose(out[s].sum(axis=0), raw[s].sum(axis=0),
                                   atol=20 * e_raw)


def test_pipeline_with_preprocessing_outputs_every_sample_at_its_stamp():
    from sins_align_ros.align.pipeline import AlignmentPipeline
    from sins_align_ros.eval.feed import feed_arrays
    from sins_align_ros.sim.presets import alignment_params
    from sins_align_ros.units import DEG
    sc = scenario('seed004_high', duration=150.0)
    b = ScenarioStream(sc, seed=5).next_block(15000)
    res = {}
    for pre in (False, True):
        p = AlignmentPipeline(alignment_params(sc, 'vbckf', preprocess=pre))
        p.start_clock(0.0)
        out = feed_arrays(p, b.imu, b.gnss)
        np.testing.assert_array_equal(out.t, b.imu.t)
        res[pre] = out.euler[-1]
    d = ((res[True] - res[False] + np.pi) % (2 * np.pi) - np.pi) / DEG
    assert np.all(np.abs(d[:2]) < 0.05) and abs(d[2]) < 1.0, d   # the same alignment

"""IMU pre-processing of seed 004 sec. 4 (its Fig. 1): resampling, denoising, delay.

Resampling to a higher rate with the increments preserved, wavelet threshold
denoising, and compensation of the delay that introduces.

* Resampling: the cumulative increments (angle, velocity) at the sample stamps are
  interpolated by a cubic spline and differenced at ``factor`` times the rate, so the
  fine increments of every original interval add up to its increment exactly.
* Denoising: the fine rates (increment / interval) of a window are decomposed with
  PyWavelets, every detail level is soft-thresholded at its own universal threshold
  ``sigma_j sqrt(2 ln n)`` (``sigma_j`` = median absolute detail / 0.6745: the
  spline leaves little noise in the finest levels, so one noise estimate for all
  levels would threshold nothing), and the window is reconstructed; the denoised
  fine increments of each original interval are summed back to the input rate, so
  the alignment runs at the IMU rate. The sea's motion has periods above 1 s (seed
  004), far below the levels thresholded.
* Delay: the window is centred on the samples it outputs (zero-phase), so the output
  lags the input by half a window plus a hop; each output sample keeps the stamp of the
  input it came from, i.e. the delay is compensated (no lag against truth), at the cost
  of latency. GNSS epochs are queued by stamp downstream, so they meet the right sample.

:class:`Preprocessor` streams (push samples, get the finished ones); :func:`preprocess`
runs it over whole arrays.
"""
import math

import numpy as np


def upsample_increments(t, inc, factor):
    """Resample increments to ``factor`` times the rate, each interval's sum preserved.

    ``t`` (N,): stamps; ``inc`` (N, k): increments over ``(t[i-1], t[i]]`` (the first
    row is not used: its interval starts before ``t[0]``). Returns ``(t_f, inc_f)``
    with ``factor * (N - 1)`` fine samples covering ``(t[0], t[-1]]``.
    """
    t = np.asarray(t, dtype=float)
    inc = np.asarray(inc, dtype=float)
    cum = np.vstack([np.zeros((1, inc.shape[1])), np.cumsum(inc[1:], axis=0)])
    frac = np.arange(1, factor + 1) / factor
    t_f = (t[:-1, None] + np.diff(t)[:, None] * frac[None, :]).ravel()
    # imported here: scipy.interpolate is 0.1 s of every replay's start-up, and only an
    # upsampling run needs it
    from scipy.interpolate import CubicSpline
    c_f = CubicSpline(t, cum, axis=0)(t_f)
    c_f[factor - 1::factor] = cum[1:]                 # exact at the knots (no round-off)
    return t_f, np.diff(np.vstack([cum[:1], c_f]), axis=0)


def wavelet_denoise(x, wavelet='sym8', level=None):
    """Soft-threshold every detail level of ``x`` (n, k) at its universal threshold.

    Returns the reconstruction (n, k). ``level`` None: as deep as the window allows.
    """
    import pywt
    x = np.asarray(x, dtype=float)
    n = x.shape[0]
    w = pywt.Wavelet(wavelet)
    lev = pywt.dwt_max_level(n, w.dec_len) if level is None else int(level)
    coeffs = pywt.wavedec(x, w, level=lev, axis=0, mode='symmetric')
    gain = math.sqrt(2.0 * math.log(n))
    out = [coeffs[0]]
    for d in coeffs[1:]:
        sigma = np.median(np.abs(d), axis=0) / 0.6745
        out.append(pywt.threshold(d, sigma[None, :] * gain, mode='soft'))
    return pywt.waverec(out, w, axis=0, mode='symmetric')[:n]


class Preprocessor:
    """Streaming resample + denoise + delay compensation (module docstring).

    Parameters
    ----------
    factor : int
        Resampling factor (seed 004: 10).
    window : int
        Input samples per denoising window (even).
    hop : int
        Input samples output per window (the window moves by ``hop``).
    wavelet : str
        PyWavelets name.
    """

    def __init__(self, factor=10, window=64, hop=16, wavelet='sym8'):
        if hop > window // 2 or window % 2:
            raise ValueError('window must be even and hop at most half of it')
        self.factor, self.window, self.hop, self.wavelet = int(factor), int(window), \
            int(hop), wavelet
        self._t = []
        self._inc = []
        self._start = None          # index (in the buffer) of the next sample to output

    @property
    def delay_samples(self):
        """Largest number of input samples an output waits for."""
        return self.window // 2 + self.hop

    def push(self, t, dtheta, dv):
        """Add samples (stamps (N,), increments (N, 3) each); return the finished ones.

        Returns ``(t, dtheta, dv)`` of the samples whose window is complete, with
        their own stamps (possibly empty arrays).
        """
        self._t.extend(np.atleast_1d(np.asarray(t, dtype=float)).tolist())
        self._inc.extend(np.hstack([np.atleast_2d(dtheta), np.atleast_2d(dv)]).tolist())
        outs = []
        half = self.window // 2
        if self._start is None and self._t:
            # the first sample's interval starts before its stamp: passed on unchanged
            outs.append((np.array(self._t[:1]), np.array(self._inc[:1])))
            self._start = 1
        while len(self._t) - self._start >= half + self.hop:
            outs.append(self._emit(self.hop, self._start + self.hop + half))
            drop = max(0, self._start - half - 1)
            if drop:
                del self._t[:drop]
                del self._inc[:drop]
                self._start -= drop
        return self._stack(outs)

    def flush(self):
        """Output the samples still waiting (their windows reach past the data's end)."""
        outs = []
        while self._start is not None and self._start < len(self._t):
            outs.append(self._emit(min(self.hop, len(self._t) - self._start), len(self._t)))
        return self._stack(outs)

    def _emit(self, k, hi):
        """Output the next ``k`` samples, denoised in the window ending before buffer ``hi``."""
        lo = max(0, self._start - self.window // 2)
        seg = self._run(lo, hi)
        a = self._start - lo
        out = (np.array(self._t[self._start:self._start + k]), seg[a - 1:a - 1 + k])
        self._start += k
        return out

    def _run(self, lo, hi):
        """Denoised increments of buffer samples lo+1..hi-1, at the input rate, (hi-lo-1, 6)."""
        t = np.array(self._t[lo:hi])
        inc = np.array(self._inc[lo:hi])
        t_f, inc_f = upsample_increments(t, inc, self.factor)
        dt_f = np.diff(np.concatenate([[t[0]], t_f]))
        rate = wavelet_denoise(inc_f / dt_f[:, None], self.wavelet) * dt_f[:, None]
        return rate.reshape(len(t) - 1, self.factor, -1).sum(axis=1)

    @staticmethod
    def _stack(outs):
        if not outs:
            return np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))
        t = np.concatenate([o[0] for o in outs])
        inc = np.vstack([o[1] for o in outs])
        return t, inc[:, :3], inc[:, 3:]


def preprocess(t, dtheta, dv, **kw):
    """Run a :class:`Preprocessor` over whole arrays; returns ``(t, dtheta, dv)``.

    The first sample (whose interval starts before ``t[0]``) is returned unchanged.
    """
    p = Preprocessor(**kw)
    t0, th0, v0 = p.push(t, dtheta, dv)
    t1, th1, v1 = p.flush()
    return np.concatenate([t0, t1]), np.vstack([th0, th1]), np.vstack([v0, v1])

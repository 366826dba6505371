"""White-noise estimates from the samples of the coarse window, for :mod:`.self_check`.

Pure functions of the samples: the white-noise density where the 1-s and the sample-level
scatter agree (:func:`white_density`), an upper bound from the third differences, which
smooth motion hardly enters (:func:`difference_density`), a robust (median) noise 1-sigma
of GNSS fixes (:func:`robust_difference_sigma`), and whether the gyro and accelerometer
differences move together (:func:`coherent`: the base's disturbance, not sensor noise).
What the estimates mean for the sensor model: :mod:`.grade_check` (IMU) and
:mod:`.gnss_noise_check` (GNSS).
"""
import math

import numpy as np

#: a noise estimate widens the configured density when it is this many times larger
NOISE_RATIO = 2.0
#: white noise: the sample-level and the 1-s densities agree within this factor
WHITE_AGREE = 2.0
#: gyro-accelerometer correlation of sample differences, in 1/sqrt(N), that means motion
COHERENCE_SIGMAS = 4.5
#: order of the differences of :func:`difference_density`
DIFF_ORDER = 3


def white_density(x, dt):
    """White-noise density estimate from samples ``x`` (N, 3) at interval ``dt`` (s).

    The geometric mean of ``sqrt(AVAR(1 s) * 1 s)`` and the sample-difference density
    (root means over the axes; the unit of ``x`` times sqrt(s)) where they agree within
    :data:`WHITE_AGREE`, else NaN (also with fewer than 4 s of data).
    """
    m = max(1, int(round(1.0 / dt)))
    k = len(x) // m
    if k < 4:
        return float('nan')
    x1 = x[:k * m].reshape(k, m, 3).mean(axis=1)
    allan = math.sqrt(0.5 * float(np.mean(np.diff(x1, axis=0) ** 2)) * m * dt)
    sample = math.sqrt(0.5 * float(np.mean(np.diff(x, axis=0) ** 2)) * dt)
    if not allan / WHITE_AGREE <= sample <= allan * WHITE_AGREE:
        return float('nan')
    return math.sqrt(allan * sample)


def coherent(dth, dvv, order=DIFF_ORDER):
    """Tell whether the gyro and accelerometer differences are correlated (base motion).

    Sensor noises are independent, so the correlation of each gyro axis's
    ``order``-th differences with each accelerometer axis's stays within a few
    ``1/sqrt(N)``; a physical disturbance turns and accelerates the IMU together.
    Threshold :data:`COHERENCE_SIGMAS` ``/ sqrt(N)`` (the disturbed laser-gyro recording
    of ../shared/data: 0.08 at N = 6000, simulated white noise 0.02).
    """
    a = np.diff(dth, n=order, axis=0)
    b = np.diff(dvv, n=order, axis=0)
    sa, sb = a.std(axis=0), b.std(axis=0)
    if len(a) < 100 or np.any(sa <= 0.0) or np.any(sb <= 0.0):
        return False
    r = ((a - a.mean(axis=0)) / sa).T @ ((b - b.mean(axis=0)) / sb) / len(a)
    return bool(np.max(np.abs(r)) > COHERENCE_SIGMAS / math.sqrt(len(a)))


def difference_density(x, dt, order=DIFF_ORDER):
    """White-noise density upper bound from ``order``-th differences of ``x`` (N, 3).

    For white samples of variance s^2 the ``k``-th difference has variance
    ``C(2k, k) s^2`` and the density is ``s sqrt(dt)``; smooth motion hardly enters a
    third difference at IMU rates. Root mean over the axes; NaN with fewer than 100
    samples.
    """
    if len(x) < 100:
        return float('nan')
    d = np.diff(x, n=order, axis=0)
    return math.sqrt(float(np.mean(d * d)) / math.comb(2 * order, order) * dt)


def robust_difference_sigma(x, order=DIFF_ORDER):
    """Noise 1-sigma of the columns of ``x`` (N, k) from the median of ``order``-th differences.

    For white noise the ``k``-th difference is normal with variance ``C(2k, k) sigma^2``
    and its absolute median is 0.6745 of its sigma. Root mean over the columns; NaN
    with fewer than 10 rows.
    """
    x = np.asarray(x, dtype=float)
    if len(x) < 10:
        return float('nan')
    d = np.diff(x, n=order, axis=0)
    s = np.median(np.abs(d), axis=0) / (0.6745 * math.sqrt(math.comb(2 * order, order)))
    return float(np.sqrt(np.mean(s * s)))

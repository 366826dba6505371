"""The gyro's angle random walk over seconds, told from a vibrating mount's bounded jitter.

On a moving base the self-check takes the gyro white noise from the third differences
of the rate samples (:func:`~.noise_estimates.difference_density`): motion is smooth at the
sample level, so what is left is the sensor's noise, plus vibration and quantization.
For the grade that is the right figure (a vibrating chassis does carry a cheap IMU), but
the filters take ``gyro_arw_dpsh`` as a random walk of the attitude, and a mount's
vibration is bounded in angle: it does not accumulate. A skid-steer robot on asphalt
(``ROBOT_VIBRATION`` of the simulator: 3 deg/s per sample, correlated over 0.05 s, a
bounded angle of about 6') shows 37 deg/sqrt(h) at the sample level from a gyro of 0.42
or 3; taken whole as random walk it held the robot's tilt 1-sigma at 38' with a receiver
measuring velocity and 125' with positions only, 2-6 times the error.

The random walk shows over seconds. Over a span of ``T`` seconds the integrated rate
(per body axis), less its least-squares cubic in time (smooth motion: a turn, a
braking), leaves

    ``E[r^2] = k(T) q^2 + (1 - 4/n) s^2 + motion not cubic``

with ``q`` the random walk (rad/sqrt(s)), ``s`` the bounded jitter's angle and ``k(T)``
the mean residual variance of a unit Brownian motion on the span's ``n`` sample times
after the same cubic fit (computed exactly, :func:`walk_factor`; about 0.033 T). The
jitter's share falls as ``1/T``, the motion's grows: each span gives an upper bound
``sqrt(mean r^2 / k(T))`` of ``q``, and the smallest over the spans of
:data:`SPANS_S` that fit :data:`MIN_CHUNKS` times in the data is taken, per axis; the
triad's figure is the median of its three axes (a turning vehicle's vertical axis sees
its turns' starts and ends, which are not cubic). It replaces the sample-level noise only
where it is less than half of it (:func:`walk_or_noise`): where the two agree the noise
is white and the sample-level figure stands. For white noise alone every span
gives ``q`` (the simulated cars: 2.8-3.2 deg/sqrt(h) from a 3.0 gyro); the robot's
vibrating triads give 8.5-9.4 over a 60-s window, 16-17.6 over the motion check's 20 s
(the simulation's 3.0 or 0.42 plus the jitter still left over the longest span that
fits): an upper bound, so never narrower than the data support.

Not from a seed (their IMUs are still or on ships, where the two figures agree); the
idea is the Allan variance's (IEEE Std 952: angle random walk read where the Allan
deviation falls as ``1/sqrt(T)``), with a cubic taken off each span for the motion.
"""

import numpy as np

#: spans (s) over which the random walk is bounded
SPANS_S = (2.0, 4.0, 8.0, 16.0)
#: a span counts only when the data hold at least this many of them
MIN_CHUNKS = 3
#: degree of the polynomial taken off each span (the motion)
DEGREE = 3
#: most sample times the walk factor is computed on (it converges long before)
FACTOR_POINTS = 400
#: the walk bound replaces the sample-level noise only below it by this factor (where the
#: two agree, as for every vibration-free IMU, the sample-level figure is kept as it was)
BOUNDED_RATIO = 2.0


def walk_factor(n, T, degree=DEGREE):
    """Mean residual variance of a unit Brownian motion over ``n`` samples spanning ``T`` s.

    The samples at ``T (1..n) / n``; the residual after the least-squares polynomial of
    ``degree``: ``trace(M S M^T) / n`` with ``S_ij = min(t_i, t_j)`` and ``M = I - X X^+``.
    Computed on at most :data:`FACTOR_POINTS` points (a finer grid changes it by less than
    a percent). Returns s (the variance per unit ``q^2``).
    """
    m = int(min(n, FACTOR_POINTS))
    t = T * np.arange(1, m + 1) / m
    X = np.vander(t / T, degree + 1)
    M = np.eye(m) - X @ np.linalg.pinv(X)
    S = np.minimum.outer(t, t)
    return float(np.trace(M @ S @ M.T)) / m


def walk_density(dtheta, dts, spans=SPANS_S):
    """Upper bound of the gyro's angle random walk (rad/sqrt(s)); module docstring.

    ``dtheta`` (N, 3) angle increments (rad), ``dts`` (N,) their intervals (s, nearly
    even). NaN when no span fits :data:`MIN_CHUNKS` times.
    """
    dtheta = np.asarray(dtheta, dtype=float)
    dt = float(np.mean(dts))
    theta = np.cumsum(dtheta, axis=0)
    best = np.full(3, np.inf)
    for T in spans:
        n = int(round(T / dt))
        m = len(theta) // n if n > 0 else 0
        if n < 4 * (DEGREE + 1) or m < MIN_CHUNKS:
            continue
        chunks = theta[:m * n].reshape(m, n, 3)
        X = np.vander(np.arange(1, n + 1) / n, DEGREE + 1)
        coef = np.linalg.pinv(X) @ chunks                   # (m, degree + 1, 3)
        r = chunks - X @ coef
        ms = np.mean(r * r, axis=(0, 1))
        best = np.minimum(best, np.sqrt(ms / walk_factor(n, n * dt)))
    if not np.all(np.isfinite(best)):
        return float('nan')
    return float(np.median(best))


def walk_or_noise(walk, noise):
    """Return the gyro random walk a filter should take (rad/sqrt(s)).

    ``walk`` the bound of :func:`walk_density` (NaN or None: none), ``noise`` the
    sample-level white noise (:func:`~.noise_estimates.difference_density`): the walk where it
    is below the noise by :data:`BOUNDED_RATIO` (the rest is bounded: vibration), else the
    noise.
    """
    if walk is None or not np.isfinite(walk) or not walk < noise / BOUNDED_RATIO:
        return noise
    return float(walk)

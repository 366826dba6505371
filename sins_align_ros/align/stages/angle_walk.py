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

The jitter's share of the longest span is still the bound's largest part (3-5 times the
walk on the robot at 16 s). Over two spans it cancels: the jitter is the same in both, the
walk grows as ``k(T)``, so ``(mean r_L^2 - a mean r_S^2) / (k_L - a k_S)`` (``a`` the ratio of
the two ``1 - 4/n``) estimates ``q^2`` without it, and motion that is not cubic (larger over
the longer span) only raises it. The chunks are independent, so their spread gives the
estimate's standard error; the **difference bound** is the estimate plus
:data:`DIFFERENCE_Z` of them, taken where the longer span has at least
:data:`DIFFERENCE_CHUNKS` chunks, and the smaller of the two bounds stands per axis. The
fine stage's motion check sums the chunks over all its windows (:class:`WalkBound`), so
the bound tightens as the vehicle drives: on the simulator's vibrating robot triads
(gyros of 0.42 and 3.0 deg/sqrt(h)) about 12.5 from one 20-s window, 6-7 from 60 s and
3.7-4.8 from 400 s, against 16, 8.5-9 and 8.5-9 from the single-span bound (40 seeds
each; never below the truth).

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
#: a longer span gives a difference bound only with at least this many chunks (the spread
#: of its chunks stands for the estimate's: too few and the spread is itself a guess)
DIFFERENCE_CHUNKS = 5
#: the difference bound is its estimate plus this many standard errors
DIFFERENCE_Z = 2.0
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


class WalkBound:
    """The random-walk bound of :func:`walk_density` over data that come in windows.

    Per span, the mean squares of the chunks' residuals (per axis) are summed over every
    window :meth:`add` was given (chunks do not cross windows), so the bound tightens as the
    data grow: the jitter's share of the longest span falls with more chunks, and the
    difference bound (module docstring) gets the chunks it needs. ``spans`` (s).
    """

    def __init__(self, spans=SPANS_S):
        self.spans = tuple(spans)
        #: span (s) -> [samples per chunk n, chunks m, sum of r^2 (3,), sum of r^4 (3,)]
        self.stats = {}

    def add(self, dtheta, dt):
        """Take one window: angle increments ``dtheta`` (N, 3, rad), mean interval ``dt`` (s)."""
        theta = np.cumsum(np.asarray(dtheta, dtype=float), axis=0)
        for T in self.spans:
            n = int(round(T / dt))
            m = len(theta) // n if n > 0 else 0
            if n < 4 * (DEGREE + 1) or m < 1:
                continue
            chunks = theta[:m * n].reshape(m, n, 3)
            X = np.vander(np.arange(1, n + 1) / n, DEGREE + 1)
            r = chunks - X @ (np.linalg.pinv(X) @ chunks)
            r2 = np.mean(r * r, axis=1)                     # (m, 3)
            s = self.stats.get(T)
            if s is None or s[0] != n:                      # a new rate starts the span anew
                s = self.stats[T] = [n, 0, np.zeros(3), np.zeros(3)]
            s[1] += m
            s[2] += r2.sum(axis=0)
            s[3] += (r2 * r2).sum(axis=0)
        return self

    def bound(self, dt):
        """Return the walk's upper limit, rad/sqrt(s); NaN: no span has :data:`MIN_CHUNKS` chunks.

        ``dt`` the mean sample interval (s). Per axis the smallest of each span's
        ``sqrt(mean r^2 / k(T))`` and of the difference bounds; the median of the axes.
        """
        got = [(n, m, s2 / m, (s4 / m - (s2 / m) ** 2) * m / (m - 1) / m,
                walk_factor(n, n * dt))
               for T, (n, m, s2, s4) in sorted(self.stats.items()) if m >= MIN_CHUNKS]
        if not got:
            return float('nan')
        best = np.full(3, np.inf)
        for n, m, ms, var, k in got:
            best = np.minimum(best, np.sqrt(ms / k))
        n1, m1, ms1, var1, k1 = got[0]
        for n, m, ms, var, k in got[1:]:
            if m < DIFFERENCE_CHUNKS:
                continue
            a = (1.0 - (DEGREE + 1) / n) / (1.0 - (DEGREE + 1) / n1)
            upper = ms - a * ms1 + DIFFERENCE_Z * np.sqrt(np.maximum(var + a * a * var1, 0.0))
            best = np.minimum(best, np.sqrt(np.maximum(upper, 0.0) / (k - a * k1)))
        return float(np.median(best))


def walk_density(dtheta, dts, spans=SPANS_S):
    """Upper bound of the gyro's angle random walk (rad/sqrt(s)); module docstring.

    ``dtheta`` (N, 3) angle increments (rad), ``dts`` (N,) their intervals (s, nearly
    even). NaN when no span fits :data:`MIN_CHUNKS` times.
    """
    dt = float(np.mean(dts))
    return WalkBound(spans).add(dtheta, dt).bound(dt)


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

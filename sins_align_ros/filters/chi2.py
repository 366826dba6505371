"""Chi-square quantiles for the innovation gates and consistency tests, without scipy.

The quantile ``x`` of ``probability`` p for ``dof`` degrees of freedom solves
``P(dof/2, x/2) = p`` (for p < 1/2) or ``Q(dof/2, x/2) = 1 - p`` with ``P``, ``Q`` the
regularised lower and upper incomplete gamma functions, evaluated by the power series
of ``P`` (``x < a + 1``) or the continued fraction of ``Q`` (otherwise); the equation
is solved by Newton's method from the Wilson-Hilferty approximation, kept inside a
bracket that bisection narrows when a Newton step leaves it. The result agrees with
``scipy.special.chdtri`` to 1e-12 relative for p >= 1/2 (test_filters); for small p
it is the more accurate of the two (chdtri is given 1 - p, rounded).

Written here because importing ``scipy.special`` (and with it ``scipy.linalg``'s
array-API layer) cost 0.15-0.2 s of every replay and node start, for a handful of
numbers per run.
"""
import math
from functools import lru_cache

_EPS = 1e-15
_TINY = 1e-300


def _lower_series(a, x):
    """Regularised lower incomplete gamma ``P(a, x)`` by its series (``x < a + 1``)."""
    term = total = 1.0 / a
    n = a
    for _ in range(10_000):
        n += 1.0
        term *= x / n
        total += term
        if abs(term) < abs(total) * _EPS:
            break
    return total * math.exp(-x + a * math.log(x) - math.lgamma(a))


def _upper_fraction(a, x):
    """Regularised upper incomplete gamma ``Q(a, x)`` by its continued fraction (``x >= a + 1``).

    Modified Lentz evaluation of ``1 / (x + 1 - a - 1 (1 - a) / (x + 3 - a - ...))``.
    """
    b = x + 1.0 - a
    c = 1.0 / _TINY
    d = 1.0 / b
    h = d
    for i in range(1, 10_000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = _TINY if abs(d) < _TINY else d
        c = b + an / c
        c = _TINY if abs(c) < _TINY else c
        d = 1.0 / d
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < _EPS:
            break
    return h * math.exp(-x + a * math.log(x) - math.lgamma(a))


def gamma_p(a, x):
    """Regularised lower incomplete gamma function ``P(a, x)`` for ``a > 0``, ``x >= 0``."""
    if x <= 0.0:
        return 0.0
    if x < a + 1.0:
        return _lower_series(a, x)
    return 1.0 - _upper_fraction(a, x)


def gamma_q(a, x):
    """Regularised upper incomplete gamma function ``Q(a, x) = 1 - P(a, x)``."""
    if x <= 0.0:
        return 1.0
    if x < a + 1.0:
        return 1.0 - _lower_series(a, x)
    return _upper_fraction(a, x)


@lru_cache(maxsize=None)
def chi2_quantile(probability, dof):
    """Chi-square quantile of ``probability`` (0 < p < 1) for ``dof`` > 0 (cached).

    The same number as ``scipy.special.chdtri(dof, 1 - probability)`` (or
    ``scipy.stats.chi2.ppf``) to about 1e-13 relative.
    """
    if not 0.0 < probability < 1.0 or dof <= 0:
        raise ValueError(f'chi2_quantile needs 0 < probability < 1 and dof > 0, '
                         f'got {probability}, {dof}')
    a, q = 0.5 * dof, 1.0 - probability
    # Wilson-Hilferty start: x / dof ~ (1 - 2/(9 dof) + z sqrt(2/(9 dof)))^3
    z = _normal_quantile(probability)
    v = 2.0 / (9.0 * dof)
    x = max(dof * (1.0 - v + z * math.sqrt(v)) ** 3, 1e-8)
    lo, hi = 0.0, math.inf
    for _ in range(200):
        # the smaller tail is computed directly, never as 1 minus a number near 1
        g = gamma_p(a, 0.5 * x) - probability if probability < 0.5 else q - gamma_q(a, 0.5 * x)
        if g < 0.0:                                 # g increases with x
            lo = x
        else:
            hi = x
        density = math.exp((a - 1.0) * math.log(0.5 * x) - 0.5 * x - math.lgamma(a)) * 0.5
        step = -g / density if density > 0.0 else math.inf
        x_new = x + step
        if not lo < x_new < hi:                     # Newton left the bracket: bisect
            x_new = 0.5 * (lo + hi) if math.isfinite(hi) else 2.0 * x
        if abs(x_new - x) <= 1e-14 * x:
            return x_new
        x = x_new
    return x


def _normal_quantile(p):
    """Return the standard normal quantile to about 5e-4 (Abramowitz-Stegun 26.2.23)."""
    t = math.sqrt(-2.0 * math.log(min(p, 1.0 - p)))
    z = t - (2.515517 + 0.802853 * t + 0.010328 * t * t) / (
        1.0 + 1.432788 * t + 0.189269 * t * t + 0.001308 * t ** 3)
    return z if p >= 0.5 else -z

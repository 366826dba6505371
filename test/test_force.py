"""Which horizontal specific force a GNSS-aided error model uses (align/engines/force.py).

:func:`model_force` against its closed forms: the horizontal force is kept beyond
``FORCE_SIGNIFICANCE`` sigma of what the filter's tilt and accelerometer-bias variances put
on it, and a dropped force's velocity-rate variance is the heading error's through it,
never narrower than the exact variance of a Gaussian heading error rotating the force.
"""
import math

import numpy as np
import pytest

from sins_align_ros.align.engines.force import FORCE_SIGNIFICANCE, model_force
from tolerance import assert_roundoff

G = 9.80665
#: a tactical IMU's tilt sigma after coarse alignment and a MEMS accelerometer's bias sigma
VAR_TILT, VAR_BIAS = (0.5e-3) ** 2, (3e-3) ** 2
VAR_HEADING = math.radians(5.0) ** 2


def _sigma(var_tilt, var_bias):
    """The 1-sigma (m/s^2) the filter's own errors put on the computed horizontal force."""
    return math.sqrt(G * G * var_tilt + var_bias)


@pytest.mark.parametrize('direction', [(1.0, 0.0), (0.6, 0.8), (-0.28, 0.96)])
def test_the_horizontal_force_is_kept_only_beyond_the_significance_threshold(direction):
    limit = FORCE_SIGNIFICANCE * _sigma(VAR_TILT, VAR_BIAS)      # 0.0287 m/s^2
    u = np.array(direction)
    for k, keep in ((1.0 - 1e-6, False), (1.0 + 1e-6, True), (0.5, False), (3.0, True)):
        f_n = np.r_[k * limit * u, G]
        f, acc_var = model_force(f_n, VAR_TILT, VAR_HEADING, VAR_BIAS, G)
        if keep:
            # the force as given, nothing dropped
            assert np.array_equal(f, f_n) and acc_var == 0.0
        else:
            # the vertical alone; the heading error's variance through |f_h|^2 (3 ops)
            assert np.array_equal(f, [0.0, 0.0, G])
            h2 = (k * limit) ** 2
            assert_roundoff(acc_var, VAR_HEADING * h2, 8, what='dropped force variance')


def test_the_accelerometer_bias_variance_raises_the_threshold():
    # between the threshold of the tilt alone (5 g sigma_tilt = 0.0245) and with the bias
    f_h = 0.027
    assert FORCE_SIGNIFICANCE * _sigma(VAR_TILT, 0.0) < f_h < \
        FORCE_SIGNIFICANCE * _sigma(VAR_TILT, VAR_BIAS)
    f_n = np.array([0.0, f_h, G])
    f, acc = model_force(f_n, VAR_TILT, VAR_HEADING, 0.0, G)           # no bias state
    assert np.array_equal(f, f_n) and acc == 0.0
    f, acc = model_force(f_n, VAR_TILT, VAR_HEADING, VAR_BIAS, G)      # with one
    assert np.array_equal(f, [0.0, 0.0, G]) and acc > 0.0


def test_a_still_base_tilt_error_is_dropped_and_a_turn_is_kept():
    # simulator truth of a still base: a tilt error phi about north puts g sin(phi) on the
    # computed east force; with phi at the filter's 1-sigma that is 1/5 of the threshold
    phi = math.sqrt(VAR_TILT)
    f_still = np.array([G * math.sin(phi), 0.0, G * math.cos(phi)])
    f, acc = model_force(f_still, VAR_TILT, VAR_HEADING, 0.0, G)
    assert np.array_equal(f, [0.0, 0.0, f_still[2]])
    assert_roundoff(acc, VAR_HEADING * f_still[0] ** 2, 8)
    # a car turning at 10 deg/s at 5 m/s: centripetal force v w = 0.87 m/s^2 to the north
    a_c = 5.0 * math.radians(10.0)
    f_turn = np.array([0.0, a_c, G]) + f_still * [1.0, 0.0, 0.0]
    f, acc = model_force(f_turn, VAR_TILT, VAR_HEADING, VAR_BIAS, G)
    assert np.array_equal(f, f_turn) and acc == 0.0


def test_the_dropped_force_variance_bounds_a_rotated_force_exactly_and_by_monte_carlo():
    # velocity-rate error of a heading error psi ~ N(0, s^2) through f_h: (C(psi) - I) f_h.
    # Exactly: E sin^2 = (1 - e^(-2 s^2)) / 2, E cos = e^(-s^2 / 2), E cos^2 = (1 + e^(-2 s^2))
    # / 2, so Var e_E + Var e_N = |f_h|^2 (1 - e^(-s^2)) <= s^2 |f_h|^2 = acc_var, with
    # s^2 |f_h|^2 - exact <= s^4 |f_h|^2 / 2 (the series of 1 - e^-x).
    s2 = math.radians(20.0) ** 2
    f_h = np.array([0.3, -0.4])           # below 5 sigma of a 5 deg tilt: dropped
    var_tilt = math.radians(5.0) ** 2
    f, acc = model_force(np.r_[f_h, G], var_tilt, s2, 0.0, G)
    assert f[0] == 0.0 and f[1] == 0.0
    h2 = float(f_h @ f_h)
    exact = h2 * (1.0 - math.exp(-s2))
    assert exact <= acc <= exact + 0.5 * s2 * s2 * h2
    # Monte Carlo check of the exact form (seeded; relative sigma of a variance sqrt(2/N))
    n = 200_000
    psi = np.random.default_rng(45).normal(0.0, math.sqrt(s2), n)
    c, s = np.cos(psi), np.sin(psi)
    e = np.column_stack([(c - 1.0) * f_h[0] - s * f_h[1], s * f_h[0] + (c - 1.0) * f_h[1]])
    total = float(np.var(e[:, 0]) + np.var(e[:, 1]))
    assert total == pytest.approx(exact, rel=6.0 * math.sqrt(2.0 / n))
    # per axis the model is never narrower than the error it stands for
    assert np.all(np.var(e, axis=0) <= acc)

"""Overlapping Allan deviation and its closed forms for the simulated error terms.

IEEE Std 952-1997 (Annex C) definitions: for rate samples ``y`` at interval
``tau0`` the overlapping Allan variance at ``tau = m tau0`` is
``AVAR = 1/(2 tau^2 (N - 2m)) sum (theta_{k+2m} - 2 theta_{k+m} + theta_k)^2``
with ``theta`` the cumulative sum ``tau0 * cumsum(y)``.
"""
import numpy as np


def allan_deviation(y, tau0, m):
    """Overlapping Allan deviation of a rate series.

    Parameters
    ----------
    y : ndarray (N,) or (N, K)
        Rate samples (e.g. rad/s or m/s^2), one column per axis.
    tau0 : float
        Sample interval, s.
    m : array_like of int
        Cluster sizes; ``tau = m * tau0``.

    Returns
    -------
    tau : ndarray (M,)
    adev : ndarray (M,) or (M, K)
    """
    y = np.asarray(y, dtype=float)
    theta = np.concatenate([np.zeros((1,) + y.shape[1:]), np.cumsum(y, axis=0) * tau0])
    n = len(theta)
    m = np.asarray(m, dtype=int)
    out = []
    for mi in m:
        if 2 * mi >= n:
            raise ValueError(f'cluster size {mi} too large for {n - 1} samples')
        d = theta[2 * mi:] - 2.0 * theta[mi:n - mi] + theta[:n - 2 * mi]
        tau = mi * tau0
        out.append(np.sqrt(np.mean(d * d, axis=0) / (2.0 * tau * tau)))
    return m * tau0, np.array(out)


def adev_white(N, tau):
    """Allan deviation of white rate noise with density ``N`` (units/sqrt(Hz)): ``N/sqrt(tau)``."""
    return N / np.sqrt(tau)


def adev_markov(sigma, tc, tau):
    """Allan deviation of a first-order Gauss-Markov rate (sigma, correlation time ``tc``).

    ``AVAR = (sigma^2 tc / tau) * 2 * [1 - tc/(2 tau) (3 - 4 e^{-tau/tc} + e^{-2 tau/tc})]``
    (IEEE Std 952-1997, Table C.2 with ``q_c^2 = 2 sigma^2 / tc``).
    """
    tau = np.asarray(tau, dtype=float)
    x = tau / tc
    avar = (2.0 * sigma ** 2 * tc / tau) * (
        1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))
    return np.sqrt(avar)


def adev_quantization(lsb, tau):
    """Allan deviation of quantization of increments with step ``lsb``.

    IEEE Std 952-1997 C.2: ``sqrt(3) Q / tau`` with the quantization coefficient
    ``Q = lsb / sqrt(12)`` (uniform angle error), i.e. ``lsb / (2 tau)``. Holds
    when the signal dithers over several LSBs between samples.
    """
    return np.sqrt(3.0) * (lsb / np.sqrt(12.0)) / np.asarray(tau, dtype=float)

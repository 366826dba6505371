"""The variance curves a forecast is made of: closed forms and a linear filter's covariance run on.

The arithmetic of :mod:`.expectation`, on arrays only (no pipeline, no fine stage): the
gyro's variance growth (:func:`process_noise`), the heading limit of a gyro that sees Earth
rate (:func:`heading_limit_var`, seed 002 eq. 15), the scalar Riccati equation a filter's
variance trend is extrapolated with (:func:`riccati`), a linear filter's covariance run on
epoch after epoch with the model of its last epoch (:func:`covariance_shadow`), and the
pipeline's settle and ``aligned`` rules applied to a forecast curve
(:func:`first_aligned`).
"""
import math

import numpy as np

from ...models.stationary import sees_earth_rate, unobservable_variance
from ...units import DPH
from ..engines.force import ANGLE_UNKNOWN_VAR

#: the covariance shadow stops once the attitude variances changed less than this
#: fraction over :data:`SETTLED_S` s (the rest of the horizon holds the last value)
SETTLED = 1e-3
SETTLED_S = 60.0
#: the shadow steps one GNSS interval at a time over this much of its horizon, then
#: doubles its step (up to :data:`MOTION_MAX_LUMP` intervals) every as much again, s
MOTION_FINE_S = 120.0
MOTION_MAX_LUMP = 32


def process_noise(noise, cfg):
    """Variance growth (3,) rad^2/s of the misalignment with no measurement: the gyro's.

    Angle random walk, plus the bias drift a Gauss-Markov instability of sigma ``s`` and
    correlation time ``tau`` adds (``2 s^2 / tau``, as the filters' drift states).
    """
    drift = 2.0 * (cfg['gyro_bias_instability_dph'] * DPH) ** 2 / cfg['gyro_bias_tau_s']
    return np.full(3, noise.gyro_arw ** 2 + drift)


def heading_limit_var(lat, noise):
    """Heading variance (rad^2) a gyro that sees Earth rate cannot beat from it: seed 002 eq. 15.

    ``(eps / (W cos L))^2``; zero where the gyro cannot see Earth rate (its bias above half
    the horizontal Earth rate, as the self-check judges): then only motion or an external
    heading set the heading and there is no such limit.
    """
    if not sees_earth_rate(lat, noise):
        return 0.0
    return float(unobservable_variance(lat, noise)[2])


def riccati(P0, q, r, tau):
    """Solve ``dP/dt = q - r P^2`` from ``P0`` at times ``tau`` (M,); per axis, (M, 3).

    ``P0``, ``q``, ``r`` (3,); ``r <= 0`` (no information): ``P0 + q tau``.
    """
    tau = np.asarray(tau, dtype=float)[:, None]
    P0, q, r = (np.broadcast_to(np.asarray(a, dtype=float), (3,)) for a in (P0, q, r))
    out = P0 + q * tau
    for k in range(3):
        if r[k] <= 0.0:
            continue
        if q[k] <= 0.0:
            out[:, k] = P0[k] / (1.0 + r[k] * P0[k] * tau[:, 0])
            continue
        P_ss, rate = math.sqrt(q[k] / r[k]), 2.0 * math.sqrt(q[k] * r[k])
        c = (P0[k] - P_ss) / (P0[k] + P_ss)
        e = c * np.exp(-rate * tau[:, 0])
        out[:, k] = P_ss * (1.0 + e) / (1.0 - e)
    return out


def first_aligned(t, P, t_stage, converged, min_duration, max_tilt, max_heading):
    """Apply the pipeline's rules to a forecast variance curve ``P`` (M, 3) at ``t`` (M,).

    The stage (its settle test started at ``t_stage``; ``converged`` already latched)
    settles where it has run ``min_duration`` (the settle test's two spans: a forecast
    curve has no corrections to sum, and a filter whose variance follows it settles as
    the spans fill); ``aligned`` from then on where the tilt and heading 1-sigma are
    within the bounds (:mod:`.fine_stage`). Returns ``(index of aligned or None, index of
    a ready tilt or None)``.
    """
    s = np.sqrt(np.maximum(P, 0.0))
    tilt_ok = np.maximum(s[:, 0], s[:, 1]) <= max_tilt
    i_tilt = np.flatnonzero(tilt_ok)
    i_tilt = int(i_tilt[0]) if len(i_tilt) else None
    start = 0 if converged else int(np.searchsorted(t, t_stage + min_duration, side='left'))
    good = np.flatnonzero(tilt_ok[start:] & (s[start:, 2] <= max_heading))
    return (start + int(good[0]) if len(good) else None), i_tilt


def covariance_shadow(model, horizon_s):
    """Run a linear filter's covariance on for ``horizon_s``: ``(tau (M,), P_att (M, 3))``.

    ``model``: an engine's ``forecast_model()`` (``P``, ``Phi``, ``Q``, ``H``, ``R``, ``T``,
    ``i_phi``, ``heading_cap``, ``heading_claim``), its epoch repeated every ``T`` seconds:
    the prior recursion ``P- <- Q + Phi P- (I + S P-)^-1 Phi^T`` with ``S = H^T R^-1 H``,
    whose posterior after each epoch is ``P- (I + S P-)^-1``. ``P_att``: the attitude
    variances of that posterior as published (a heading variance beyond
    ``heading_claim`` is an unknown angle's; the heading held within ``heading_cap`` as the
    engine holds it). One epoch a step over the first :data:`MOTION_FINE_S` s, then the
    step doubles every as much again up to :data:`MOTION_MAX_LUMP` epochs, with the exact
    map of that many epochs (the doubling recursion of Chu, Fan and Lin's structure-
    preserving doubling algorithm for the discrete Riccati equation): a few hundred steps,
    a few ms, for an hour. Stops once the variances change less than :data:`SETTLED` over
    :data:`SETTLED_S` s; the last row, at ``horizon_s``, holds them.
    """
    P, Phi, Q, H, R, T = (model[k] for k in ('P', 'Phi', 'Q', 'H', 'R', 'T'))
    i_att = np.arange(len(P))[model['i_phi']]
    k_head, cap = i_att[2], model['heading_cap']
    eye = np.eye(len(P))
    # the map of `lump` epochs: P- -> Hq + At^T P- (I + Gs P-)^-1 At
    At, Gs, Hq = Phi.T, H.T @ np.linalg.solve(R, H), Q
    S = Gs
    lump, span_end = 1, MOTION_FINE_S
    Pm = Phi @ P @ Phi.T + Q                        # the prior of the next epoch
    taus, rows, t, last, t_checked = [], [], 0.0, None, 0.0
    while True:
        Pp = np.linalg.solve(eye + Pm @ S, Pm)          # P- (I + S P-)^-1, symmetric
        Pp = 0.5 * (Pp + Pp.T)
        t += T * lump
        taus.append(t)
        rows.append(np.diag(Pp)[i_att])
        if t >= horizon_s:
            break
        if t - t_checked >= SETTLED_S:
            if last is not None and np.all(np.abs(rows[-1] - last) <= SETTLED * last):
                taus.append(horizon_s)
                rows.append(rows[-1])
                break
            last, t_checked = rows[-1], t
        if cap is not None and Pm[k_head, k_head] > cap:
            sc = np.ones(len(P))
            sc[k_head] = math.sqrt(cap / Pm[k_head, k_head])
            Pm = Pm * np.outer(sc, sc)
        if t >= span_end and lump < MOTION_MAX_LUMP:
            W = np.linalg.inv(eye + Gs @ Hq)
            At, Gs, Hq = At @ W @ At, Gs + At @ W @ Gs @ At.T, Hq + At.T @ Hq @ W @ At
            lump *= 2
            span_end += MOTION_FINE_S
        Pm = Hq + At.T @ Pm @ np.linalg.solve(eye + Gs @ Pm, At)
        Pm = 0.5 * (Pm + Pm.T)
    Pa = np.array(rows)
    if model['heading_claim'] is not None:
        Pa[:, 2] = np.where(Pa[:, 2] > model['heading_claim'], ANGLE_UNKNOWN_VAR, Pa[:, 2])
    return np.array(taus), Pa

"""Bias bounds from a still window's mean rate and specific force (part of :mod:`.self_check`).

* **Biases on a still base** (the window shows no motion once the noise is right):
  the mean specific force must have the magnitude of normal gravity, so
  ``|f| - g`` is the accelerometer bias along the vertical; the mean rate along the
  measured vertical must be ``W sin(L)`` and its horizontal magnitude ``W cos(L)``, so
  their differences bound the gyro bias. A bound beyond two model sigmas
  (plus what noise, gravity-model and scale-factor errors explain) widens the bias
  sigma to the bound. On a moving base this check is skipped (said so).
"""
import math

import numpy as np

from ...nav import earth
from ...units import DPH, UG
from .grade_check import _model
from .latitude_estimate import _latitude

#: specific-force magnitude that normal gravity, height and scale factor may explain, m/s^2
GRAVITY_TOL = 300.0 * UG
#: rate the gravity direction and scale factors may explain on a still base, rad/s
RATE_TOL = 0.05 * DPH


def _gyro_bias_sigma(out, cfg):
    """Return the (widened) gyro bias 1-sigma, constant and varying parts, rad/s."""
    return math.hypot(_model(out, cfg, 'gyro_bias_dph'),
                      _model(out, cfg, 'gyro_bias_instability_dph')) * DPH


def _biases(out, w_b, f_b, T, lat, h, cfg, arw, vrw):
    """Bias bounds from the window means ``w_b``, ``f_b`` (3,) widen ``out``'s model.

    ``lat`` None: the latitude is not known; the gyro bound compares the rate's magnitude
    only, the latitude is estimated (:func:`~.latitude_estimate.estimate_latitude`) and,
    where the gyros see the Earth rate clearly, used; else it is unknown and the
    accelerometer bound compares with gravity's range over all latitudes. Returns the
    latitude used (rad).
    """
    f_norm = float(np.linalg.norm(f_b))
    u = f_b / f_norm
    w_up = float(w_b @ u)
    w_h = float(np.linalg.norm(w_b - w_up * u))
    gyro_sigma = _gyro_bias_sigma(out, cfg)
    tol_g = 2.0 * gyro_sigma + 3.0 * arw / math.sqrt(T) + RATE_TOL
    if lat is not None:
        bound = max(abs(w_up - earth.OMEGA_IE * math.sin(lat)),
                    abs(w_h - earth.OMEGA_IE * math.cos(lat)))
        what = f'mean rate at rest differs from Earth rate by {bound / DPH:.3g} deg/h'
    else:
        bound = abs(math.hypot(w_up, w_h) - earth.OMEGA_IE)
        what = (f'mean rate at rest is {math.hypot(w_up, w_h) / DPH:.3g} deg/h, Earth rate '
                f'{earth.OMEGA_IE / DPH:.4g} deg/h (its direction not compared: latitude not '
                'set)')
    widened = _bound(out, 'gyro_bias_dph', bound / DPH, tol_g / DPH, gyro_sigma / DPH,
                     f'{what}: a gyro bias of at least {bound / DPH:.3g} deg/h')
    accel_sigma = _model(out, cfg, 'accel_bias_ug') * UG
    if lat is None:
        lat = _latitude(out, w_b, f_b, T, _gyro_bias_sigma(out, cfg), arw, accel_sigma,
                        widened)
    if out.latitude_unknown:
        g_lo, g_hi = earth.gravity(0.0, h), earth.gravity(0.5 * math.pi, h)
        g = min(max(f_norm, g_lo), g_hi)
        against = f'gravity {g_lo:.5g}-{g_hi:.5g} (latitude unknown)'
    else:
        g = earth.gravity(lat, h)
        against = f'gravity {g:.5g}'
    accel_bound = abs(f_norm - g)
    tol_a = 2.0 * accel_sigma + 3.0 * vrw / math.sqrt(T) + GRAVITY_TOL
    _bound(out, 'accel_bias_ug', accel_bound / UG, tol_a / UG, accel_sigma / UG,
           f'specific force {f_norm:.5g} m/s^2 at rest against {against}: an '
           f'accelerometer bias of at least {accel_bound / UG:.0f} ug')
    return lat


def _bound(out, name, bound, tolerance, model, what):
    """Record a bias ``bound`` on parameter ``name``; widen to it beyond ``tolerance``.

    Returns True if it widened.
    """
    out.figures[name.replace('_ug', '_bound_ug').replace('_dph', '_bound_dph')] = bound
    if bound > tolerance:
        out.widened[name] = bound
        out.findings.append(f'{what}, {model:.3g} in the model: {name} widened')
        return True
    return False

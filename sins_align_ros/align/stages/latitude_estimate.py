"""The latitude from the gyros at rest, where it is not set (part of :mod:`.self_check`).

* **Latitude** (``initial_latitude_deg`` not set and no GNSS fix): at rest the mean rate is
  the Earth rate, at the latitude's angle from the equatorial plane: the angle between
  the mean rate and the mean specific force (up) gives ``sin L = (w . f) / (|w| |f|)``,
  with a 1-sigma of the gyro bias and noise over the Earth rate. Where the gyro sees the
  Earth rate clearly (its magnitude as modelled, that sigma at most
  :data:`LATITUDE_MAX_SIGMA`: a navigation-grade IMU) the estimate replaces the
  position's latitude (in place: the coarse and fine stages use it) and a warning says
  so. Elsewhere (a lower grade, a swaying or moving base) the latitude is unknown: 0
  is used, the finding says so, the bias bounds compare only what needs no latitude
  (the rate's magnitude, gravity's range) and the heading is published as unknown (its
  sigma grows as 1 / cos L with a latitude nobody knows).
"""
import math

import numpy as np

from ...nav import earth
from ...units import DEG, DPH

#: the latitude estimated at rest is used when its 1-sigma is at most this, rad (2 deg: a
#: gyro bias of 0.5 deg/h against the 15.04 deg/h Earth rate; tactical and lower grades
#: need initial_latitude_deg or a GNSS fix)
LATITUDE_MAX_SIGMA = 2.0 * DEG


def _latitude_unknown(out, why):
    """Record that the latitude is unknown (not set, no fix, not estimated) and ``why``."""
    out.latitude_unknown = True
    out.findings.append(f'latitude unknown: initial_latitude_deg is not set and no GNSS fix '
                        f'came, and the gyros cannot estimate it ({why}): 0 deg used, heading '
                        'published as unknown; set initial_latitude_deg')


def estimate_latitude(w_b, f_b, T, gyro_sigma, arw, accel_sigma):
    """Latitude (rad) and its 1-sigma from the window means ``w_b``, ``f_b`` (3,) at rest.

    ``sin L = (w . f) / (|w| |f|)``, taken as ``atan2(w_up, w_h)``. The sigma: the gyro
    bias ``gyro_sigma`` and the mean noise ``arw / sqrt(T)`` (rad/s) move the rate by that
    much across its direction, and an accelerometer bias ``accel_sigma`` tilts the
    vertical by ``accel_sigma / g``.
    """
    f_norm = float(np.linalg.norm(f_b))
    u = f_b / f_norm
    w_up = float(w_b @ u)
    w_h = float(np.linalg.norm(w_b - w_up * u))
    lat = math.atan2(w_up, w_h)
    sigma = math.sqrt(gyro_sigma ** 2 + arw ** 2 / T) / earth.OMEGA_IE
    return lat, math.hypot(sigma, accel_sigma / f_norm)


def _latitude(out, w_b, f_b, T, gyro_sigma, arw, accel_sigma, rate_off):
    """Estimate the latitude not set; use it where clear (module docstring). Returns rad.

    ``rate_off``: the rate's magnitude contradicted the model (the gyro does not see the
    Earth rate as modelled): no estimate is used then.
    """
    lat, sigma = estimate_latitude(w_b, f_b, T, gyro_sigma, arw, accel_sigma)
    out.figures.update(latitude_estimate_deg=lat / DEG, latitude_sigma_deg=sigma / DEG)
    if rate_off or not sigma <= LATITUDE_MAX_SIGMA:
        why = ('its mean rate at rest is not the Earth rate' if rate_off else
               f'{sigma / DEG:.3g} deg 1-sigma from a gyro bias of {gyro_sigma / DPH:.3g} deg/h')
        _latitude_unknown(out, why)
        return 0.0
    out.latitude = (lat, sigma)
    out.findings.append(f'latitude not set (initial_latitude_deg) and no GNSS fix: '
                        f'{lat / DEG:.2f} +- {sigma / DEG:.2f} deg (1 sigma) estimated from the '
                        'angle between the mean rate (Earth rate) and the mean specific force '
                        'at rest, and used')
    return lat

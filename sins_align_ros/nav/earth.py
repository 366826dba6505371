"""WGS-84 Earth model in the ENU navigation frame.

All functions are vectorised: latitude ``lat`` (rad) and height ``h`` (m) may be
scalars or arrays of shape (N,); velocities ``v_n`` are ENU, shape (3,) or (N, 3).
Vector results keep the trailing axis of length 3.

References: NIMA TR8350.2 (WGS-84 constants, Somigliana normal gravity and the
free-air height correction); Groves, *Principles of GNSS, Inertial and
Multisensor Integrated Navigation*, ch. 2 (radii of curvature, transport rate).

The conventional standard gravity ``G0`` (the micro-g and g of datasheets), not the
normal gravity here, is :mod:`sins_align_ros.units`'s.
"""
import numpy as np

#: semi-major axis (m)
A = 6378137.0
#: flattening
F = 1.0 / 298.257223563
#: first eccentricity squared
E2 = F * (2.0 - F)
#: Earth rotation rate (rad/s)
OMEGA_IE = 7.292115e-5
#: normal gravity at the equator (m/s^2)
G_EQUATOR = 9.7803253359
#: Somigliana constant k = (b*g_pole)/(a*g_eq) - 1
K_SOMIGLIANA = 0.00193185265241


def radii(lat):
    """Meridian (R_M) and prime-vertical (R_N) radii of curvature.

    Parameters
    ----------
    lat : float or ndarray (N,)
        Geodetic latitude, rad.

    Returns
    -------
    R_M, R_N : float or ndarray (N,)
        Radii in metres.
    """
    s2 = np.sin(lat) ** 2
    w = 1.0 - E2 * s2
    R_N = A / np.sqrt(w)
    R_M = A * (1.0 - E2) / (w * np.sqrt(w))
    return R_M, R_N


def gravity(lat, h):
    """Return the normal gravity magnitude, m/s^2, at ``lat`` (rad) and height ``h`` (m).

    Somigliana's closed form on the ellipsoid plus the second-order free-air
    correction in height (TR8350.2 eq. 4-1 and 4-3).
    """
    s2 = np.sin(lat) ** 2
    g0 = G_EQUATOR * (1.0 + K_SOMIGLIANA * s2) / np.sqrt(1.0 - E2 * s2)
    return g0 - (3.0877e-6 - 4.4e-9 * s2) * h + 7.2e-14 * h ** 2


def gravity_n(lat, h):
    """Return the normal gravity vector in ENU, shape (3,) or (N, 3): ``[0, 0, -g]``."""
    g = np.asarray(gravity(lat, h), dtype=float)
    out = np.zeros(g.shape + (3,))
    out[..., 2] = -g
    return out


def w_ie_n(lat):
    """Earth rotation rate in ENU, shape (3,) or (N, 3): ``Omega*[0, cos L, sin L]``."""
    lat = np.asarray(lat, dtype=float)
    out = np.zeros(lat.shape + (3,))
    out[..., 1] = OMEGA_IE * np.cos(lat)
    out[..., 2] = OMEGA_IE * np.sin(lat)
    return out


def w_en_n(lat, h, v_n):
    """Transport rate in ENU, shape like ``v_n``.

    ``w_en_n = [-v_N/(R_M+h), v_E/(R_N+h), v_E tan(L)/(R_N+h)]``.
    """
    v_n = np.asarray(v_n, dtype=float)
    R_M, R_N = radii(lat)
    out = np.empty(np.broadcast_shapes(np.shape(lat) + (3,), v_n.shape))
    out[..., 0] = -v_n[..., 1] / (R_M + h)
    out[..., 1] = v_n[..., 0] / (R_N + h)
    out[..., 2] = v_n[..., 0] * np.tan(lat) / (R_N + h)
    return out


def position_rate(lat, h, v_n):
    """Time derivative of geodetic position ``(lat, lon, h)`` for ENU velocity ``v_n``.

    Returns an array of shape (3,) or (N, 3): ``[dlat/dt, dlon/dt, dh/dt]`` in
    rad/s, rad/s, m/s.
    """
    v_n = np.asarray(v_n, dtype=float)
    R_M, R_N = radii(lat)
    out = np.empty(np.broadcast_shapes(np.shape(lat) + (3,), v_n.shape))
    out[..., 0] = v_n[..., 1] / (R_M + h)
    out[..., 1] = v_n[..., 0] / ((R_N + h) * np.cos(lat))
    out[..., 2] = v_n[..., 2]
    return out


def local_offset_m(lat0, lon0, h0, lat, lon, h):
    """ENU offset (m) of ``(lat, lon, h)`` from ``(lat0, lon0, h0)``, small-area approximation.

    Uses the radii at ``lat0``; accurate to millimetres over a few kilometres,
    which is what position error statistics need.
    """
    R_M, R_N = radii(lat0)
    return np.stack([(np.asarray(lon) - lon0) * (R_N + h0) * np.cos(lat0),
                     (np.asarray(lat) - lat0) * (R_M + h0),
                     np.asarray(h) - h0], axis=-1)

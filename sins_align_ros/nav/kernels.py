"""Compiled inner loops of the navigation layer (numba), with a pure-Python fallback.

:func:`strapdown_run` is :meth:`~.mechanization.Strapdown.update` applied to a block
of samples: the same equations in the same order (the module docstring of
:mod:`~.mechanization`), written on scalars so that numba compiles it to a loop
without temporaries. :meth:`Strapdown.update` stays the readable reference, and a test
keeps the two equal to round-off (test_mechanization.py). How they are compiled (ahead
of time, just in time or not at all): :mod:`sins_align_ros.compiled`.
"""
import math

import numpy as np

from ..compiled import jit, run_warm_ups
from .earth import A, E2, G_EQUATOR, K_SOMIGLIANA, OMEGA_IE


@jit
def _radii(lat):
    s = math.sin(lat)
    w = 1.0 - E2 * s * s
    sw = math.sqrt(w)
    return A * (1.0 - E2) / (w * sw), A / sw


@jit
def _gravity(lat, h):
    s2 = math.sin(lat) ** 2
    g0 = G_EQUATOR * (1.0 + K_SOMIGLIANA * s2) / math.sqrt(1.0 - E2 * s2)
    return g0 - (3.0877e-6 - 4.4e-9 * s2) * h + 7.2e-14 * h ** 2


@jit(sig='UniTuple(f8, 9)(f8, f8, f8)')
def rodrigues9(x, y, z):
    """Rodrigues ``exp([v x])`` of ``v = (x, y, z)`` as a row-major 9-tuple of floats.

    The one Rodrigues of the mechanization: the kernels and the scalar Python path
    (``Strapdown.step``) both call it.
    """
    a2 = x * x + y * y + z * z
    if a2 < 1e-12:
        s = 1.0 - a2 / 6.0
        c = 0.5 - a2 / 24.0
    else:
        a = math.sqrt(a2)
        s = math.sin(a) / a
        c = (1.0 - math.cos(a)) / a2
    return (1.0 - c * (y * y + z * z), c * x * y - s * z, c * x * z + s * y,
            c * x * y + s * z, 1.0 - c * (x * x + z * z), c * y * z - s * x,
            c * x * z - s * y, c * y * z + s * x, 1.0 - c * (x * x + y * y))


@jit
def _rodrigues(x, y, z, R):
    """:func:`rodrigues9` into ``R`` (3, 3)."""
    r = rodrigues9(x, y, z)
    R[0, 0], R[0, 1], R[0, 2] = r[0], r[1], r[2]
    R[1, 0], R[1, 1], R[1, 2] = r[3], r[4], r[5]
    R[2, 0], R[2, 1], R[2, 2] = r[6], r[7], r[8]


@jit
def _newton_schulz(C, T, steps):
    """Take ``C`` (3, 3) toward its polar factor in place; return its last departure.

    At most ``steps`` Newton-Schulz steps ``C <- C (3 I - C^T C) / 2`` (``T`` (3, 3)
    scratch), stopping once the departure ``max |C^T C - I|`` is below 1e-15. Each step
    squares the departure (``3/4 |E|^2``), so the 1e-13 that 1000 products of rotations
    gather is gone to round-off in two; the same matrix as the SVD's ``U V^T`` to 1e-16.
    Not the SVD because LAPACK inside compiled code makes numba import ``scipy.linalg``
    (0.15 s of a replay's start). Returns the departure of the ``C`` left (below 1e-15:
    converged; ``C`` is not stepped after its departure is measured below that or after
    the last of the ``steps``).
    """
    err = 0.0
    for k in range(steps + 1):
        err = 0.0
        for i in range(3):
            for j in range(3):
                d = C[0, i] * C[0, j] + C[1, i] * C[1, j] + C[2, i] * C[2, j]
                err = max(err, abs(d - 1.0) if i == j else abs(d))
                T[i, j] = 0.5 * ((3.0 if i == j else 0.0) - d)
        if err < 1e-15 or k == steps:
            return err
        for i in range(3):
            a, b, c = C[i, 0], C[i, 1], C[i, 2]
            C[i, 0] = a * T[0, 0] + b * T[1, 0] + c * T[2, 0]
            C[i, 1] = a * T[0, 1] + b * T[1, 1] + c * T[2, 1]
            C[i, 2] = a * T[0, 2] + b * T[1, 2] + c * T[2, 2]
    return err


#: departure ``max |C^T C - I|`` up to which :func:`polar_factor` iterates (a mean
#: attitude over an interval or an attitude after feedback is far inside it; a matrix that
#: passes but is singular runs out of steps); further, the SVD
POLAR_MAX_DEPARTURE = 0.5


@jit(sig='b1(f8[:, :], f8[:, :])')
def polar_factor(C, out):
    """Write the polar factor of ``C`` (3, 3), the nearest orthonormal matrix, into ``out``.

    Newton-Schulz steps (:func:`_newton_schulz`) from a matrix within
    :data:`POLAR_MAX_DEPARTURE` of orthonormal: a filter's attitude after feedback, or
    the mean attitude over an interval. False (``out`` not usable) when ``C`` is further
    or the steps do not reach round-off, and when an entry is not finite (the SVD then
    raises, as without the kernels): the caller takes the SVD.
    """
    for i in range(3):
        for j in range(3):
            if not np.isfinite(C[i, j]):
                return False
            out[i, j] = C[i, j]
    T = np.empty((3, 3))
    err = 0.0
    for i in range(3):
        for j in range(3):
            d = C[0, i] * C[0, j] + C[1, i] * C[1, j] + C[2, i] * C[2, j]
            err = max(err, abs(d - 1.0) if i == j else abs(d))
    if not err < POLAR_MAX_DEPARTURE:
        return False
    return _newton_schulz(out, T, 12) < 1e-15


@jit(sig='UniTuple(f8, 6)(f8, f8, b1, f8[:])')
def earth_terms(lat, h, cached, ec):
    """``(sin, cos, tan, R_M, R_N, g)`` at ``lat``, ``h``; ``cached``: through ``ec`` (8,).

    ``ec`` holds ``(lat, h, sin, cos, tan, R_M, R_N, g)`` of the last evaluation (``lat``
    NaN: none), refreshed when the latitude moved by more than 1e-7 rad or the height by
    more than 0.01 m; ``Strapdown.step`` uses it through ``Strapdown._earth_cache``.
    """
    if cached and ec[0] == ec[0] and abs(lat - ec[0]) <= 1e-7 and abs(h - ec[1]) <= 0.01:
        return ec[2], ec[3], ec[4], ec[5], ec[6], ec[7]
    RM, RN = _radii(lat)
    out = (math.sin(lat), math.cos(lat), math.tan(lat), RM, RN, _gravity(lat, h))
    if cached:
        ec[0], ec[1] = lat, h
        ec[2], ec[3], ec[4], ec[5], ec[6], ec[7] = out
    return out


@jit(sig='UniTuple(f8, 6)(' + ', '.join(['f8'] * 12) + ')')
def coning_sculling(ax, ay, az, bx, by, bz, px, py, pz, qx, qy, qz):
    """Coning-corrected rotation ``phi`` and rotation + sculling corrected ``dv_b``.

    ``a``: this sample's ``dtheta``, ``b`` its ``dv``, ``p`` and ``q`` the previous
    sample's (body axes, rad and m/s); the formulas of :mod:`~.mechanization`'s module
    docstring. Returns the six floats ``phi (3), dv_b (3)``; the scalar Python path
    (``Strapdown.step``) calls it too.
    """
    fx = ax + (py * az - pz * ay) / 12.0
    fy = ay + (pz * ax - px * az) / 12.0
    fz = az + (px * ay - py * ax) / 12.0
    rx, ry, rz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    ux = (bx + 0.5 * rx + (ay * rz - az * ry) / 6.0
          + ((py * bz - pz * by) + (qy * az - qz * ay)) / 12.0)
    uy = (by + 0.5 * ry + (az * rx - ax * rz) / 6.0
          + ((pz * bx - px * bz) + (qz * ax - qx * az)) / 12.0)
    uz = (bz + 0.5 * rz + (ax * ry - ay * rx) / 6.0
          + ((px * by - py * bx) + (qx * ay - qy * ax)) / 12.0)
    return fx, fy, fz, ux, uy, uz


@jit(sig='i8(f8[:, :], f8[:], f8[:], f8[:], f8[:], f8[:], f8[:], i8, f8[:, :], f8[:, :], '
         'f8[:], b1, b1, b1, b1, b1, f8[:], f8[:, :, :], f8[:, :], f8[:, :], f8[:, :])')
def strapdown_run(C, v, v_prev, pos, pos_prev, dth_prev, dv_prev, steps, dtheta, dv, dt,
                  transport_rate, update_position, coriolis, hold_vertical, cached, ec,
                  C_out, v_out, pos_out, dvsf_out):
    """Advance the strapdown state over N samples; the state arrays change in place.

    State (as :class:`~.mechanization.Strapdown`'s): ``C`` (3, 3) ``C_b_n``; ``v``,
    ``v_prev`` (3,) ENU velocity now and one sample before; ``pos``, ``pos_prev`` (3,)
    (lat, lon, h); ``dth_prev``, ``dv_prev`` (3,) the last increments; ``steps`` the
    samples so far (re-orthonormalisation every 1000). Input: ``dtheta``, ``dv`` (N, 3)
    body increments (rad, m/s), ``dt`` (N,) s; the four
    :class:`~.mechanization.MechanizationOptions` flags. ``cached`` False:
    :meth:`~.mechanization.Strapdown.update`'s arithmetic (Earth terms at every sample);
    True: :meth:`~.mechanization.Strapdown.step`'s (Earth terms through the cache ``ec``,
    :func:`earth_terms`). Output, per sample: ``C_out`` (N, 3, 3), ``v_out`` (N, 3),
    ``pos_out`` (N, 3) and ``dvsf_out`` (N, 3), the specific-force increment in ENU.
    Returns the new ``steps``.
    """
    E = np.empty((3, 3))
    Pm = np.empty((3, 3))
    T = np.empty((3, 3))
    for k in range(dtheta.shape[0]):
        ax, ay, az = dtheta[k, 0], dtheta[k, 1], dtheta[k, 2]
        bx, by, bz = dv[k, 0], dv[k, 1], dv[k, 2]
        px, py, pz = dth_prev[0], dth_prev[1], dth_prev[2]
        qx, qy, qz = dv_prev[0], dv_prev[1], dv_prev[2]
        h_dt = dt[k]
        fx, fy, fz, ux, uy, uz = coning_sculling(ax, ay, az, bx, by, bz,
                                                 px, py, pz, qx, qy, qz)
        v0, v1, v2 = v[0], v[1], v[2]
        m0 = 1.5 * v0 - 0.5 * v_prev[0]
        m1 = 1.5 * v1 - 0.5 * v_prev[1]
        m2 = 1.5 * v2 - 0.5 * v_prev[2]
        lat, lon, h = pos[0], pos[1], pos[2]
        if update_position:
            lat_m = 1.5 * lat - 0.5 * pos_prev[0]
            h_m = 1.5 * h - 0.5 * pos_prev[2]
        else:
            lat_m, h_m = lat, h
        sl, cl, tl, RM, RN, g = earth_terms(lat_m, h_m, cached, ec)
        ie1, ie2 = OMEGA_IE * cl, OMEGA_IE * sl
        if transport_rate:
            en0 = -m1 / (RM + h_m)
            en1 = m0 / (RN + h_m)
            en2 = en1 * tl if cached else m0 * tl / (RN + h_m)
        else:
            en0 = en1 = en2 = 0.0
        zx, zy, zz = en0 * h_dt, (ie1 + en1) * h_dt, (ie2 + en2) * h_dt
        sx = C[0, 0] * ux + C[0, 1] * uy + C[0, 2] * uz
        sy = C[1, 0] * ux + C[1, 1] * uy + C[1, 2] * uz
        sz = C[2, 0] * ux + C[2, 1] * uy + C[2, 2] * uz
        sx, sy, sz = (sx - 0.5 * (zy * sz - zz * sy), sy - 0.5 * (zz * sx - zx * sz),
                      sz - 0.5 * (zx * sy - zy * sx))
        n0, n1, n2 = v0 + sx, v1 + sy, v2 + sz - g * h_dt
        if coriolis:
            c0, c1, c2 = en0, 2.0 * ie1 + en1, 2.0 * ie2 + en2
            n0 -= (c1 * m2 - c2 * m1) * h_dt
            n1 -= (c2 * m0 - c0 * m2) * h_dt
            n2 -= (c0 * m1 - c1 * m0) * h_dt
        if hold_vertical:
            n2 = 0.0
        dvsf_out[k, 0], dvsf_out[k, 1], dvsf_out[k, 2] = sx, sy, sz
        if update_position:
            pos_prev[0], pos_prev[1], pos_prev[2] = lat, lon, h
            a0, a1, a2 = 0.5 * (v0 + n0), 0.5 * (v1 + n1), 0.5 * (v2 + n2)
            h_avg = h + 0.25 * (v2 + n2) * h_dt
            if cached:                       # the radii of the interval (step)
                RMa, RNa = RM, RN
                lat_avg = lat + 0.5 * a1 / (RM + h_avg) * h_dt
            else:                            # at the position, then mid-step (update)
                RM0, _ = _radii(lat)
                lat_avg = lat + 0.5 * (a1 / (RM0 + h_avg)) * h_dt
                RMa, RNa = _radii(lat_avg)
            pos[0] = lat + a1 / (RMa + h_avg) * h_dt
            pos[1] = lon + a0 / ((RNa + h_avg) * math.cos(lat_avg)) * h_dt
            pos[2] = h + a2 * h_dt
        # C <- exp(-[zeta x]) C exp([phi x])
        _rodrigues(-zx, -zy, -zz, E)
        _rodrigues(fx, fy, fz, Pm)
        for i in range(3):
            for j in range(3):
                T[i, j] = E[i, 0] * C[0, j] + E[i, 1] * C[1, j] + E[i, 2] * C[2, j]
        for i in range(3):
            for j in range(3):
                C[i, j] = T[i, 0] * Pm[0, j] + T[i, 1] * Pm[1, j] + T[i, 2] * Pm[2, j]
        steps += 1
        if steps % 1000 == 0:
            _newton_schulz(C, T, 4)
        v_prev[0], v_prev[1], v_prev[2] = v0, v1, v2
        v[0], v[1], v[2] = n0, n1, n2
        dth_prev[0], dth_prev[1], dth_prev[2] = ax, ay, az
        dv_prev[0], dv_prev[1], dv_prev[2] = bx, by, bz
        C_out[k] = C
        v_out[k] = v
        pos_out[k] = pos
    return steps


@jit(sig='f8(f8, f8[:], f8[:], f8[:, :], b1, f8[:, :], f8[:, :], f8[:, :, :], f8[:])')
def interval_sums(T, dv_sum, v_sum, C_sum, attitude, dv_sf, v_n, C, dt):
    """Add N mechanized samples to a filter interval's sums in place; return the new ``T``.

    ``dv_sum``, ``v_sum`` (3,) and, with ``attitude``, ``C_sum`` (3, 3) gain each sample's
    ``dv_sf``, ``v_n dt`` and ``C dt`` (``dv_sf``, ``v_n`` (N, 3), ``C`` (N, 3, 3), ``dt``
    (N,)) one after the other, the order of a sample-by-sample sum, so a block and its
    samples added singly agree bit for bit (``align.engines.aided.IntervalSums``).
    """
    for k in range(len(dt)):
        h = dt[k]
        T += h
        for i in range(3):
            dv_sum[i] += dv_sf[k, i]
            v_sum[i] += v_n[k, i] * h
        if attitude:
            for i in range(3):
                for j in range(3):
                    C_sum[i, j] += C[k, i, j] * h
    return T


@jit(sig='void(f8[:, :], f8[:, :, :])')
def attitude_increments(dtheta, out):
    """``C_b(t_k)^{b0}`` for k = 1..N into ``out`` (N, 3, 3), from ``dtheta`` (N, 3) rad.

    The body attitude relative to the start, with the mechanization's coning correction
    (``coarse.body_attitude_increments``).
    """
    C = np.eye(3)
    T = np.empty((3, 3))
    R = np.empty((3, 3))
    px = py = pz = 0.0
    for k in range(dtheta.shape[0]):
        ax, ay, az = dtheta[k, 0], dtheta[k, 1], dtheta[k, 2]
        _rodrigues(ax + (py * az - pz * ay) / 12.0, ay + (pz * ax - px * az) / 12.0,
                   az + (px * ay - py * ax) / 12.0, R)
        for i in range(3):
            for j in range(3):
                T[i, j] = C[i, 0] * R[0, j] + C[i, 1] * R[1, j] + C[i, 2] * R[2, j]
        C[:, :] = T
        out[k] = C
        px, py, pz = ax, ay, az


def warm_up():
    """Compile (or load from the cache) every kernel now; returns the seconds it took.

    A live node calls this before it subscribes: the first use otherwise compiles in the
    middle of the data (the coarse window's end), seconds during which messages queue up
    and can be dropped. The kernels of other modules run the first calls they registered
    with :func:`~sins_align_ros.compiled.warms_up` (modules imported by then).
    """
    import time
    t0 = time.perf_counter()
    z = np.zeros((2, 3))
    attitude_increments(z, np.empty((2, 3, 3)))
    rodrigues9(0.0, 0.0, 0.0)                       # the scalar path's entry points
    earth_terms(0.5, 0.0, True, np.full(8, np.nan))
    coning_sculling(*([0.0] * 12))
    for cached in (False, True):
        strapdown_run(np.eye(3), np.zeros(3), np.zeros(3), np.array([0.5, 0.0, 0.0]),
                      np.array([0.5, 0.0, 0.0]), np.zeros(3), np.zeros(3), 0, z, z,
                      np.full(2, 0.01), True, True, True, False, cached, np.full(8, np.nan),
                      np.empty((2, 3, 3)), np.empty((2, 3)), np.empty((2, 3)), np.empty((2, 3)))
    z3 = np.zeros(3)
    interval_sums(0.0, z3, z3.copy(), np.zeros((3, 3)), True, z, z, np.empty((2, 3, 3)),
                  np.full(2, 0.01))
    polar_factor(np.eye(3), np.empty((3, 3)))
    run_warm_ups()
    return time.perf_counter() - t0

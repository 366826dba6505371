"""Strapdown mechanization in ENU from IMU increments.

Each IMU sample is an increment pair over ``[t_{k-1}, t_k]``: ``dtheta`` (rad) and
``dv`` (m/s), both in body (FLU) axes. The update follows the classic
two-speed structure (Savage, *Strapdown Analytics*, ch. 7; Titterton & Weston
ch. 11) with the previous-sample form of the two-sample corrections:

* coning: ``phi = dtheta_k + (1/12) dtheta_{k-1} x dtheta_k``
* rotation + sculling: ``dv_b = dv_k + 1/2 dtheta_k x dv_k
  + 1/6 dtheta_k x (dtheta_k x dv_k)
  + 1/12 (dtheta_{k-1} x dv_k + dv_{k-1} x dtheta_k)``; the third-order
  rotation term removes a rectified vertical error of ~0.1 micro-g on a
  swaying base
* attitude: ``C_b_n(k) = exp(-[zeta x]) C_b_n(k-1) exp([phi x])`` with
  ``zeta = w_in_n dt`` taken at mid-interval
* velocity: ``v_k = v_{k-1} + (I - [zeta x]/2) C_b_n(k-1) dv_b
  + (g_n - (2 w_ie_n + w_en_n) x v) dt``
* position: trapezoidal in velocity.

Mid-interval velocity and position are extrapolated linearly from the two
previous epochs. :class:`MechanizationOptions` switches on the stationary
"equivalence operations" of seed 002 Table 1: no transport rate, position
fixed at its initial value, optional removal of the Coriolis term
(seed 002 eq. 8) and vertical velocity held at zero (seed 002 sec. 3, (1)).
"""
import math
from dataclasses import dataclass

import numpy as np

from .. import compiled
from . import earth, kernels
from .kernels import rodrigues9 as _rodrigues9


@dataclass(frozen=True)
class MechanizationOptions:
    """Which terms the mechanization computes.

    Attributes
    ----------
    transport_rate : bool
        Compute ``w_en_n`` from velocity (False: set to zero, seed 002 Table 1 row 1).
    update_position : bool
        Integrate position (False: keep the initial position, Table 1 row 2).
    coriolis : bool
        Include ``(2 w_ie + w_en) x v`` (False: seed 002 eq. 8, Table 1 row 3).
    hold_vertical : bool
        Force the vertical velocity to zero after each update (seed 002 sec. 3).
    """

    transport_rate: bool = True
    update_position: bool = True
    coriolis: bool = True
    hold_vertical: bool = False

    @classmethod
    def stationary(cls, coriolis=False):
        """Seed 002 Table 1 equivalence operations for a still base."""
        return cls(transport_rate=False, update_position=False,
                   coriolis=coriolis, hold_vertical=True)


def _exp_so3(v):
    """Rodrigues: ``exp([v x])`` for one rotation vector (3,), as (3, 3)."""
    return np.array(_rodrigues9(float(v[0]), float(v[1]), float(v[2]))).reshape(3, 3)


def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1],
                     a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


class Strapdown:
    """Strapdown navigator state and update.

    Parameters
    ----------
    C_b_n : ndarray (3, 3)
        Initial attitude, body (FLU) -> ENU.
    v_n : ndarray (3,)
        Initial ENU velocity, m/s.
    lat, lon, h : float
        Initial geodetic position, rad, rad, m.
    options : MechanizationOptions
    """

    def __init__(self, C_b_n, v_n, lat, lon, h, options=MechanizationOptions()):
        self.C_b_n = np.array(C_b_n, dtype=float)
        self.v_n = np.array(v_n, dtype=float)
        self.lat, self.lon, self.h = float(lat), float(lon), float(h)
        self.options = options
        self._dtheta_prev = np.zeros(3)
        self._dv_prev = np.zeros(3)
        self._v_prev = self.v_n.copy()
        self._pos_prev = np.array([self.lat, self.lon, self.h])
        self._steps = 0
        self.dv_sf = np.zeros(3)
        #: Earth-term cache of the scalar path (lat, h, sin, cos, tan, R_M, R_N, g; NaN: none)
        self._ec = np.full(8, np.nan)

    @property
    def position(self):
        """``[lat, lon, h]`` (rad, rad, m)."""
        return np.array([self.lat, self.lon, self.h])

    # -- closed-loop feedback: the one way filters correct the navigator's state ------------
    def correct_velocity(self, dv_n):
        """Remove an estimated ENU velocity error ``dv_n`` (3,) m/s.

        The previous velocity used for the mid-interval extrapolation moves with it,
        so the next step does not see the correction as an acceleration.
        """
        self.v_n = self.v_n - dv_n
        self._v_prev = self._v_prev - dv_n

    def correct_position(self, dpos):
        """Remove an estimated position error ``dpos`` (3,) (rad, rad, m); history moves too."""
        self.lat -= dpos[0]
        self.lon -= dpos[1]
        self.h -= dpos[2]
        self._pos_prev = self._pos_prev - dpos

    def reset_position(self, lat, lon, h):
        """Put the position at ``lat``, ``lon``, ``h`` (rad, rad, m); history moves by as much."""
        new = np.array([lat, lon, h])
        self._pos_prev = self._pos_prev + (new - np.array([self.lat, self.lon, self.h]))
        self.lat, self.lon, self.h = (float(v) for v in new)

    def hold_vertical(self, h, v_up):
        """Hold the vertical channel to an external height ``h`` (m) and up velocity (m/s)."""
        self.h = h
        self.v_n[2] = v_up
        self._pos_prev[2] = h

    def reset_history(self):
        """Forget the previous increments (use after a gap in the data)."""
        self._dtheta_prev = np.zeros(3)
        self._dv_prev = np.zeros(3)
        self._v_prev = self.v_n.copy()
        self._pos_prev = self.position

    def update(self, dtheta, dv, dt):
        """Advance one IMU sample.

        Parameters
        ----------
        dtheta, dv : array_like (3,)
            Angle (rad) and velocity (m/s) increments over ``dt``, body axes.
        dt : float
            Sample interval, s (> 0).
        """
        dtheta = np.asarray(dtheta, dtype=float)
        dv = np.asarray(dv, dtype=float)
        opt = self.options
        dth_p, dv_p = self._dtheta_prev, self._dv_prev

        phi = dtheta + _cross(dth_p, dtheta) / 12.0
        rot = _cross(dtheta, dv)
        dv_b = (dv + 0.5 * rot + _cross(dtheta, rot) / 6.0
                + (_cross(dth_p, dv) + _cross(dv_p, dtheta)) / 12.0)

        v = self.v_n
        v_mid = 1.5 * v - 0.5 * self._v_prev
        if opt.update_position:
            pos = self.position
            lat_m, _, h_m = 1.5 * pos - 0.5 * self._pos_prev
        else:
            lat_m, h_m = self.lat, self.h

        w_ie = earth.w_ie_n(lat_m)
        if opt.transport_rate:
            w_en = earth.w_en_n(lat_m, h_m, v_mid)
        else:
            w_en = np.zeros(3)
        zeta = (w_ie + w_en) * dt

        dv_sf = self.C_b_n @ dv_b
        dv_sf = dv_sf - 0.5 * _cross(zeta, dv_sf)
        g_n = np.array([0.0, 0.0, -earth.gravity(lat_m, h_m)])
        if opt.coriolis:
            dv_g = (g_n - _cross(2.0 * w_ie + w_en, v_mid)) * dt
        else:
            dv_g = g_n * dt
        v_new = v + dv_sf + dv_g
        #: specific-force velocity increment of the last update in ENU (3,), for error models
        self.dv_sf = dv_sf
        if opt.hold_vertical:
            v_new[2] = 0.0

        if opt.update_position:
            self._pos_prev = self.position
            v_avg = 0.5 * (v + v_new)
            h_avg = self.h + 0.25 * (v[2] + v_new[2]) * dt
            lat_avg = self.lat + 0.5 * earth.position_rate(self.lat, h_avg, v_avg)[0] * dt
            rate = earth.position_rate(lat_avg, h_avg, v_avg)
            self.lat += rate[0] * dt
            self.lon += rate[1] * dt
            self.h += rate[2] * dt

        self.C_b_n = _exp_so3(-zeta) @ self.C_b_n @ _exp_so3(phi)
        self._steps += 1
        if self._steps % 1000 == 0:
            u, _, vt = np.linalg.svd(self.C_b_n)
            self.C_b_n = u @ vt

        self._v_prev = v
        self.v_n = v_new
        self._dtheta_prev = dtheta
        self._dv_prev = dv

    def step(self, dtheta, dv, dt):
        """One sample of :meth:`update` in scalar float arithmetic (moving-base fast path).

        The same equations; the Earth quantities (radii, gravity, sin/cos of the
        latitude) are refreshed when the latitude moves by more than 1e-7 rad
        (0.6 m) or the height by more than 0.01 m, which changes the result by
        less than 1e-9 relative (a test keeps the two paths together). Several
        times faster than :meth:`update` for one sample. Returns ``C_b_n``.
        """
        ax, ay, az, bx, by, bz, fx, fy, fz, ux, uy, uz = _coning_sculling(
            dtheta, dv, self._dtheta_prev, self._dv_prev)
        opt = self.options
        v0, v1, v2 = self.v_n.tolist()
        w0, w1, w2 = self._v_prev.tolist()
        m0, m1, m2 = 1.5 * v0 - 0.5 * w0, 1.5 * v1 - 0.5 * w1, 1.5 * v2 - 0.5 * w2
        lat, h = self.lat, self.h
        if opt.update_position:
            lat_m = 1.5 * lat - 0.5 * self._pos_prev[0]
            h_m = 1.5 * h - 0.5 * self._pos_prev[2]
        else:
            lat_m, h_m = lat, h
        e = self._earth_cache(lat_m, h_m)
        sl, cl, tl, RM, RN, g = e
        W = earth.OMEGA_IE
        ie1, ie2 = W * cl, W * sl
        if opt.transport_rate:
            en0, en1 = -m1 / (RM + h_m), m0 / (RN + h_m)
            en2 = en1 * tl
        else:
            en0 = en1 = en2 = 0.0
        zx, zy, zz = en0 * dt, (ie1 + en1) * dt, (ie2 + en2) * dt
        C0 = self.C_b_n.ravel().tolist()
        sx, sy, sz = _nav_specific_force(C0, ux, uy, uz, zx, zy, zz)
        n0, n1, n2 = v0 + sx, v1 + sy, v2 + sz - g * dt
        if opt.coriolis:
            c0, c1, c2 = en0, 2.0 * ie1 + en1, 2.0 * ie2 + en2
            n0 -= (c1 * m2 - c2 * m1) * dt
            n1 -= (c2 * m0 - c0 * m2) * dt
            n2 -= (c0 * m1 - c1 * m0) * dt
        if opt.hold_vertical:
            n2 = 0.0
        self.dv_sf = np.array([sx, sy, sz])
        if opt.update_position:
            self._pos_prev = np.array([lat, self.lon, h])
            a0, a1, a2 = 0.5 * (v0 + n0), 0.5 * (v1 + n1), 0.5 * (v2 + n2)
            h_avg = h + 0.25 * (v2 + n2) * dt
            lat_avg = lat + 0.5 * a1 / (RM + h_avg) * dt
            self.lat = lat + a1 / (RM + h_avg) * dt
            self.lon += a0 / ((RN + h_avg) * math.cos(lat_avg)) * dt
            self.h = h + a2 * dt
        return self._commit_scalar(C0, (zx, zy, zz), (fx, fy, fz), (n0, n1, n2),
                                   (ax, ay, az), (bx, by, bz))

    def _commit_scalar(self, C0, zeta, phi, v_new, dtheta, dv):
        """End of a scalar step: attitude update, history, returns ``C_b_n``."""
        C = _mm9(_mm9(_rodrigues9(-zeta[0], -zeta[1], -zeta[2]), C0), _rodrigues9(*phi))
        self._steps += 1
        self.C_b_n = orthonormal_if_needed(np.array(C).reshape(3, 3), self._steps, 1)
        self._v_prev = self.v_n
        self.v_n = np.array(v_new)
        self._dtheta_prev = np.array(dtheta)
        self._dv_prev = np.array(dv)
        return self.C_b_n

    def _earth_cache(self, lat, h):
        """``(sin, cos, tan, R_M, R_N, g)`` at ``lat``, ``h`` through the cache ``_ec`` (8,).

        Refreshed when the latitude moves by more than 1e-7 rad or the height by more than
        0.01 m (:func:`~.kernels.earth_terms`, which the compiled loop shares).
        """
        return kernels.earth_terms(lat, h, True, self._ec)

    def run(self, dtheta, dv, dt, as_step=False):
        """Process N samples and record the state after each.

        Parameters
        ----------
        dtheta, dv : ndarray (N, 3)
        dt : float or ndarray (N,)
        as_step : bool
            False: :meth:`update`'s arithmetic; True: :meth:`step`'s (its Earth-term
            cache, shared with it), so that a block and the same samples one
            :meth:`step` at a time give the same state to round-off.

        Returns
        -------
        dict with ``C_b_n`` (N, 3, 3), ``v_n`` (N, 3), ``pos`` (N, 3) as (lat, lon, h),
        and ``dv_sf`` (N, 3), each sample's specific-force increment in ENU.

        The loop is :func:`~.kernels.strapdown_run` (compiled), kept equal to
        :meth:`update` and :meth:`step` to round-off (test_mechanization.py).
        """
        # contiguous and writeable: numba compiles a separate version for read-only arrays
        # (a broadcast dt is one), which cost a live node a second at its first block
        dtheta = compiled.kernel_array(dtheta)
        dv = compiled.kernel_array(dv)
        n = len(dtheta)
        dt = np.asarray(dt, dtype=float)
        if dt.shape != (n,):              # one interval for every sample
            dt = np.broadcast_to(dt, (n,))
        dt = compiled.kernel_array(dt)
        out = {'C_b_n': np.empty((n, 3, 3)), 'v_n': np.empty((n, 3)), 'pos': np.empty((n, 3)),
               'dv_sf': np.empty((n, 3))}
        if n == 0:
            return out
        opt = self.options
        # copies: the kernel writes its state in place, and the history may share memory
        # with a caller's array (``update`` keeps references)
        state = [np.array(a, dtype=float) for a in (
            self.C_b_n, self.v_n, self._v_prev, self.position, self._pos_prev,
            self._dtheta_prev, self._dv_prev)]
        ec = self._ec if as_step else np.full(8, np.nan)
        self._steps = kernels.strapdown_run(
            *state, self._steps, dtheta, dv, dt, opt.transport_rate, opt.update_position,
            opt.coriolis, opt.hold_vertical, bool(as_step), ec, out['C_b_n'], out['v_n'],
            out['pos'], out['dv_sf'])
        (self.C_b_n, self.v_n, self._v_prev, pos, self._pos_prev, self._dtheta_prev,
         self._dv_prev) = state
        self.lat, self.lon, self.h = pos.tolist()
        self.dv_sf = out['dv_sf'][-1].copy()
        return out


def _exp_so3_batch(v):
    """Rodrigues for a stack of rotation vectors (N, 3) -> (N, 3, 3)."""
    a2 = np.einsum('ki,ki->k', v, v)
    small = a2 < 1e-12
    a = np.sqrt(np.where(small, 1.0, a2))
    s = np.where(small, 1.0 - a2 / 6.0, np.sin(a) / a)
    c = np.where(small, 0.5 - a2 / 24.0, (1.0 - np.cos(a)) / np.where(small, 1.0, a2))
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    out = np.empty((len(v), 3, 3))
    out[:, 0, 0] = 1.0 - c * (y * y + z * z)
    out[:, 0, 1] = c * x * y - s * z
    out[:, 0, 2] = c * x * z + s * y
    out[:, 1, 0] = c * x * y + s * z
    out[:, 1, 1] = 1.0 - c * (x * x + z * z)
    out[:, 1, 2] = c * y * z - s * x
    out[:, 2, 0] = c * x * z - s * y
    out[:, 2, 1] = c * y * z + s * x
    out[:, 2, 2] = 1.0 - c * (x * x + y * y)
    return out


def _cross_rows(a, b):
    """Row-wise cross product of (N, 3) arrays (faster than np.cross for small N)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def prefix_products(B):
    """Cumulative matrix products ``B_1, B_1 B_2, ..., B_1...B_N`` of (N, 3, 3).

    Hillis-Steele scan: log2(N) batched multiplications instead of N sequential ones.
    """
    P = np.array(B, dtype=float, copy=True)
    n, step = len(P), 1
    while step < n:
        nxt = P.copy()
        nxt[step:] = P[:-step] @ P[step:]
        P = nxt
        step *= 2
    return P


class StationaryStrapdown(Strapdown):
    """The stationary mechanization (seed 002 Table 1) vectorised over sample blocks.

    Same state and the same arithmetic as :class:`Strapdown` with
    ``MechanizationOptions.stationary(coriolis)``: because the navigation frame
    then turns only with the Earth (one fixed axis) the nav-side rotations of a
    block commute and collapse to one, and the body-side rotations are a prefix
    product (:func:`prefix_products`). ``run`` returns the state after every sample.
    """

    def __init__(self, C_b_n, lat, lon, h, coriolis=False, hold_vertical=True):
        opts = MechanizationOptions(transport_rate=False, update_position=False,
                                    coriolis=coriolis, hold_vertical=hold_vertical)
        super().__init__(C_b_n, np.zeros(3), lat, lon, h, opts)
        self._w_ie = earth.w_ie_n(self.lat)
        self._g_n = np.array([0.0, 0.0, -earth.gravity(self.lat, self.h)])

    def run(self, dtheta, dv, dt):
        """Process N samples; return ``{'C_b_n': (N, 3, 3), 'v_n': (N, 3)}``.

        ``dt`` is a float or (N,) array of sample intervals. With the compiled kernels
        this is :meth:`Strapdown.run`'s loop (the stationary filters give blocks of a
        few samples, where a compiled loop is several times faster than numpy's batched
        calls); without, :meth:`run_vectorised`. The two agree to round-off
        (test_mechanization.py).
        """
        if compiled.COMPILED:
            out = Strapdown.run(self, dtheta, dv, dt)
            return {'C_b_n': out['C_b_n'], 'v_n': out['v_n']}
        return self.run_vectorised(dtheta, dv, dt)

    def run_vectorised(self, dtheta, dv, dt):
        """:meth:`run` in numpy batch operations (prefix products), without numba."""
        dtheta = np.asarray(dtheta, dtype=float)
        dv = np.asarray(dv, dtype=float)
        n = len(dtheta)
        dt = np.broadcast_to(np.asarray(dt, dtype=float), (n,))
        dth_p = np.vstack([self._dtheta_prev[None], dtheta[:-1]])
        dv_p = np.vstack([self._dv_prev[None], dv[:-1]])
        phi = dtheta + _cross_rows(dth_p, dtheta) / 12.0
        rot = _cross_rows(dtheta, dv)
        dv_b = (dv + 0.5 * rot + _cross_rows(dtheta, rot) / 6.0
                + (_cross_rows(dth_p, dv) + _cross_rows(dv_p, dtheta)) / 12.0)
        zeta = self._w_ie[None, :] * dt[:, None]
        body = prefix_products(_exp_so3_batch(phi))
        nav = _exp_so3_batch(-np.cumsum(zeta, axis=0))
        C = np.einsum('kij,jl,klm->kim', nav, self.C_b_n, body)
        C_prev = np.concatenate([self.C_b_n[None], C[:-1]])
        dv_sf = np.einsum('kij,kj->ki', C_prev, dv_b)
        dv_sf = dv_sf - 0.5 * _cross_rows(zeta, dv_sf)
        dv_tot = dv_sf + self._g_n[None, :] * dt[:, None]
        if self.options.coriolis:
            V = np.empty((n, 3))
            v, v_prev = self.v_n.copy(), self._v_prev.copy()
            two_w = 2.0 * self._w_ie
            for k in range(n):
                v_mid = 1.5 * v - 0.5 * v_prev
                v_new = v + dv_tot[k] - _cross(two_w, v_mid) * dt[k]
                if self.options.hold_vertical:
                    v_new[2] = 0.0
                v_prev, v = v, v_new
                V[k] = v
        else:
            if self.options.hold_vertical:
                dv_tot[:, 2] = 0.0
            V = self.v_n[None, :] + np.cumsum(dv_tot, axis=0)
        self._v_prev = V[-2].copy() if n > 1 else self.v_n.copy()
        self.v_n = V[-1].copy()
        self.C_b_n = orthonormal_if_needed(C[-1], self._steps + n, n)
        self._steps += n
        self._dtheta_prev = dtheta[-1].copy()
        self._dv_prev = dv[-1].copy()
        return {'C_b_n': C, 'v_n': V}

    def step(self, dtheta, dv, dt):
        """One sample with scalar float arithmetic: the live node's per-message path.

        The same equations as :meth:`run` (a test keeps them equal to round-off),
        about ten times faster than numpy for a single sample.
        Returns the new ``C_b_n`` (3, 3).
        """
        ax, ay, az, bx, by, bz, fx, fy, fz, ux, uy, uz = _coning_sculling(
            dtheta, dv, self._dtheta_prev, self._dv_prev)
        wx, wy, wz = self._w_ie.tolist()
        zx, zy, zz = wx * dt, wy * dt, wz * dt
        C0 = self.C_b_n.ravel().tolist()
        sx, sy, sz = _nav_specific_force(C0, ux, uy, uz, zx, zy, zz)
        g = self._g_n[2]
        v0, v1, v2 = self.v_n.tolist()
        n0, n1, n2 = v0 + sx, v1 + sy, v2 + sz + g * dt
        if self.options.coriolis:
            m0, m1, m2 = (1.5 * v0 - 0.5 * self._v_prev[0], 1.5 * v1 - 0.5 * self._v_prev[1],
                          1.5 * v2 - 0.5 * self._v_prev[2])
            n0 -= 2.0 * (wy * m2 - wz * m1) * dt
            n1 -= 2.0 * (wz * m0 - wx * m2) * dt
            n2 -= 2.0 * (wx * m1 - wy * m0) * dt
        if self.options.hold_vertical:
            n2 = 0.0
        return self._commit_scalar(C0, (zx, zy, zz), (fx, fy, fz), (n0, n1, n2),
                                   (ax, ay, az), (bx, by, bz))


def _coning_sculling(dtheta, dv, dtheta_prev, dv_prev):
    """Scalar coning and rotation/sculling terms of one sample (the scalar fast paths).

    Returns the 12 floats ``dtheta (3), dv (3), phi (3), dv_b (3)`` of the module
    docstring's coning and rotation + sculling formulas.
    """
    ax, ay, az = float(dtheta[0]), float(dtheta[1]), float(dtheta[2])
    bx, by, bz = float(dv[0]), float(dv[1]), float(dv[2])
    px, py, pz = dtheta_prev.tolist()
    qx, qy, qz = dv_prev.tolist()
    fx, fy, fz, ux, uy, uz = kernels.coning_sculling(ax, ay, az, bx, by, bz,
                                                     px, py, pz, qx, qy, qz)
    return ax, ay, az, bx, by, bz, fx, fy, fz, ux, uy, uz


def _nav_specific_force(C0, ux, uy, uz, zx, zy, zz):
    """Scalar ``(I - [zeta x]/2) C_b_n dv_b``: the specific-force increment in ENU.

    ``C0`` is ``C_b_n`` as a row-major 9-sequence, ``u`` the compensated body
    increment, ``z`` the nav-frame rotation ``zeta`` of the interval.
    """
    sx = C0[0] * ux + C0[1] * uy + C0[2] * uz
    sy = C0[3] * ux + C0[4] * uy + C0[5] * uz
    sz = C0[6] * ux + C0[7] * uy + C0[8] * uz
    return (sx - 0.5 * (zy * sz - zz * sy), sy - 0.5 * (zz * sx - zx * sz),
            sz - 0.5 * (zx * sy - zy * sx))


def _mm9(A, B):
    """Product of two row-major 3x3 matrices given as 9-sequences."""
    return (A[0] * B[0] + A[1] * B[3] + A[2] * B[6], A[0] * B[1] + A[1] * B[4] + A[2] * B[7],
            A[0] * B[2] + A[1] * B[5] + A[2] * B[8],
            A[3] * B[0] + A[4] * B[3] + A[5] * B[6], A[3] * B[1] + A[4] * B[4] + A[5] * B[7],
            A[3] * B[2] + A[4] * B[5] + A[5] * B[8],
            A[6] * B[0] + A[7] * B[3] + A[8] * B[6], A[6] * B[1] + A[7] * B[4] + A[8] * B[7],
            A[6] * B[2] + A[7] * B[5] + A[8] * B[8])


def orthonormal_if_needed(C, steps, n):
    """Re-orthonormalise ``C`` when a multiple of 1000 steps was crossed."""
    if (steps // 1000) != ((steps - n) // 1000):
        u, _, vt = np.linalg.svd(C)
        return u @ vt
    return C

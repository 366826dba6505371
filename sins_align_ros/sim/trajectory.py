"""Trajectories with closed-form attitude, velocity and acceleration.

A :class:`Trajectory` is a base motion — along-track speed ``V``, course ``chi``
(clockwise from north) and flight-path angle ``gamma`` driven by a list of
:class:`Segment` rates with smooth raised-cosine ramps — plus optional
sinusoidal sway of the attitude and linear oscillation (surge, sway, heave) of
the position. Everything except the geodetic position is evaluated in closed
form at any time; the position is the integral of the velocity on the WGS-84
ellipsoid (:class:`PositionIntegrator`, an 8th-order Dormand-Prince solve with
relative tolerance 1e-12, i.e. sub-millimetre).

Attitude of the base: heading = course, pitch (nose up) = flight-path angle,
roll = 0 or the coordinated-turn bank ``atan(V chi'/g0)``; sway terms are added
to these angles (seed 000 sec. 4.1 models ship sway this way). Outputs are
REP-103 Euler angles of the FLU body in ENU (see :mod:`sins_align_ros.nav.frames`).
"""
import bisect
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from ..nav import earth
from ..nav.frames import nav_to_euler
from ..units import DEG, G0


@dataclass(frozen=True)
class Segment:
    """A manoeuvre of ``duration`` seconds with constant plateau rates.

    Attributes
    ----------
    duration : float
        s.
    accel : float
        Along-track acceleration on the plateau, m/s^2.
    turn_rate : float
        Course rate on the plateau, deg/s (positive turns clockwise seen from above).
    climb_rate : float
        Flight-path angle rate on the plateau, deg/s (positive pitches up).
    ramp : float or None
        Raised-cosine ramp time at both ends, s; default ``min(2, duration/4)``.
    """

    duration: float
    accel: float = 0.0
    turn_rate: float = 0.0
    climb_rate: float = 0.0
    ramp: float = None

    @property
    def ramp_s(self):
        r = min(2.0, self.duration / 4.0) if self.ramp is None else self.ramp
        if not 0.0 < r <= self.duration / 2.0:
            raise ValueError(f'segment ramp {r} s must be in (0, duration/2]')
        return r


@dataclass(frozen=True)
class Sway:
    """Sinusoidal attitude sway (deg, s, rad) and linear oscillation (m, s).

    ``roll += roll_amp sin(2 pi t / roll_period + roll_phase)`` and the same for
    pitch (nose up) and heading. Surge is along the initial course, sway to its
    right, heave up.
    """

    roll_amp: float = 0.0
    roll_period: float = 1.0
    roll_phase: float = 0.0
    pitch_amp: float = 0.0
    pitch_period: float = 1.0
    pitch_phase: float = 0.0
    yaw_amp: float = 0.0
    yaw_period: float = 1.0
    yaw_phase: float = 0.0
    surge_amp: float = 0.0
    surge_period: float = 1.0
    sway_amp: float = 0.0
    sway_period: float = 1.0
    heave_amp: float = 0.0
    heave_period: float = 1.0


def _ramp_profile(tau, D, r):
    """Shape s(tau), its integral S(tau) and derivative s'(tau) of one segment.

    s rises from 0 to 1 over ``r`` as ``(1 - cos(pi tau / r))/2``, stays at 1 and
    falls symmetrically at the end; zero outside [0, D]. ``D`` and ``r`` are scalars
    or arrays like ``tau`` (one segment per time).
    """
    tau = np.asarray(tau, dtype=float)
    D = np.broadcast_to(D, tau.shape)
    r = np.broadcast_to(r, tau.shape)
    s = np.zeros_like(tau)
    S = np.zeros_like(tau)
    ds = np.zeros_like(tau)
    k = np.pi / r
    up = (tau >= 0.0) & (tau < r)
    mid = (tau >= r) & (tau <= D - r)
    down = (tau > D - r) & (tau <= D)
    after = tau > D
    ku = k[up]
    s[up] = 0.5 * (1.0 - np.cos(ku * tau[up]))
    S[up] = 0.5 * (tau[up] - np.sin(ku * tau[up]) / ku)
    ds[up] = 0.5 * ku * np.sin(ku * tau[up])
    s[mid] = 1.0
    S[mid] = 0.5 * r[mid] + (tau[mid] - r[mid])
    kd, Dd = k[down], D[down]
    u = Dd - tau[down]
    s[down] = 0.5 * (1.0 - np.cos(kd * u))
    S[down] = (Dd - r[down]) - 0.5 * (u - np.sin(kd * u) / kd)
    ds[down] = -0.5 * kd * np.sin(kd * u)
    S[after] = D[after] - r[after]
    return s, S, ds


def _ramp_integral(tau, D, r):
    """S(tau) of :func:`_ramp_profile` for one time (floats), in scalar arithmetic."""
    if tau < 0.0:
        return 0.0
    k = math.pi / r
    if tau < r:
        return 0.5 * (tau - math.sin(k * tau) / k)
    if tau <= D - r:
        return 0.5 * r + (tau - r)
    if tau <= D:
        u = D - tau
        return (D - r) - 0.5 * (u - math.sin(k * u) / k)
    return D - r


@dataclass
class Kinematics:
    """Closed-form kinematics at times ``t`` (N,).

    ``v_n``, ``a_n``: ENU velocity and its derivative (N, 3); ``euler``,
    ``euler_rate``: REP-103 ``[roll, pitch, yaw]`` and derivatives (N, 3).
    """

    t: np.ndarray
    v_n: np.ndarray
    a_n: np.ndarray
    euler: np.ndarray
    euler_rate: np.ndarray


class _Tables:
    """What :meth:`Trajectory._base` and :meth:`Trajectory.velocity` need, computed once.

    Segment rows: two null segments (start -inf, no rates: every time is after them),
    then each segment with a non-zero rate in order. ``t0``, ``D``, ``r`` (s), ``accel``
    (m/s^2), ``turn``, ``climb`` (rad/s) per row; ``V0``, ``chi0``, ``gam0``: speed,
    course and flight-path angle before row ``i`` plus the whole integrals of rows
    ``< i``, summed in row order (the order of adding every segment in turn).
    ``t0_list``, ``rows`` and ``base_list`` hold the same as Python floats for one time
    at a time. ``oscillations``: ``(amp, w, axis)`` of each non-zero linear oscillation
    of the sway, m, rad/s, ENU unit vector (3,).
    """

    def __init__(self, traj):
        starts = np.concatenate([[0.0], np.cumsum([s.duration for s in traj.segments])])
        moving = [(t0, seg) for seg, t0 in zip(traj.segments, starts[:-1])
                  if seg.accel or seg.turn_rate or seg.climb_rate]
        null = (-np.inf, 1.0, 0.25, 0.0, 0.0, 0.0)
        rows = [null, null] + [(float(t0), seg.duration, seg.ramp_s, seg.accel,
                                seg.turn_rate * DEG, seg.climb_rate * DEG)
                               for t0, seg in moving]
        self.t0, self.D, self.r, self.accel, self.turn, self.climb = np.array(rows).T
        whole = self.D - self.r                                   # S after a segment
        self.V0 = np.cumsum(np.concatenate([[traj.speed], self.accel * whole]))
        self.chi0 = np.cumsum(np.concatenate([[traj.heading_deg * DEG], self.turn * whole]))
        self.gam0 = np.cumsum(np.concatenate([[0.0], self.climb * whole]))
        self.rows = [tuple(map(float, row)) for row in rows]
        self.t0_list = [row[0] for row in self.rows]
        self.base_list = list(zip(self.V0.tolist(), self.chi0.tolist(), self.gam0.tolist()))
        self.oscillations = ()
        sw = traj.sway
        if sw is not None:
            c0 = traj.heading_deg * DEG
            self.oscillations = tuple(
                (amp, 2.0 * np.pi / per, axis) for amp, per, axis in (
                    (sw.surge_amp, sw.surge_period, np.array([np.sin(c0), np.cos(c0), 0.0])),
                    (sw.sway_amp, sw.sway_period, np.array([np.cos(c0), -np.sin(c0), 0.0])),
                    (sw.heave_amp, sw.heave_period, np.array([0.0, 0.0, 1.0])))
                if amp)


@dataclass
class Trajectory:
    """A base motion with optional sway; see the module docstring.

    Attributes
    ----------
    lat_deg, lon_deg, h : float
        Initial position.
    heading_deg : float
        Initial course/heading, clockwise from north.
    speed : float
        Initial along-track speed, m/s.
    pitch_deg, roll_deg : float
        Constant attitude offsets added to the base attitude (a static IMU that is
        not level, for instance).
    segments : list of Segment
        Manoeuvres in sequence from t = 0; after the last one the rates are zero.
    sway : Sway or None
    coordinated_bank : bool
        Bank into turns as an aircraft does (roll = atan(V chi'/g0)).
    current_mps : (2,)
        A current (or wind) carrying the vehicle, east and north, m/s: the velocity is
        the base motion's (through the water, along the heading) plus this, so the
        course over ground is off the heading by a crab angle that changes with the
        heading (a boat in a current; issue 44's course heading aid must not take it
        for a heading).
    name : str
    """

    lat_deg: float
    lon_deg: float
    h: float = 0.0
    heading_deg: float = 0.0
    speed: float = 0.0
    pitch_deg: float = 0.0
    roll_deg: float = 0.0
    segments: list = field(default_factory=list)
    sway: Sway = None
    coordinated_bank: bool = False
    current_mps: tuple = (0.0, 0.0)
    name: str = ''

    def __setattr__(self, name, value):
        object.__setattr__(self, name, value)
        self.__dict__.pop('_derived', None)      # a field was set (benches set heading_deg)

    def __getstate__(self):
        state = dict(self.__dict__)
        state.pop('_derived', None)              # pickles (cache keys) as the fields alone
        if not any(state.get('current_mps', ())):
            state.pop('current_mps', None)       # no current: the keys of before it existed
        return state

    @property
    def _tables(self):
        """:class:`_Tables` of the current fields, computed on first use.

        Setting a field computes them again; change ``segments`` by assigning a new
        list, not in place.
        """
        tables = self.__dict__.get('_derived')
        if tables is None:
            tables = self.__dict__['_derived'] = _Tables(self)
        return tables

    @property
    def initial_position(self):
        """``[lat, lon, h]`` at t = 0 (rad, rad, m)."""
        return np.array([self.lat_deg * DEG, self.lon_deg * DEG, self.h])

    @property
    def moves(self):
        """True if the trajectory ever translates (not only sways in place)."""
        sw = self.sway
        osc = sw is not None and (sw.surge_amp or sw.sway_amp or sw.heave_amp)
        return bool(self.speed or osc or any(s.accel for s in self.segments)
                    or any(self.current_mps))

    def _base(self, t):
        """Speed, course, flight-path angle and their first/second derivatives at ``t`` (N,).

        Only the segment under way at each time and the one before it (which a time
        on their common boundary may still reach by a rounding of the start times)
        are evaluated; every earlier segment adds its whole integral, kept summed in
        the tables (:class:`_Tables`) in the order of the segments, a later one adds nothing.
        The sums are thus those of adding every segment's profile in turn.
        """
        tab = self._tables
        k = np.searchsorted(tab.t0, t, side='right') - 1       # >= 1: two leading nulls
        V, chi, gam = tab.V0[k - 1], tab.chi0[k - 1], tab.gam0[k - 1]
        dV = np.zeros_like(t)
        dchi = np.zeros_like(t)
        ddchi = np.zeros_like(t)
        dgam = np.zeros_like(t)
        for j in (k - 1, k):
            s, S, ds = _ramp_profile(t - tab.t0[j], tab.D[j], tab.r[j])
            a, w, c = tab.accel[j], tab.turn[j], tab.climb[j]
            V = V + a * S
            dV += a * s
            chi = chi + w * S
            dchi += w * s
            ddchi += w * ds
            gam = gam + c * S
            dgam += c * s
        return V, dV, chi, dchi, ddchi, gam, dgam

    def _base_at(self, t):
        """``V, chi, gam`` of :meth:`_base` at one time ``t`` (floats), scalar arithmetic."""
        tab = self._tables
        k = bisect.bisect_right(tab.t0_list, t) - 1
        V, chi, gam = tab.base_list[k - 1]
        for j in (k - 1, k):
            t0, D, r, a, w, c = tab.rows[j]
            S = _ramp_integral(t - t0, D, r)
            V += a * S
            chi += w * S
            gam += c * S
        return V, chi, gam

    def velocity(self, t):
        """Return the ENU ``v_n`` of :meth:`kinematics` at one time ``t`` (s): (3,), m/s.

        The position ODE asks for one time thousands of times; this evaluates the same
        formulas in scalar arithmetic, 100 times faster (equal to round-off, test_sim.py).
        """
        t = float(t)
        V, chi, gam = self._base_at(t)
        cg = math.cos(gam)
        v_n = np.array([V * (cg * math.sin(chi)), V * (cg * math.cos(chi)), V * math.sin(gam)])
        v_n[:2] += self.current_mps
        for amp, w, axis in self._tables.oscillations:
            v_n += (amp * w * math.cos(w * t)) * axis
        return v_n

    def kinematics(self, t):
        """Closed-form velocity, acceleration and attitude at times ``t`` (s), shape (N,)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        V, dV, chi, dchi, ddchi, gam, dgam = self._base(t)
        sc, cc, sg, cg = np.sin(chi), np.cos(chi), np.sin(gam), np.cos(gam)
        u = np.stack([cg * sc, cg * cc, sg], axis=-1)
        du = np.stack([-sg * dgam * sc + cg * cc * dchi,
                       -sg * dgam * cc - cg * sc * dchi,
                       cg * dgam], axis=-1)
        v_n = V[:, None] * u
        v_n[:, :2] += np.asarray(self.current_mps, dtype=float)
        a_n = dV[:, None] * u + V[:, None] * du

        roll = np.full_like(t, self.roll_deg * DEG)
        droll = np.zeros_like(t)
        if self.coordinated_bank:
            q = V * dchi / G0
            dq = (dV * dchi + V * ddchi) / G0
            roll += np.arctan(q)
            droll += dq / (1.0 + q * q)
        pitch = gam + self.pitch_deg * DEG
        dpitch = dgam.copy()
        heading = chi.copy()
        dheading = dchi.copy()

        sw = self.sway
        if sw is not None:
            for amp, per, ph, ang, dang in (
                    (sw.roll_amp, sw.roll_period, sw.roll_phase, roll, droll),
                    (sw.pitch_amp, sw.pitch_period, sw.pitch_phase, pitch, dpitch),
                    (sw.yaw_amp, sw.yaw_period, sw.yaw_phase, heading, dheading)):
                if amp:
                    w = 2.0 * np.pi / per
                    ang += amp * DEG * np.sin(w * t + ph)
                    dang += amp * DEG * w * np.cos(w * t + ph)
        for amp, w, axis in self._tables.oscillations:
            v_n = v_n + (amp * w * np.cos(w * t))[:, None] * axis
            a_n = a_n - (amp * w * w * np.sin(w * t))[:, None] * axis

        euler = nav_to_euler(roll, pitch, heading)
        euler_rate = np.stack([droll, -dpitch, -dheading], axis=-1)
        return Kinematics(t=t, v_n=v_n, a_n=a_n, euler=euler, euler_rate=euler_rate)


class PositionIntegrator:
    """Geodetic position of a trajectory, integrated chunk by chunk.

    ``advance(t_end)`` integrates from the current time to ``t_end`` and returns
    a callable giving ``(N, 3)`` positions ``[lat, lon, h]`` for times inside
    that chunk. A still trajectory skips the ODE.
    """

    #: DOP853's relative and absolute tolerances on ``[lat, lon, h]`` (rad, rad, m)
    RTOL = 1e-12
    ATOL = (1e-15, 1e-15, 1e-8)

    def __init__(self, traj, t0=0.0):
        self.traj = traj
        self.t = float(t0)
        self.y = traj.initial_position.astype(float)
        self._moves = traj.moves
        self.steps = 0   # DOP853 steps accepted so far (solver bounds in tests)

    def _rhs(self, t, y):
        return earth.position_rate(y[0], y[2], self.traj.velocity(t))

    def advance(self, t_end):
        """Integrate to ``t_end`` and return ``f(t) -> (N, 3)`` valid on [t_start, t_end]."""
        t_start, y0 = self.t, self.y.copy()
        if not self._moves or t_end <= t_start:
            self.t = max(t_end, t_start)
            return lambda t: np.tile(y0, (np.size(t), 1))
        sol = solve_ivp(self._rhs, (t_start, t_end), y0, method='DOP853',
                        rtol=self.RTOL, atol=list(self.ATOL), dense_output=True)
        if not sol.success:
            raise RuntimeError(f'position integration failed: {sol.message}')
        self.t = t_end
        self.y = sol.y[:, -1].copy()
        self.steps += len(sol.t) - 1
        dense = sol.sol
        return lambda t: dense(np.atleast_1d(t)).T

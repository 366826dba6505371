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
    falls symmetrically at the end; zero outside [0, D].
    """
    tau = np.asarray(tau, dtype=float)
    s = np.zeros_like(tau)
    S = np.zeros_like(tau)
    ds = np.zeros_like(tau)
    k = np.pi / r
    up = (tau >= 0.0) & (tau < r)
    mid = (tau >= r) & (tau <= D - r)
    down = (tau > D - r) & (tau <= D)
    after = tau > D
    s[up] = 0.5 * (1.0 - np.cos(k * tau[up]))
    S[up] = 0.5 * (tau[up] - np.sin(k * tau[up]) / k)
    ds[up] = 0.5 * k * np.sin(k * tau[up])
    s[mid] = 1.0
    S[mid] = 0.5 * r + (tau[mid] - r)
    u = D - tau[down]
    s[down] = 0.5 * (1.0 - np.cos(k * u))
    S[down] = (D - r) - 0.5 * (u - np.sin(k * u) / k)
    ds[down] = -0.5 * k * np.sin(k * u)
    S[after] = D - r
    return s, S, ds


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
    name: str = ''

    def __post_init__(self):
        starts = np.concatenate([[0.0], np.cumsum([s.duration for s in self.segments])])
        self._starts = starts[:-1]

    @property
    def initial_position(self):
        """``[lat, lon, h]`` at t = 0 (rad, rad, m)."""
        return np.array([self.lat_deg * DEG, self.lon_deg * DEG, self.h])

    @property
    def moves(self):
        """True if the trajectory ever translates (not only sways in place)."""
        sw = self.sway
        osc = sw is not None and (sw.surge_amp or sw.sway_amp or sw.heave_amp)
        return bool(self.speed or osc or any(s.accel for s in self.segments))

    def _base(self, t):
        """Speed, course, flight-path angle and their first/second derivatives."""
        V = np.full_like(t, self.speed)
        dV = np.zeros_like(t)
        chi = np.full_like(t, self.heading_deg * DEG)
        dchi = np.zeros_like(t)
        ddchi = np.zeros_like(t)
        gam = np.zeros_like(t)
        dgam = np.zeros_like(t)
        for seg, t0 in zip(self.segments, self._starts):
            if not (seg.accel or seg.turn_rate or seg.climb_rate):
                continue
            s, S, ds = _ramp_profile(t - t0, seg.duration, seg.ramp_s)
            V += seg.accel * S
            dV += seg.accel * s
            w = seg.turn_rate * DEG
            chi += w * S
            dchi += w * s
            ddchi += w * ds
            c = seg.climb_rate * DEG
            gam += c * S
            dgam += c * s
        return V, dV, chi, dchi, ddchi, gam, dgam

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
            c0 = self.heading_deg * DEG
            axes = (np.array([np.sin(c0), np.cos(c0), 0.0]),
                    np.array([np.cos(c0), -np.sin(c0), 0.0]),
                    np.array([0.0, 0.0, 1.0]))
            for amp, per, axis in ((sw.surge_amp, sw.surge_period, axes[0]),
                                   (sw.sway_amp, sw.sway_period, axes[1]),
                                   (sw.heave_amp, sw.heave_period, axes[2])):
                if amp:
                    w = 2.0 * np.pi / per
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

    def __init__(self, traj, t0=0.0):
        self.traj = traj
        self.t = float(t0)
        self.y = traj.initial_position.astype(float)
        self._moves = traj.moves

    def _rhs(self, t, y):
        v_n = self.traj.kinematics(t).v_n[0]
        return earth.position_rate(y[0], y[2], v_n)

    def advance(self, t_end):
        """Integrate to ``t_end`` and return ``f(t) -> (N, 3)`` valid on [t_start, t_end]."""
        t_start, y0 = self.t, self.y.copy()
        if not self._moves or t_end <= t_start:
            self.t = max(t_end, t_start)
            return lambda t: np.tile(y0, (np.size(t), 1))
        sol = solve_ivp(self._rhs, (t_start, t_end), y0, method='DOP853',
                        rtol=1e-12, atol=[1e-15, 1e-15, 1e-8], dense_output=True)
        if not sol.success:
            raise RuntimeError(f'position integration failed: {sol.message}')
        self.t = t_end
        self.y = sol.y[:, -1].copy()
        dense = sol.sol
        return lambda t: dense(np.atleast_1d(t)).T

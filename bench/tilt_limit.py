#!/usr/bin/env python3
"""Tilt sigma of the ideal linear estimator on ``robot:posonly`` (issue 44 "Useful").

Issue 44 asks the robot's tilt 1-sigma at the end to be at most 1.5 x the simulated
accelerometer bias / g (25.8' for ``mems``, 36.1' for ``mems_ahrs``). This script measures
what the *ideal* estimator reaches on the same data: a covariance-only analysis (no state
estimate) of a linearized error-state Kalman filter along the simulator's truth trajectory
of ``robot_skid`` (bench/integrity.py's cell ``robot:posonly``, built here as that file's
``scenario_of`` does, without importing it), with every simulated error a state and the
noises exactly the simulator's.

Model (ENU navigation frame, FLU body, ``C~_b_n = (I - [phi x]) C_b_n``)
--------------------------------------------------------------------------
Navigation block: :func:`sins_align_ros.models.loosely_coupled.F_matrix` (the phi-angle
model, position error in metres; its 15 states with constant gyro and accelerometer
biases), evaluated every IMU step (30 Hz) at the truth: attitude, velocity, position and
specific force at the middle of the step. Added states, where the grade has them:

- ``gm_g``, ``gm_a`` (3 each): the first-order Gauss-Markov biases (sigma, tau of the grade);
- ``sg``, ``sa`` (3 each): scale factors, ``mg``, ``ma`` (6 each): the off-diagonal axis
  misalignment entries ``M[i, j]`` (sim/imu.py: measured = (I + S + M) true + ...), so that
  ``d phi/dt += -C_b_n (S + M) w_ib_b`` and ``d dV/dt += C_b_n (S_a + M_a) f_b``;
- ``gnss`` (3): the receiver's Gauss-Markov position error (sigma 1.5 m, tau 60 s); its
  white part (0.8 m horizontal, 1.6 m vertical) is R;
- ``vx``, ``vy`` (3 each): the vibration (below).

Process noise: the grade's angle and velocity random walks, the Markov drives
``sigma^2 (1 - phi^2)`` per step (exact discretization). The transition over a step is
``I + F dt + (F dt)^2 / 2``; the GNSS positions (every 12th step, 2.5 Hz) update P with
the Joseph form.

Vibration (sim/imu.py ``ImuErrors._vibration``)
-----------------------------------------------
The simulator adds to sample ``k``'s angle increment ``g_k x_k - g_{k-1} x_{k-1}``, with
``x`` a discrete first-order Gauss-Markov angle (``phi_v = exp(-dt / 0.05 s) = 0.5134`` at
30 Hz, sigma ``s_x = A dt / sqrt(2 (1 - phi_v))``, ``A`` = 3 deg/s, so that the increments'
RMS is ``A dt``) and ``g`` the speed gain (1 above 0.5 m/s: always, here). Likewise the
velocity increment with ``A`` = 1.5 m/s^2. A white noise with the same per-sample RMS would
have the density ``A^2 dt``: sqrt = 0.548 deg/sqrt(s) = 32.9 deg/sqrt(h) for the gyro,
0.274 m/s/sqrt(s) = 27.9 mg/sqrt(Hz) for the accelerometer, 11 and 78 times the plain MEMS
grade's ARW and VRW. But the increments are *differences*: their sum over any span is
``g_k x_k - g_0 x_0``, bounded by ``s_x`` = 6.08' (angle) and 5.07 cm/s (velocity), so their
density at frequencies below ``1 / tau`` is zero: as a white noise the vibration would be a
random walk reaching 11 deg of tilt in 400 s, the simulated one never leaves 6' (one axis,
one sigma). The ideal estimator therefore carries ``x`` and ``y`` as states (exact
discrete transition, per step)::

    x_k = phi_v x_{k-1} + w_k,   phi_k = ... - C_b_n (g_k x_k - g_{k-1} x_{k-1})

(and the same for ``y`` on the velocity error, sign +). What remains of the vibration is
then (a) the attitude jitter ``-C_b_n g x`` itself, sigma 6.08' per axis, in the total
tilt error at any instant (we report the total; the column "no jitter" is the attitude
error without it, ``phi + C_b_n g x``), (b) the jitter's tilt rotating the specific force:
``f x phi`` with ``phi`` a 0.05-s process, i.e. a velocity random walk of low-frequency
density ``g^2 s_x^2 dt (1 + phi_v) / (1 - phi_v)`` (sqrt 5.6 mm/s/sqrt(s) = 570 ug/sqrt(Hz),
1.6 times the plain MEMS VRW), and (c) during turns the body rotation between steps,
which keeps the summed increments from cancelling exactly (a gyro noise of density about
``|w|^2 s_x^2 0.104 s``, about 1 deg/sqrt(h) at 30 deg/s). All three are in the exact model
above. The variant ``vibwhite`` takes the vibration as the white noise of the same
per-sample RMS instead (the density ``A^2 dt`` above), to show what that assumption costs.

Variants (``--variants``): ``base`` (the cell as simulated); ``vel`` (GNSS velocity too,
the ``consumer`` receiver's 0.08 m/s white, at the same 2.5 Hz epochs); ``white`` (the
GNSS position error white only: no Gauss-Markov part); ``novib`` (no vibration);
``vibwhite`` (vibration as white noise); ``prior`` (the second attitude prior).
Priors: ``A`` = 2 deg tilt, 10 deg heading (1 sigma); ``B`` = 0.5 deg tilt, 3 deg heading.
Velocity 1 m/s, position 3 m per axis; every sensor state its grade's 1-sigma (for the
``mems`` grade, whose errors the simulator applies as given rather than drawn, that value
is taken as the 1-sigma of an unknown constant, as the filters are told).

The covariance depends on the trajectory only, not on the noise drawn: the seeds (1000,
1001, 1002 by default) give the same P; the page says so after comparing them, and lists
each seed's drawn accelerometer errors (the horizontal part a level robot cannot tell from
a tilt: bias plus misalignment under gravity).

Usage: python bench/tilt_limit.py [--grades mems,mems_ahrs] [--seeds 1000,1001,1002]
       [--variants base,vel,white,novib,vibwhite,prior] [--out bench/results/tilt_limit.md]
"""
import argparse
import math
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))      # this checkout's package, not an installed copy

from sins_align_ros.eval.markdown import machine_summary, write_markdown  # noqa: E402
from sins_align_ros.models import loosely_coupled as lc  # noqa: E402
from sins_align_ros.nav import earth  # noqa: E402
from sins_align_ros.nav.frames import euler_to_dcm  # noqa: E402
from sins_align_ros.sim.gnss import GnssSpec  # noqa: E402
from sins_align_ros.sim.imu import ideal_increments  # noqa: E402
from sins_align_ros.sim.presets import SENSOR_GRADES, scenario  # noqa: E402
from sins_align_ros.sim.scenario import ScenarioStream  # noqa: E402
from sins_align_ros.sim.trajectory import PositionIntegrator  # noqa: E402
from sins_align_ros.units import ARCMIN, DEG, DPH, DPSH, UG  # noqa: E402

#: bench/integrity.py GROUND_GNSS['posonly'] (copied: that module imports align/)
POSONLY = GnssSpec(rate_hz=2.5, pos_sigma_h=0.8, pos_sigma_v=1.6, pos_markov_sigma=1.5,
                   pos_markov_tau_s=60.0, vel_sigma=0.1, velocity=False,
                   reported_pos_sigma_h=0.9, reported_pos_sigma_v=1.8)
#: bench/integrity.py GROUND_GNSS['consumer'].vel_sigma: Doppler velocity white noise, m/s
CONSUMER_VEL_SIGMA = 0.08
#: bench/integrity.py: USEFUL_TILT_BY_BIAS, the robot cell's duration (s), FIRST_SEED
USEFUL_TILT_BY_BIAS = 1.5
DURATION_S = 400.0
SEEDS = (1000, 1001, 1002)
GRADES = ('mems', 'mems_ahrs')
REPORT_S = (60.0, 120.0, 200.0, 300.0, 400.0)
#: attitude priors (1 sigma, deg): tilt (E and N), heading
PRIORS = {'A': (2.0, 10.0), 'B': (0.5, 3.0)}
VEL_PRIOR_MPS = 1.0
POS_PRIOR_M = 3.0
VARIANTS = {
    'base': 'as simulated: positions only, white + Gauss-Markov, vibration',
    'vel': 'plus GNSS velocity, 0.08 m/s white (the consumer receiver\'s)',
    'white': 'GNSS position error white only (no Gauss-Markov part)',
    'novib': 'no vibration',
    'vibwhite': 'vibration as white noise of the same per-sample RMS',
    'prior': 'attitude prior B (0.5 deg tilt, 3 deg heading)',
}
#: the off-diagonal entries (i, j) of a misalignment matrix, in state order
OFF_DIAGONAL = tuple((i, j) for i in range(3) for j in range(3) if i != j)


def cell(grade, duration=DURATION_S):
    """Return scenario ``robot:posonly`` with the IMU of ``grade`` (bench/integrity.py's cell).

    ``robot_skid``'s trajectory and IMU rate, the grade's sensor errors with
    ``robot_skid``'s vibration kept, the position-only receiver.
    """
    sc = scenario('robot_skid', duration=duration)
    vib = {k: v for k, v in vars(sc.imu).items() if k.startswith('vibration_')}
    sc.imu = SENSOR_GRADES[grade].with_(**vib)
    sc.gnss = POSONLY
    return sc


@dataclass
class Truth:
    """The truth along a trajectory, per IMU step ``k`` (interval ``[t_k, t_k+1]``).

    ``dt`` (s); ``t`` (N,) the steps' end times; ``C_b_n`` (N, 3, 3), ``f_n``, ``v_n`` (N, 3),
    ``lat``, ``h`` (N,) at the middle of each step; ``f_b``, ``w_ib_b`` (N, 3) the means
    over each step (the ideal increments / dt); ``gain`` (N,) the vibration's speed gain at
    the steps' ends (sim/imu.py: ``min(1, speed / full_speed)``, 1 without a full speed).
    """

    dt: float
    t: np.ndarray
    C_b_n: np.ndarray
    f_n: np.ndarray
    v_n: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    f_b: np.ndarray
    w_ib_b: np.ndarray
    gain: np.ndarray


def truth_of(traj, rate_hz, duration, vibration_full_speed_mps=0.0):
    """Return the :class:`Truth` of ``traj`` sampled at ``rate_hz`` for ``duration`` s.

    The increments are sim/imu.py's exact ones (``ideal_increments``), the same integrals
    the simulator corrupts, so ``f_b`` and ``w_ib_b`` are the truth the sensors see.
    """
    n = int(round(duration * rate_hz))
    dt = 1.0 / rate_hz
    t_grid = np.arange(n + 1) * dt
    pos_fn = PositionIntegrator(traj).advance(t_grid[-1])
    dtheta, dv = ideal_increments(traj, t_grid, pos_fn)
    t_mid = 0.5 * (t_grid[:-1] + t_grid[1:])
    kin = traj.kinematics(t_mid)
    pos = pos_fn(t_mid)
    C = euler_to_dcm(kin.euler)
    f_b = dv / dt
    speed = np.hypot(*traj.kinematics(t_grid[1:]).v_n[:, :2].T)
    gain = (np.ones(n) if vibration_full_speed_mps <= 0.0
            else np.minimum(1.0, speed / vibration_full_speed_mps))
    return Truth(dt=dt, t=t_grid[1:], C_b_n=C, f_n=np.einsum('kij,kj->ki', C, f_b),
                 v_n=kin.v_n, lat=pos[:, 0], h=pos[:, 2], f_b=f_b, w_ib_b=dtheta / dt,
                 gain=gain)


class Layout:
    """State vector of the ideal filter for an IMU ``spec`` and receiver ``gnss``.

    The first 15 states are models/loosely_coupled.py's (phi, dV, dp, gyro bias,
    accelerometer bias); the others are added where the simulated errors exist:
    attributes ``gm_g``, ``gm_a``, ``sg``, ``mg``, ``sa``, ``ma``, ``gnss``, ``vx``, ``vy``
    are slices, or None. ``vibration``: carry the vibration as states (else as white
    noise, ``vib_white``, or not at all when the spec has none).
    """

    def __init__(self, spec, gnss, vibration='states'):
        self.n = 15
        self.spec, self.gnss_spec = spec, gnss
        has_vib = bool(spec.vibration_gyro_dps or spec.vibration_accel_mps2)
        self.vib_states = has_vib and vibration == 'states'
        self.vib_white = has_vib and vibration == 'white'
        self.gm_g = self._add(3, spec.gyro_markov_dph > 0.0)
        self.gm_a = self._add(3, spec.accel_markov_ug > 0.0)
        self.sg = self._add(3, np.any(spec.gyro_scale_ppm))
        self.mg = self._add(6, np.any(spec.gyro_misalign_ppm))
        self.sa = self._add(3, np.any(spec.accel_scale_ppm))
        self.ma = self._add(6, np.any(spec.accel_misalign_ppm))
        self.gnss = self._add(3, gnss.pos_markov_sigma > 0.0)
        self.vx = self._add(3, self.vib_states)
        self.vy = self._add(3, self.vib_states)

    def _add(self, size, present):
        if not present:
            return None
        s = slice(self.n, self.n + size)
        self.n += size
        return s


def _vibration_figures(spec, dt):
    """Discrete vibration model of sim/imu.py: ``(phi_v, s_x rad, s_y m/s)``."""
    phi = math.exp(-dt / spec.vibration_tau_s)
    k = dt / math.sqrt(2.0 * (1.0 - phi))
    return phi, spec.vibration_gyro_dps * DEG * k, spec.vibration_accel_mps2 * k


def _misalign_sigma(value):
    """Return the six off-diagonal 1-sigmas (dimensionless) of a ``*_misalign_ppm`` value."""
    m = np.broadcast_to(np.asarray(value, dtype=float), (3, 3)) * 1e-6
    return np.array([m[i, j] for i, j in OFF_DIAGONAL])


def initial_P(lay, tilt_deg, heading_deg, dt):
    """Return the initial covariance (n, n): the attitude prior, each state's true 1-sigma."""
    s, g = lay.spec, lay.gnss_spec
    sig = np.zeros(lay.n)
    sig[0:3] = np.array([tilt_deg, tilt_deg, heading_deg]) * DEG
    sig[3:6] = VEL_PRIOR_MPS
    sig[6:9] = POS_PRIOR_M
    sig[9:12] = np.abs(np.broadcast_to(s.gyro_bias_dph, (3,))) * DPH
    sig[12:15] = np.abs(np.broadcast_to(s.accel_bias_ug, (3,))) * UG
    for sl, value in ((lay.gm_g, s.gyro_markov_dph * DPH), (lay.gm_a, s.accel_markov_ug * UG),
                      (lay.sg, np.abs(np.broadcast_to(s.gyro_scale_ppm, (3,))) * 1e-6),
                      (lay.sa, np.abs(np.broadcast_to(s.accel_scale_ppm, (3,))) * 1e-6),
                      (lay.mg, np.abs(_misalign_sigma(s.gyro_misalign_ppm))),
                      (lay.ma, np.abs(_misalign_sigma(s.accel_misalign_ppm))),
                      (lay.gnss, g.pos_markov_sigma)):
        if sl is not None:
            sig[sl] = value
    if lay.vib_states:
        _, s_x, s_y = _vibration_figures(s, dt)
        sig[lay.vx], sig[lay.vy] = s_x, s_y
    return np.diag(sig * sig)


@dataclass
class Result:
    """Sigmas at the report times.

    ``t`` (M,); ``phi`` (M, 3) rad (E, N, U: the total attitude error); ``phi_slow``
    (M, 3) rad (without the vibration's jitter; equal to ``phi`` without vibration
    states); ``accel_bias`` (M, 3) m/s^2 (body x, y, z).
    """

    t: np.ndarray
    phi: np.ndarray
    phi_slow: np.ndarray
    accel_bias: np.ndarray


def run(truth, spec, gnss, report_s, prior=PRIORS['A'], velocity_sigma=None,
        vibration='states'):
    """Propagate and update the ideal filter's P along ``truth``; return a :class:`Result`.

    ``spec``: the simulated :class:`~sins_align_ros.sim.imu.ImuSpec`; ``gnss``: the
    receiver's :class:`~sins_align_ros.sim.gnss.GnssSpec` (its rate must divide the IMU
    rate); ``report_s`` times (s) to report at (after that epoch's update);
    ``prior`` (tilt deg, heading deg); ``velocity_sigma`` (m/s): also measure the velocity
    with this white noise at every epoch (None: positions only); ``vibration``
    ``'states'`` (exact) or ``'white'`` (see the module docstring).
    """
    dt = truth.dt
    lay = Layout(spec, gnss, vibration)
    n = lay.n
    P = initial_P(lay, prior[0], prior[1], dt)
    eye = np.eye(n)
    every = int(round(1.0 / (gnss.rate_hz * dt)))
    if abs(every * gnss.rate_hz * dt - 1.0) > 1e-9:
        raise ValueError('the GNSS rate must divide the IMU rate')
    # measurement: position error minus the receiver's Markov error, R its white part
    rows = 6 if velocity_sigma is not None else 3
    H = np.zeros((rows, n))
    H[0:3, 6:9] = np.eye(3)
    if lay.gnss is not None:
        H[0:3, lay.gnss] = -np.eye(3)
    R_diag = [gnss.pos_sigma_h ** 2, gnss.pos_sigma_h ** 2, gnss.pos_sigma_v ** 2]
    if velocity_sigma is not None:
        H[3:6, 3:6] = np.eye(3)
        R_diag += [velocity_sigma ** 2] * 3
    R = np.diag(R_diag)
    # per-step process noise that does not depend on the attitude
    q_g = (spec.gyro_arw_dpsh * DPSH) ** 2 * dt
    q_a = (spec.accel_vrw_ug_rthz * UG) ** 2 * dt
    if lay.vib_white:       # the white noise of the same per-sample RMS: density A^2 dt
        q_g += (spec.vibration_gyro_dps * DEG * dt) ** 2
        q_a += (spec.vibration_accel_mps2 * dt) ** 2
    Q0 = np.zeros((n, n))
    Q0[0:3, 0:3] = q_g * np.eye(3)        # C q I C^T = q I
    Q0[3:6, 3:6] = q_a * np.eye(3)
    decay = np.ones(n)                    # per-step factor of the Markov states
    for sl, sigma, tau in ((lay.gm_g, spec.gyro_markov_dph * DPH, spec.gyro_markov_tau_s),
                           (lay.gm_a, spec.accel_markov_ug * UG, spec.accel_markov_tau_s),
                           (lay.gnss, gnss.pos_markov_sigma, gnss.pos_markov_tau_s)):
        if sl is not None:
            phi = math.exp(-dt / tau)
            decay[sl] = phi
            Q0[sl, sl] = sigma * sigma * (1.0 - phi * phi) * np.eye(3)
    if lay.vib_states:
        phi_v, s_x, s_y = _vibration_figures(spec, dt)
        q_x, q_y = s_x * s_x * (1.0 - phi_v * phi_v), s_y * s_y * (1.0 - phi_v * phi_v)
        decay[lay.vx] = decay[lay.vy] = phi_v
        Q0[lay.vx, lay.vx] = q_x * np.eye(3)
        Q0[lay.vy, lay.vy] = q_y * np.eye(3)
    markov = [sl for sl in (lay.gm_g, lay.gm_a, lay.gnss) if sl is not None]
    report_k = {int(round(t / dt)) - 1: t for t in report_s}
    out_phi, out_slow, out_ba, out_t = [], [], [], []
    F = np.zeros((n, n))
    g_prev = truth.gain[0]
    for k in range(len(truth.t)):
        C, w_b, f_b = truth.C_b_n[k], truth.w_ib_b[k], truth.f_b[k]
        F[:15, :15] = lc.F_matrix(C, truth.f_n[k], truth.v_n[k], truth.lat[k], truth.h[k],
                                  math.inf, math.inf, 15)
        if lay.gm_g is not None:
            F[0:3, lay.gm_g] = -C
        if lay.gm_a is not None:
            F[3:6, lay.gm_a] = C
        if lay.sg is not None:
            F[0:3, lay.sg] = -C * w_b[None, :]
        if lay.sa is not None:
            F[3:6, lay.sa] = C * f_b[None, :]
        if lay.mg is not None:
            F[0:3, lay.mg] = -np.stack([C[:, i] * w_b[j] for i, j in OFF_DIAGONAL], axis=1)
        if lay.ma is not None:
            F[3:6, lay.ma] = np.stack([C[:, i] * f_b[j] for i, j in OFF_DIAGONAL], axis=1)
        Fdt = F * dt
        A = eye + Fdt + 0.5 * (Fdt @ Fdt)
        for sl in markov:           # exact decay (F holds no -1/tau for them)
            A[sl, sl] = decay[sl] * np.eye(3)
        Q = Q0
        if lay.vib_states:
            g = truth.gain[k]
            A[lay.vx, lay.vx] = phi_v * np.eye(3)
            A[lay.vy, lay.vy] = phi_v * np.eye(3)
            # increments g_k x_k - g_{k-1} x_{k-1}, with x_k = phi_v x_{k-1} + w_k
            A[0:3, lay.vx] = -C * (g * phi_v - g_prev)
            A[3:6, lay.vy] = C * (g * phi_v - g_prev)
            Q = Q0.copy()
            Q[0:3, 0:3] += g * g * q_x * np.eye(3)
            Q[0:3, lay.vx] = -C * g * q_x
            Q[lay.vx, 0:3] = Q[0:3, lay.vx].T
            Q[3:6, 3:6] += g * g * q_y * np.eye(3)
            Q[3:6, lay.vy] = C * g * q_y
            Q[lay.vy, 3:6] = Q[3:6, lay.vy].T
            g_prev = g
        P = A @ P @ A.T + Q
        if (k + 1) % every == 0:
            S = H @ P @ H.T + R
            K = np.linalg.solve(S, H @ P).T
            IKH = eye - K @ H
            P = IKH @ P @ IKH.T + K @ R @ K.T
        P = 0.5 * (P + P.T)
        if k in report_k:
            out_t.append(report_k[k])
            out_phi.append(np.sqrt(np.diag(P)[0:3]))
            out_ba.append(np.sqrt(np.diag(P)[12:15]))
            if lay.vib_states:      # phi + C g x: the attitude error without the jitter
                T = np.zeros((3, n))
                T[:, 0:3] = np.eye(3)
                T[:, lay.vx] = C * truth.gain[k]
                out_slow.append(np.sqrt(np.diag(T @ P @ T.T)))
            else:
                out_slow.append(out_phi[-1])
    return Result(t=np.array(out_t), phi=np.array(out_phi), phi_slow=np.array(out_slow),
                  accel_bias=np.array(out_ba))


def bound(sc):
    """Return issue 44's tilt limit, rad: 1.5 x the simulated accelerometer bias / g.

    As bench/integrity.py ``usefulness``: the constant and Gauss-Markov bias combined.
    """
    g = earth.gravity(sc.trajectory.lat_deg * DEG, sc.trajectory.h)
    s = sc.imu
    acc = math.hypot(float(np.max(np.abs(s.accel_bias_ug))), s.accel_markov_ug) * UG / g
    return USEFUL_TILT_BY_BIAS * acc


def still_limit(sc):
    """Return the horizontal accelerometer error / g (rad) a still IMU cannot tell from tilt.

    1-sigma per axis: the bias (constant and Markov) and the misalignment entries that
    turn gravity into a horizontal reading (``M[0, 2] g``, ``M[1, 2] g``).
    """
    g = earth.gravity(sc.trajectory.lat_deg * DEG, sc.trajectory.h)
    s = sc.imu
    m = np.broadcast_to(np.asarray(s.accel_misalign_ppm, float), (3, 3))[0, 2] * 1e-6 * g
    b = math.hypot(float(np.max(np.abs(s.accel_bias_ug))), s.accel_markov_ug) * UG
    return math.hypot(b, m) / g


def drawn_errors(sc, seed):
    """Return the horizontal accelerometer error (mg, body x and y) that ``seed`` draws.

    The constant bias plus the misalignment under gravity ``M[i, 2] g`` (what a level
    robot turning about its z axis cannot tell from a tilt), ScenarioStream's draw.
    """
    err = ScenarioStream(sc, seed=seed).imu.errors
    g = earth.gravity(sc.trajectory.lat_deg * DEG, sc.trajectory.h)
    return (err.accel_bias[:2] + err.accel_sm[:2, 2] * g) / (1e-3 * 9.80665)


def _commit():
    try:
        return subprocess.run(['git', '-C', str(ROOT), 'rev-parse', '--short', 'HEAD'],
                              capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return 'unknown'


def _am(x):
    return f'{x / ARCMIN:.1f}'


def _variant_run(truth, sc, variant):
    """Run variant ``variant`` (see :data:`VARIANTS`) of the cell ``sc`` along ``truth``."""
    spec, gnss = sc.imu, sc.gnss
    kw = {}
    if variant == 'vel':
        kw['velocity_sigma'] = CONSUMER_VEL_SIGMA
    elif variant == 'white':
        gnss = gnss.with_(pos_markov_sigma=0.0)
    elif variant == 'novib':
        spec = spec.with_(vibration_gyro_dps=0.0, vibration_accel_mps2=0.0)
    elif variant == 'vibwhite':
        kw['vibration'] = 'white'
    elif variant == 'prior':
        kw['prior'] = PRIORS['B']
    return run(truth, spec, gnss, REPORT_S, **kw)


def main():
    """Run the analysis for each grade, seed and variant and write the results page."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--grades', default=','.join(GRADES))
    ap.add_argument('--seeds', default=','.join(map(str, SEEDS)))
    ap.add_argument('--variants', default=','.join(VARIANTS))
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'tilt_limit.md'))
    args = ap.parse_args()
    grades = args.grades.split(',')
    seeds = [int(s) for s in args.seeds.split(',')]
    variants = args.variants.split(',')
    cmd = 'python bench/tilt_limit.py ' + ' '.join(sys.argv[1:])
    t_start = time.time()
    results = {}
    drawn = {}
    for grade in grades:
        sc = cell(grade)
        for seed in seeds:
            # the truth of the cell's run: the trajectory is fixed, so every seed's is the same
            truth = truth_of(sc.trajectory, sc.imu_rate_hz, sc.duration,
                             sc.imu.vibration_full_speed_mps)
            drawn[(grade, seed)] = drawn_errors(sc, seed)
            for v in variants:
                t0 = time.time()
                results[(grade, seed, v)] = _variant_run(truth, sc, v)
                print(f'{grade} {seed} {v}: tilt {_am(results[(grade, seed, v)].phi[-1, 0])} / '
                      f'{_am(results[(grade, seed, v)].phi[-1, 1])} ({time.time() - t0:.1f} s)',
                      flush=True)
    lines = page(args, cmd, grades, seeds, variants, results, drawn, time.time() - t_start)
    write_markdown(args.out, lines)
    print('\n'.join(lines))


def page(args, cmd, grades, seeds, variants, results, drawn, elapsed):
    """Return the results page's lines."""
    head = ' | '.join(f'{t:.0f} s' for t in REPORT_S)
    lines = [
        '# Tilt sigma of the ideal estimator on robot:posonly (issue 44)', '',
        f'Command: `{cmd.strip()}` on {machine_summary()}; commit {_commit()}; '
        f'{elapsed:.0f} s.', '',
        'Covariance-only analysis (bench/tilt_limit.py, its docstring gives the model) of the '
        'linearized error-state Kalman filter along the simulator\'s truth trajectory of '
        '`robot_skid` (400 s, 30 Hz IMU, 2.5 Hz position-only receiver), every simulated '
        'error a state, every noise the simulator\'s; vibration as the simulator makes it '
        '(differences of a 0.05-s Gauss-Markov angle and velocity: states). Attitude prior A: '
        '2 deg tilt, 10 deg heading. Cells: tilt sigma E / N (arcmin), heading sigma (deg). '
        '"no jitter": the tilt sigma without the vibration\'s instantaneous angle jitter '
        '(what an estimate averaged over a fraction of a second would have).', '',
        'Variants: ' + '; '.join(f'`{v}` {VARIANTS[v]}' for v in variants) + '.', '']
    for grade in grades:
        sc = cell(grade)
        b, lim = bound(sc), still_limit(sc)
        lines += [f'## {grade}', '',
                  f'Bound (1.5 x accelerometer bias / g): {_am(b)}\'. Still, level IMU limit '
                  f'(horizontal accelerometer error / g: bias'
                  + (' and misalignment under gravity' if np.any(sc.imu.accel_misalign_ppm)
                     else '') + f'): {_am(lim)}\'.', '']
        ref = results[(grade, seeds[0], variants[0])]
        same = all(np.array_equal(results[(grade, s, v)].phi, results[(grade, seeds[0], v)].phi)
                   for s in seeds for v in variants)
        lines += [f'Seeds {", ".join(map(str, seeds))}: the covariances are '
                  + ('bit-identical (P depends on the trajectory only); the table is seed '
                     f'{seeds[0]}\'s.' if same else 'NOT identical: per-seed tables below.'),
                  '']
        lines += [f'| variant | {head} | no jitter, 400 s | within bound at 400 s |',
                  '|---|' + '---|' * (len(REPORT_S) + 2)]
        for s in (seeds[:1] if same else seeds):
            for v in variants:
                r = results[(grade, s, v)]
                cells = [f'{_am(p[0])} / {_am(p[1])}, {p[2] / DEG:.2f}' for p in r.phi]
                worst = max(r.phi[-1, 0], r.phi[-1, 1])
                name = v if same else f'{v} ({s})'
                lines.append(f'| {name} | ' + ' | '.join(cells)
                             + f' | {_am(r.phi_slow[-1, 0])} / {_am(r.phi_slow[-1, 1])} | '
                             + ('yes' if worst <= b else 'no') + f' ({_am(worst)}\' vs '
                             f'{_am(b)}\') |')
        lines += ['', f'Accelerometer bias sigma at 400 s (body x / y / z, mg), `{variants[0]}`: '
                  + ' / '.join(f'{x / (1e-3 * 9.80665):.2f}' for x in ref.accel_bias[-1])
                  + f' (prior {float(np.max(np.abs(sc.imu.accel_bias_ug))) / 1000:.1f}).', '',
                  'Drawn horizontal accelerometer error per seed (bias + misalignment x g, body '
                  'x / y, mg): ' + '; '.join(
                      f'{s}: {drawn[(grade, s)][0]:+.2f} / {drawn[(grade, s)][1]:+.2f}'
                      for s in seeds) + '.', '']
    return lines


if __name__ == '__main__':
    main()

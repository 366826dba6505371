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
0.274 m/s/sqrt(s) = 27.9 mg/sqrt(Hz) for the accelerometer, 11 and 80 times the plain MEMS
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

Variants (``--variants``, :data:`VARIANTS`): ``base`` (the cell as simulated); ``vel``
(GNSS velocity too, the ``consumer`` receiver's 0.08 m/s white, at the same 2.5 Hz
epochs); ``white`` (the GNSS position error white only: no Gauss-Markov part); ``novib``
(no vibration); ``vibwhite`` (vibration as white noise); ``noarw`` (no gyro white noise);
``nogyromis`` (no gyro axis misalignment; grades that have one); ``arw<N>`` (gyro white
noise N deg/sqrt(h) instead of the grade's, vibration still as states: ``arw9`` and
``arw17`` are the self-check's figures for these vibrating triads over 60 s and over the
motion check's 20 s, align/stages/angle_walk.py: what a filter told that noise could claim at
best); ``prior_loose``, ``prior_tight`` (the other attitude priors).
Priors (1 sigma): ``A`` = 2 deg tilt, 10 deg heading (all variants but the two);
``loose`` = 5 deg, 30 deg; ``tight`` = 0.5 deg, 3 deg (a prior this close to the end sigma
is information of its own). Velocity 1 m/s, position 3 m per axis; every sensor state its
grade's 1-sigma (for the ``mems`` grade, whose errors the simulator applies as given
rather than drawn, that value is taken as the 1-sigma of an unknown constant, as the
filters are told).

Filter check (``--check``): the same model run as a filter (state and covariance, closed
loop, :func:`run` ``data``) on each seed's simulated data of the ``base`` cell: its tilt
errors against its sigma (the model's agreement with the simulator, and that the sigma
is reached by a filter, not only by the covariance).

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
from sins_align_ros.nav.frames import attitude_error, euler_to_dcm, rotvec_to_dcm  # noqa: E402
from sins_align_ros.nav.mechanization import Strapdown  # noqa: E402
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
PRIORS = {'A': (2.0, 10.0), 'loose': (5.0, 30.0), 'tight': (0.5, 3.0)}
VEL_PRIOR_MPS = 1.0
POS_PRIOR_M = 3.0
VARIANTS = {
    'base': 'as simulated: positions only, white + Gauss-Markov, vibration',
    'vel': 'plus GNSS velocity, 0.08 m/s white (the consumer receiver\'s)',
    'white': 'GNSS position error white only (no Gauss-Markov part)',
    'novib': 'no vibration',
    'vibwhite': 'vibration as white noise of the same per-sample RMS',
    'noarw': 'no gyro white noise (angle random walk)',
    'nogyromis': 'no gyro axis misalignment',
    'arw9': 'gyro white noise 9 deg/sqrt(h) (the self-check\'s 60-s figure for these triads)',
    'arw17': 'gyro white noise 17 deg/sqrt(h) (the self-check\'s 20-s figure)',
    'prior_loose': 'attitude prior 5 deg tilt, 30 deg heading',
    'prior_tight': 'attitude prior 0.5 deg tilt, 3 deg heading',
}
#: the filter check's normalized errors are taken from this time on, s
CHECK_FROM_S = 100.0
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
    states); ``accel_bias`` (M, 3) m/s^2 (body x, y, z). With a filter run
    (:func:`run` ``data``): ``err`` (M, 3) rad the attitude error of its navigator at the
    report times, ``nerr`` (E, 2) the tilt errors E, N over sigma at every epoch ``E`` after
    :data:`CHECK_FROM_S`.
    """

    t: np.ndarray
    phi: np.ndarray
    phi_slow: np.ndarray
    accel_bias: np.ndarray
    err: np.ndarray = None
    nerr: np.ndarray = None


def run(truth, spec, gnss, report_s, prior=PRIORS['A'], velocity_sigma=None,
        vibration='states', data=None, rng=None):
    """Propagate and update the ideal filter's P along ``truth``; return a :class:`Result`.

    ``spec``: the simulated :class:`~sins_align_ros.sim.imu.ImuSpec`; ``gnss``: the
    receiver's :class:`~sins_align_ros.sim.gnss.GnssSpec` (its rate must divide the IMU
    rate); ``report_s`` times (s) to report at (after that epoch's update);
    ``prior`` (tilt deg, heading deg); ``velocity_sigma`` (m/s): also measure the velocity
    with this white noise at every epoch (None: positions only); ``vibration``
    ``'states'`` (exact) or ``'white'`` (see the module docstring).

    ``data``: ``(block, start)``, a simulated run (a
    :class:`~sins_align_ros.sim.scenario.SimBlock` of these ``spec`` and ``gnss``, positions
    only, starting at ``truth``'s first step) and its truth at t = 0 ``(euler, v_n, pos)``,
    to run the ideal filter on as well: a strapdown
    navigator (nav/mechanization.py) started at the truth plus errors drawn from the prior
    with ``rng``, the same ``A``, ``Q``, ``H``, ``R`` and gain, the GNSS position
    differences as measurements, the attitude, velocity and position estimates fed back
    into the navigator at every epoch and the constant sensor errors' estimates (biases,
    scale factors, misalignments) into the increments it takes, so that the residual errors
    are small enough for the linear model (the Markov, receiver and vibration states are
    not fed back: they are small or short-lived).
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
    markov = [(sl, decay[sl] * np.eye(3)) for sl in (lay.gm_g, lay.gm_a, lay.gnss)
              if sl is not None]
    # the sensor-error columns of F at every step: scale factors and misalignments
    C_all, w_all, f_all = truth.C_b_n, truth.w_ib_b, truth.f_b
    ii = [i for i, _ in OFF_DIAGONAL]
    jj = [j for _, j in OFF_DIAGONAL]
    cols = {'sg': -C_all * w_all[:, None, :], 'sa': C_all * f_all[:, None, :],
            'mg': -C_all[:, :, ii] * w_all[:, None, jj],
            'ma': C_all[:, :, ii] * f_all[:, None, jj]}
    eye3 = np.eye(3)
    report_k = {int(round(t / dt)) - 1: t for t in report_s}
    out_phi, out_slow, out_ba, out_t = [], [], [], []
    F = np.zeros((n, n))
    g_prev = truth.gain[0]
    filt = None if data is None else _Navigator(*data, P, rng, lay)
    errs, nerrs = [], []
    for k in range(len(truth.t)):
        C = C_all[k]
        F[:15, :15] = lc.F_matrix(C, truth.f_n[k], truth.v_n[k], truth.lat[k], truth.h[k],
                                  math.inf, math.inf, 15)
        if lay.gm_g is not None:
            F[0:3, lay.gm_g] = -C
        if lay.gm_a is not None:
            F[3:6, lay.gm_a] = C
        for sl, rows, key in ((lay.sg, 0, 'sg'), (lay.sa, 3, 'sa'), (lay.mg, 0, 'mg'),
                              (lay.ma, 3, 'ma')):
            if sl is not None:
                F[rows:rows + 3, sl] = cols[key][k]
        Fdt = F * dt
        A = eye + Fdt + 0.5 * (Fdt @ Fdt)
        for sl, d in markov:        # exact decay (F holds no -1/tau for them)
            A[sl, sl] = d
        Q = Q0
        if lay.vib_states:
            g = truth.gain[k]
            A[lay.vx, lay.vx] = phi_v * eye3
            A[lay.vy, lay.vy] = phi_v * eye3
            # increments g_k x_k - g_{k-1} x_{k-1}, with x_k = phi_v x_{k-1} + w_k
            A[0:3, lay.vx] = -C * (g * phi_v - g_prev)
            A[3:6, lay.vy] = C * (g * phi_v - g_prev)
            Q = Q0.copy()
            Q[0:3, 0:3] += g * g * q_x * eye3
            Q[0:3, lay.vx] = -C * g * q_x
            Q[lay.vx, 0:3] = Q[0:3, lay.vx].T
            Q[3:6, 3:6] += g * g * q_y * eye3
            Q[3:6, lay.vy] = C * g * q_y
            Q[lay.vy, 3:6] = Q[3:6, lay.vy].T
            g_prev = g
        P = A @ P @ A.T + Q
        if filt is not None:
            filt.propagate(k, A)
        if (k + 1) % every == 0:
            S = H @ P @ H.T + R
            K = np.linalg.solve(S, H @ P).T
            IKH = eye - K @ H
            P = IKH @ P @ IKH.T + K @ R @ K.T
            if filt is not None:
                filt.update((k + 1) // every - 1, K, H)
                if truth.t[k] > CHECK_FROM_S + 1e-9:
                    nerrs.append(filt.error(k)[:2] / np.sqrt(np.diag(P)[0:2]))
        P = 0.5 * (P + P.T)
        if k in report_k:
            if filt is not None:
                errs.append(filt.error(k))
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
                  accel_bias=np.array(out_ba), err=np.array(errs) if filt else None,
                  nerr=np.array(nerrs) if filt else None)


class _Navigator:
    """The ideal filter's state side: a strapdown navigator with closed-loop feedback.

    ``block``: a SimBlock, ``start`` its truth at t = 0 ``(euler, v_n, pos)``; ``P0`` the
    initial covariance the navigator's initial errors (attitude, velocity, position) are
    drawn from with ``rng``; ``lay`` the :class:`Layout`. The estimated constant sensor
    errors ``b_g``, ``b_a`` (3,) and ``E_g = S_g + M_g``, ``E_a`` (3, 3) correct the
    increments: ``dtheta_c = (I + E_g)^-1 (dtheta - b_g dt)``, likewise ``dv``.
    """

    def __init__(self, block, start, P0, rng, lay):
        imu = block.imu
        if block.gnss is None or block.gnss.v_n is not None:
            raise ValueError('the filter check takes a position-only receiver')
        self.imu, self.gnss = imu, block.gnss
        self.dt = float(imu.t[1] - imu.t[0])
        euler0, v0, (lat, lon, h) = start
        e0 = rng.standard_normal(9) * np.sqrt(np.diag(P0)[:9])
        R_M, R_N = earth.radii(lat)
        self.nav = Strapdown(rotvec_to_dcm(-e0[0:3]) @ euler_to_dcm(np.asarray(euler0)),
                             np.asarray(v0) + e0[3:6],
                             lat + e0[7] / (R_M + h), lon + e0[6] / ((R_N + h) * math.cos(lat)),
                             h + e0[8])
        self.x = np.zeros(len(P0))
        self.lay = lay
        self.b_g, self.b_a = np.zeros(3), np.zeros(3)
        self.E_g, self.E_a = np.zeros((3, 3)), np.zeros((3, 3))
        self._inv_g, self._inv_a = np.eye(3), np.eye(3)

    def propagate(self, k, A):
        """Advance the navigator over sample ``k`` and the error state by ``A``."""
        dth = self._inv_g @ (self.imu.dtheta[k] - self.b_g * self.dt)
        dv = self._inv_a @ (self.imu.dv[k] - self.b_a * self.dt)
        self.nav.update(dth, dv, self.dt)
        self.x = A @ self.x

    def _feed_sensors(self):
        """Move the constant sensor errors' estimates from the state into the corrections."""
        lay, x = self.lay, self.x
        self.b_g += x[9:12]
        self.b_a += x[12:15]
        for E, s_sl, m_sl in ((self.E_g, lay.sg, lay.mg), (self.E_a, lay.sa, lay.ma)):
            if s_sl is not None:
                E[np.diag_indices(3)] += x[s_sl]
            if m_sl is not None:
                for (i, j), v in zip(OFF_DIAGONAL, x[m_sl]):
                    E[i, j] += v
        for sl in (slice(9, 15), lay.sg, lay.mg, lay.sa, lay.ma):
            if sl is not None:
                x[sl] = 0.0
        self._inv_g = np.linalg.inv(np.eye(3) + self.E_g)
        self._inv_a = np.linalg.inv(np.eye(3) + self.E_a)

    def update(self, j, K, H):
        """Take GNSS epoch ``j`` with gain ``K``; feed the navigation errors back."""
        g, nav = self.gnss, self.nav
        z = earth.local_offset_m(g.lat[j], g.lon[j], g.h[j], nav.lat, nav.lon, nav.h)
        self.x = self.x + K @ (z - H[0:3] @ self.x)
        phi, dv, dp = self.x[0:3], self.x[3:6], self.x[6:9]
        nav.C_b_n = rotvec_to_dcm(phi) @ nav.C_b_n
        nav.correct_velocity(dv)
        R_M, R_N = earth.radii(nav.lat)
        nav.correct_position(np.array([dp[1] / (R_M + nav.h),
                                       dp[0] / ((R_N + nav.h) * math.cos(nav.lat)), dp[2]]))
        self.x[0:9] = 0.0
        self._feed_sensors()

    def error(self, k):
        """Return the navigator's attitude error, rad, ENU (3,), at sample ``k``'s end."""
        return attitude_error(self.nav.C_b_n, euler_to_dcm(np.asarray(self.imu.euler[k])))


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
    elif variant == 'noarw':
        spec = spec.with_(gyro_arw_dpsh=0.0)
    elif variant == 'nogyromis':
        if not np.any(spec.gyro_misalign_ppm):
            return None
        spec = spec.with_(gyro_misalign_ppm=0.0)
    elif variant.startswith('arw'):
        spec = spec.with_(gyro_arw_dpsh=float(variant[3:]))
    elif variant.startswith('prior_'):
        kw['prior'] = PRIORS[variant[6:]]
    elif variant != 'base':
        raise ValueError(f'unknown variant {variant!r}')
    return run(truth, spec, gnss, REPORT_S, **kw)


def check(sc, truth, seed):
    """Run the ideal filter on seed ``seed``'s simulated run of cell ``sc``; a :class:`Result`.

    The navigator's initial errors are drawn from prior A with the generator ``seed``.
    """
    stream = ScenarioStream(sc, seed=seed)
    start = stream.imu.initial_truth()
    block = stream.next_block(int(round(sc.duration * sc.imu_rate_hz)))
    return run(truth, sc.imu, sc.gnss, REPORT_S, data=(block, start),
               rng=np.random.default_rng(seed))


def main():
    """Run the analysis for each grade, seed and variant and write the results page."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--grades', default=','.join(GRADES))
    ap.add_argument('--seeds', default=','.join(map(str, SEEDS)))
    ap.add_argument('--variants', default=','.join(VARIANTS))
    ap.add_argument('--check', action='store_true', help='run the filter check too')
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'tilt_limit.md'))
    args = ap.parse_args()
    grades = args.grades.split(',')
    seeds = [int(s) for s in args.seeds.split(',')]
    variants = args.variants.split(',')
    cmd = 'python bench/tilt_limit.py ' + ' '.join(sys.argv[1:])
    t_start = time.time()
    results, drawn, checks = {}, {}, {}
    for grade in grades:
        sc = cell(grade)
        for seed in seeds:
            # the truth of the cell's run: the trajectory is fixed, so every seed's is the same
            truth = truth_of(sc.trajectory, sc.imu_rate_hz, sc.duration,
                             sc.imu.vibration_full_speed_mps)
            drawn[(grade, seed)] = drawn_errors(sc, seed)
            # P does not depend on the seed: the other seeds run the first variant only
            for v in (variants if seed == seeds[0] else variants[:1]):
                t0 = time.time()
                r = results[(grade, seed, v)] = _variant_run(truth, sc, v)
                if r is not None:
                    print(f'{grade} {seed} {v}: tilt {_am(r.phi[-1, 0])} / {_am(r.phi[-1, 1])} '
                          f'({time.time() - t0:.1f} s)', flush=True)
            if args.check:
                t0 = time.time()
                r = checks[(grade, seed)] = check(sc, truth, seed)
                print(f'{grade} {seed} check: error {_am(r.err[-1, 0])} / {_am(r.err[-1, 1])} '
                      f'({time.time() - t0:.1f} s)', flush=True)
    lines = page(cmd, grades, seeds, variants, results, drawn, checks, time.time() - t_start)
    write_markdown(args.out, lines)
    print('\n'.join(lines))


def _variant_table(grade, seeds, variants, results, b):
    """Rows of one grade's variant table, and whether the seeds' covariances are identical."""
    head = ' | '.join(f'{t:.0f} s' for t in REPORT_S)
    ran = [v for v in variants if results[(grade, seeds[0], v)] is not None]
    v0 = variants[0]
    same = all(np.array_equal(results[(grade, s, v0)].phi, results[(grade, seeds[0], v0)].phi)
               for s in seeds)
    rows = [f'| variant | {head} | no jitter, 400 s | within bound at 400 s |',
            '|---|' + '---|' * (len(REPORT_S) + 2)]
    for s, v in [(seeds[0], v) for v in ran] + ([] if same else [(s, v0) for s in seeds[1:]]):
        r = results[(grade, s, v)]
        cells = [f'{_am(p[0])} / {_am(p[1])}, {p[2] / DEG:.2f}' for p in r.phi]
        worst = max(r.phi[-1, 0], r.phi[-1, 1])
        name = f'`{v}`' if s == seeds[0] else f'`{v}` ({s})'
        rows.append(f'| {name} | ' + ' | '.join(cells)
                    + f' | {_am(r.phi_slow[-1, 0])} / {_am(r.phi_slow[-1, 1])} | '
                    + ('yes' if worst <= b else 'no') + f' ({_am(worst)}\' vs {_am(b)}\') |')
    return rows, same


def _check_table(grade, seeds, checks):
    """Rows of one grade's filter-check table."""
    rows = ['| seed | tilt error E / N at 400 s (\') | its sigma (\') | heading error / sigma '
            'at 400 s (deg) | RMS of tilt error / sigma E / N, epochs after '
            f'{CHECK_FROM_S:.0f} s | epochs inside 3 sigma E / N |', '|---|---|---|---|---|---|']
    for s in seeds:
        r = checks[(grade, s)]
        rms = np.sqrt(np.mean(r.nerr ** 2, axis=0))
        inside = np.mean(np.abs(r.nerr) <= 3.0, axis=0)
        rows.append(f'| {s} | {_am(r.err[-1, 0])} / {_am(r.err[-1, 1])} | {_am(r.phi[-1, 0])} / '
                    f'{_am(r.phi[-1, 1])} | {r.err[-1, 2] / DEG:.2f} / {r.phi[-1, 2] / DEG:.2f} | '
                    f'{rms[0]:.2f} / {rms[1]:.2f} | {inside[0]:.1%} / {inside[1]:.1%} |')
    allr = np.concatenate([checks[(grade, s)].nerr for s in seeds])
    rms = np.sqrt(np.mean(allr ** 2, axis=0))
    rows += ['', f'All {len(seeds)} seeds: RMS of tilt error / sigma {rms[0]:.2f} / {rms[1]:.2f} '
             f'(E / N; 1 for a sigma that fits the error).']
    return rows


def page(cmd, grades, seeds, variants, results, drawn, checks, elapsed):
    """Return the results page's lines."""
    lines = [
        '# Tilt sigma of the ideal estimator on robot:posonly (issue 44)', '',
        f'Command: `{cmd.strip()}` on {machine_summary()}; commit {_commit()}; '
        f'{elapsed:.0f} s.', '',
        'Covariance-only analysis (bench/tilt_limit.py, its docstring gives the model) of the '
        'linearized error-state Kalman filter along the simulator\'s truth trajectory of '
        '`robot_skid` (400 s, 30 Hz IMU, 2.5 Hz position-only receiver), every simulated '
        'error a state, every noise the simulator\'s; vibration as the simulator makes it '
        '(differences of a 0.05-s Gauss-Markov angle and velocity: states). Attitude prior: '
        '2 deg tilt, 10 deg heading (1 sigma). Cells: tilt sigma E / N (arcmin), heading '
        'sigma (deg). "no jitter": the tilt sigma without the vibration\'s instantaneous '
        'angle jitter (6.08\' per axis).', '',
        'Variants: ' + '; '.join(f'`{v}` {VARIANTS[v]}' for v in variants) + '.', '']
    for grade in grades:
        sc = cell(grade)
        b, lim = bound(sc), still_limit(sc)
        lines += [f'## {grade}', '',
                  f'Bound (1.5 x accelerometer bias / g): {_am(b)}\'. Still, level IMU limit '
                  f'(horizontal accelerometer error / g: bias'
                  + (' and misalignment under gravity' if np.any(sc.imu.accel_misalign_ppm)
                     else '') + f'): {_am(lim)}\'.', '']
        rows, same = _variant_table(grade, seeds, variants, results, b)
        lines += [f'Seeds {", ".join(map(str, seeds))}: their `{variants[0]}` covariances are '
                  + ('bit-identical (P depends on the trajectory only, which no seed changes), '
                     f'so the variants ran on seed {seeds[0]} only.' if same
                     else 'NOT identical: a row per seed.'), ''] + rows
        ref = results[(grade, seeds[0], variants[0])]
        worst = {v: float(np.max(results[(grade, seeds[0], v)].phi[-1, :2]))
                 for v in variants if results[(grade, seeds[0], v)] is not None}
        budget = [v for v in ('vel', 'white', 'novib', 'noarw', 'nogyromis') if v in worst]
        if variants[0] == 'base' and budget:
            lines += ['', f'At 400 s the ideal tilt sigma (worse axis) is {_am(worst["base"])}\' '
                      f'= {worst["base"] / b:.0%} of the bound. One change at a time: '
                      + ', '.join(f'`{v}` {_am(worst[v])}\'' for v in budget) + '.']
        lines += ['', f'Accelerometer bias sigma at 400 s (body x / y / z, mg), `{variants[0]}`: '
                  + ' / '.join(f'{x / (1e-3 * 9.80665):.2f}' for x in ref.accel_bias[-1])
                  + f' (prior {float(np.max(np.abs(sc.imu.accel_bias_ug))) / 1000:.1f}).', '',
                  'Drawn horizontal accelerometer error per seed (bias + misalignment x g, body '
                  'x / y, mg): ' + '; '.join(
                      f'{s}: {drawn[(grade, s)][0]:+.2f} / {drawn[(grade, s)][1]:+.2f}'
                      for s in seeds) + '.', '']
        if checks:
            lines += [f'Filter check ({grade}, `base`): the model run as a closed-loop filter '
                      'on each seed\'s simulated data, initial navigation errors drawn from '
                      'the prior.', ''] + _check_table(grade, seeds, checks) + ['']
    return lines


if __name__ == '__main__':
    main()

#!/usr/bin/env python3
"""Simulator and mechanization figures of the foundation issue.

1. Error-free IMU data from the simulator integrated with our mechanization for
   600 s at 100 Hz: maximum attitude (arcsec), velocity (m/s) and position (m)
   error against the truth, for the static, sway, underway and flight trajectories.
2. Allan deviation of simulated noise against the configured ARW / VRW / Markov
   values (ratio measured / configured).
3. Speed: IMU generation and mechanization, samples per second.

Usage: python bench/sim_accuracy.py [--out bench/results/sim_accuracy.md]
"""
import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's package

from sins_align_ros.eval.markdown import write_markdown  # noqa: E402
from sins_align_ros.nav import earth  # noqa: E402
from sins_align_ros.nav.frames import attitude_error, euler_to_dcm  # noqa: E402
from sins_align_ros.nav.mechanization import Strapdown  # noqa: E402
from sins_align_ros.sim.allan import adev_markov, adev_white, allan_deviation  # noqa: E402
from sins_align_ros.sim.imu import ImuErrors, ImuSimulator, ImuSpec  # noqa: E402
from sins_align_ros.sim.presets import SEED000_SWAY, scenario  # noqa: E402
from sins_align_ros.sim.trajectory import Sway, Trajectory  # noqa: E402
from sins_align_ros.units import ARCSEC, DPH, DPSH, UG  # noqa: E402


def trajectories():
    """Return the four trajectories of the issue's acceptance check."""
    return {
        'static': Trajectory(34.0, 108.0, 100.0, heading_deg=30.0, pitch_deg=1.0, roll_deg=-2.0),
        'sway (seed 000 + heave/surge)': Trajectory(
            45.7796, 126.6705, 0.0, heading_deg=45.0,
            sway=Sway(**{**SEED000_SWAY.__dict__, 'heave_amp': 1.0, 'heave_period': 8.0,
                         'surge_amp': 0.5, 'surge_period': 9.0})),
        'ship underway (ship_underway)': scenario('ship_underway').trajectory,
        'flight (seed001_flight)': scenario('seed001_flight').trajectory,
    }


def truth_reproduction(seconds=600.0, rate=100.0):
    """Return rows (name, max att arcsec, vel m/s, pos m, distance m, gen s, mech s, n)."""
    rows = []
    for name, traj in trajectories().items():
        t0 = time.perf_counter()
        sim = ImuSimulator(traj, ImuSpec(), rate)
        e0, v0, p0 = sim.initial_truth()
        c = sim.next_chunk(int(seconds * rate))
        t1 = time.perf_counter()
        out = Strapdown(euler_to_dcm(e0), v0, *p0).run(c.dtheta, c.dv, 1.0 / rate)
        t2 = time.perf_counter()
        att = np.abs(attitude_error(out['C_b_n'], euler_to_dcm(c.euler))).max() / ARCSEC
        vel = np.abs(out['v_n'] - c.v_n).max()
        pe = earth.local_offset_m(c.pos[:, 0], c.pos[:, 1], c.pos[:, 2], out['pos'][:, 0],
                                  out['pos'][:, 1], out['pos'][:, 2])
        dist = np.hypot(*earth.local_offset_m(*c.pos[0], *c.pos[-1])[:2])
        rows.append((name, att, vel, np.abs(pe).max(), dist, t1 - t0, t2 - t1, len(c.t)))
    return rows


def allan_check():
    """Return rows (quantity, tau, configured, measured, ratio)."""
    dt, n = 0.01, 720_000
    spec = ImuSpec(gyro_arw_dpsh=0.05, accel_vrw_ug_rthz=50.0)
    e = ImuErrors(spec, np.random.default_rng(11))
    dth, dv = e.apply(np.zeros((n, 3)), np.zeros((n, 3)), dt)
    rows = []
    for tau_s in (0.1, 1.0, 10.0, 100.0):
        m = [int(round(tau_s / dt))]
        tau, g = allan_deviation(dth / dt, dt, m)
        _, a = allan_deviation(dv / dt, dt, m)
        gc = adev_white(0.05 * DPSH, tau[0])
        ac = adev_white(50 * UG, tau[0])
        rows.append(('gyro ARW 0.05 deg/rt-h', tau_s, gc / DPSH * 60, g[0].mean() / DPSH * 60,
                     g[0].mean() / gc))
        rows.append(('accel VRW 50 ug/rt-Hz', tau_s, ac / UG, a[0].mean() / UG, a[0].mean() / ac))
    dt, n = 0.1, 400_000
    e = ImuErrors(ImuSpec(gyro_markov_dph=1.0, gyro_markov_tau_s=10.0),
                  np.random.default_rng(12))
    dth, _ = e.apply(np.zeros((n, 3)), np.zeros((n, 3)), dt)
    for tau_s in (1.0, 10.0, 100.0):
        tau, g = allan_deviation(dth / dt, dt, [int(round(tau_s / dt))])
        gc = adev_markov(1.0 * DPH, 10.0, tau[0])
        rows.append(('gyro Markov 1 deg/h, 10 s', tau_s, gc / DPH, g[0].mean() / DPH,
                     g[0].mean() / gc))
    return rows


def main():
    """Measure, print and write the markdown report."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--out', default=str(Path(__file__).parent / 'results' / 'sim_accuracy.md'))
    args = ap.parse_args()
    lines = ['# Simulator and mechanization accuracy', '',
             f"Command: `python bench/sim_accuracy.py`; machine: {platform.machine()}, "
             f"{os.cpu_count()} cores, "
             f'{platform.python_implementation()} {platform.python_version()}', '',
             '## Error-free IMU through the mechanization, 600 s at 100 Hz', '',
             '| trajectory | max attitude err (arcsec) | max velocity err (m/s) '
             '| max position err (m) | distance travelled (m) | IMU gen (samples/s) '
             '| mechanization (samples/s) |', '|---|---|---|---|---|---|---|']
    for name, att, vel, pos, dist, tg, tm, n in truth_reproduction():
        lines.append(f'| {name} | {att:.2e} | {vel:.2e} | {pos:.2e} | {dist:.0f} | '
                     f'{n / tg:,.0f} | {n / tm:,.0f} |')
    lines += ['', 'Acceptance: attitude < 2 arcsec, position < 1 m underway.', '',
              '## Allan deviation of simulated noise', '',
              '| term | tau (s) | configured | measured | ratio |', '|---|---|---|---|---|']
    for q, tau, c, m, r in allan_check():
        unit = 'deg/h' if 'deg' in q else 'ug'
        lines.append(f'| {q} | {tau:g} | {c:.4g} {unit} | {m:.4g} {unit} | {r:.3f} |')
    lines += ['', 'Acceptance: ratio within 0.90-1.10.']
    print(write_markdown(args.out, lines))


if __name__ == '__main__':
    main()

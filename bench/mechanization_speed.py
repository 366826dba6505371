#!/usr/bin/env python3
"""Strapdown mechanization speed against pyins's numba integrator (issue 22, must-show 2).

The same 1200 s of 100 Hz increments (120,000 samples of ``ship_underway``, our
simulator) through four integrators, side by side in one process, alternating, after
a warm-up call that compiles or loads each from its cache:

- ``pyins core``: ``pyins._numba_integrate.integrate``, the numba loop inside
  ``pyins.strapdown.Integrator`` (arrays in, arrays out; the strictest comparison);
- ``pyins Integrator``: ``pyins.strapdown.Integrator.integrate``, the public call, with
  its pandas input and output;
- ``ours run``: ``Strapdown.run``, our batch path (``nav.kernels.strapdown_run``, compiled);
- ``ours step``: ``Strapdown.step`` per sample, the scalar Python path the filters used
  before the kernel (timed on a tenth of the samples and scaled).

pyins is a test and bench dependency only (requirements-test.txt). Reports the median
of ``--repeats`` timings and the ratio pyins / ours (>= 1: ours at least as fast).

Usage: python bench/mechanization_speed.py [--repeats 7] [--out FILE]
"""
import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from sins_align_ros.eval.markdown import machine_summary  # noqa: E402
from sins_align_ros import compiled  # noqa: E402
from sins_align_ros.nav.frames import euler_to_dcm  # noqa: E402
from sins_align_ros.nav.mechanization import Strapdown  # noqa: E402
from sins_align_ros.sim.imu import ImuSimulator, ImuSpec  # noqa: E402
from sins_align_ros.sim.presets import scenario  # noqa: E402

RATE_HZ = 100.0
SECONDS = 1200.0


def samples():
    """``(e0, v0, p0, dtheta, dv, dt)`` of the case: ship_underway, 1200 s at 100 Hz."""
    sim = ImuSimulator(scenario('ship_underway').trajectory, ImuSpec(), RATE_HZ, seed=1)
    e0, v0, p0 = sim.initial_truth()
    c = sim.next_chunk(int(SECONDS * RATE_HZ))
    n = len(c.t)
    return (e0, v0, p0, np.ascontiguousarray(c.dtheta), np.ascontiguousarray(c.dv),
            np.full(n, 1.0 / RATE_HZ))


def integrators(case):
    """Return {name: zero-argument callable integrating the whole case once}."""
    import pandas as pd
    from pyins import strapdown
    from pyins._numba_integrate import integrate
    e0, v0, p0, dtheta, dv, dt = case
    n = len(dt)
    lla0 = [np.degrees(p0[0]), np.degrees(p0[1]), p0[2]]
    # pyins's frame is NED with a (roll, pitch, heading) attitude; the numbers differ from
    # ours, the work per sample does not
    vel0 = [v0[1], v0[0], -v0[2]]

    def pyins_core():
        lla = np.empty((n + 1, 3))
        vel = np.empty((n + 1, 3))
        mat = np.empty((n + 1, 3, 3))
        lla[0], vel[0], mat[0] = lla0, vel0, np.eye(3)
        integrate(dt, lla, vel, mat, dtheta, dv, 0, True)

    t = np.arange(1, n + 1) / RATE_HZ
    inc = pd.DataFrame(np.column_stack([dt, dtheta, dv]), index=t,
                       columns=['dt', 'theta_x', 'theta_y', 'theta_z', 'dv_x', 'dv_y', 'dv_z'])
    pva = pd.Series({'lat': lla0[0], 'lon': lla0[1], 'alt': lla0[2], 'VN': vel0[0],
                     'VE': vel0[1], 'VD': vel0[2], 'roll': 0.0, 'pitch': 0.0,
                     'heading': 0.0})
    pva.name = 0.0

    def pyins_integrator():
        strapdown.Integrator(pva).integrate(inc)

    def ours_run():
        Strapdown(euler_to_dcm(e0), v0, *p0).run(dtheta, dv, dt)

    def ours_step():
        nav = Strapdown(euler_to_dcm(e0), v0, *p0)
        for k in range(n // 10):
            nav.step(dtheta[k], dv[k], dt[k])

    return {'pyins core': pyins_core, 'pyins Integrator': pyins_integrator,
            'ours run': ours_run, 'ours step': ours_step}


COLD = """
import sys, time
t0 = time.perf_counter()
sys.path.insert(0, {root!r})
import numpy as np
from sins_align_ros.nav.mechanization import Strapdown
Strapdown(np.eye(3), np.zeros(3), 0.6, 2.0, 0.0).run(np.zeros((10, 3)), np.zeros((10, 3)), 0.01)
print(time.perf_counter() - t0)
"""


def start_up(cache_dir, aot=False):
    """Seconds from a new interpreter to the first ``Strapdown.run`` result.

    Imports included. ``aot``: the ahead-of-time kernel module (``_aot_kernels``);
    else numba's just-in-time path (``SINS_ALIGN_NO_AOT=1``) with ``NUMBA_CACHE_DIR`` at
    ``cache_dir`` (empty: it compiles and writes the cache; filled: it loads).
    """
    import os
    import subprocess
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    env.pop('SINS_ALIGN_NO_AOT', None)
    if not aot:
        env['SINS_ALIGN_NO_AOT'] = '1'
    code = COLD.format(root=str(Path(__file__).resolve().parents[1]))
    out = subprocess.run([sys.executable, '-c', code], env=env, check=True,
                         capture_output=True, text=True).stdout
    return float(out.strip().splitlines()[-1])


def main(argv=None):
    """Time the integrators and write the table; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--repeats', type=int, default=7)
    ap.add_argument('--out', default=str(Path(__file__).parent / 'results' /
                                         'mechanization_speed.md'))
    args = ap.parse_args(argv)
    import tempfile
    with tempfile.TemporaryDirectory() as cache:
        cold = start_up(cache)
        warm_start = statistics.median(start_up(cache) for _ in range(3))
        aot_start = statistics.median(start_up(cache, aot=True) for _ in range(3)) \
            if compiled.AOT is not None else None
    case = samples()
    funcs = integrators(case)
    warm = {}
    for name, f in funcs.items():
        t0 = time.perf_counter()
        f()
        warm[name] = time.perf_counter() - t0
    times = {name: [] for name in funcs}
    for _ in range(args.repeats):
        for name, f in funcs.items():
            t0 = time.perf_counter()
            f()
            times[name].append(time.perf_counter() - t0)
    med = {k: statistics.median(v) for k, v in times.items()}
    med['ours step'] *= 10.0                  # timed on a tenth of the samples
    n = len(case[5])
    lines = ['# Mechanization speed (issue 22, must-show 2)', '',
             f'Command: `python bench/mechanization_speed.py --repeats {args.repeats}` on '
             f'{machine_summary()}; kernels compiled: {compiled.COMPILED}, ahead of time: '
             f'{compiled.AOT is not None}.', '',
             f'{n} samples ({SECONDS:.0f} s at {RATE_HZ:.0f} Hz, ship_underway), each '
             'integrator timed alternately in one process, median of '
             f'{args.repeats} runs after a warm-up call (first call, compile or cache load, '
             'in the last column).', '',
             '| integrator | median s | x real time | pyins core / this | first call s |',
             '|---|---|---|---|---|']
    for name in funcs:
        lines.append(f'| {name} | {med[name]:.4f} | {SECONDS / med[name]:,.0f} | '
                     f'{med["pyins core"] / med[name]:.2f} | {warm[name]:.3f} |')
    ratio = med['pyins core'] / med['ours run']
    lines += ['', f'**ours run / pyins core: {ratio:.2f}x as fast** (must-show 2: at least '
              f'1); against the public `Integrator.integrate`: '
              f'{med["pyins Integrator"] / med["ours run"]:.2f}x. `Strapdown.run` is '
              f'{med["ours step"] / med["ours run"]:.0f}x faster than the per-sample '
              '`step` path.', '',
              'Start-up, a new Python process to the first `Strapdown.run` result (imports '
              'included; median of 3): '
              + (f'{aot_start:.2f} s with the ahead-of-time kernels (`_aot_kernels`, '
                 'numba not imported); ' if aot_start is not None else '')
              + f'just in time (`SINS_ALIGN_NO_AOT=1`) {cold:.2f} s with an empty numba '
              f'cache (it compiles and writes the cache), {warm_start:.2f} s with the cache '
              'filled.', '']
    Path(args.out).write_text('\n'.join(lines))
    print('\n'.join(lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())

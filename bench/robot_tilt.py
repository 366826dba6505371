#!/usr/bin/env python3
"""What limits the robot's tilt (issue 44 "Useful": tilt sigma <= 1.5 x accelerometer bias / g).

One ground cell of ``bench/integrity.py`` (``robot:rtk`` by default) run through the
pipeline for a few seeds, with the simulator's IMU errors switched off one group at a time
(``--variants``):

- ``base``: the cell as the matrix runs it;
- ``novib``: no vibration (gyro and accelerometer);
- ``nobias``: no accelerometer bias (constant and Gauss-Markov);
- ``nosf``: no scale factors and no axis misalignment (gyro and accelerometer);
- ``novib_nobias``, ``novib_nosf``: the two together.

Per run: the final tilt error (E, N, arcmin), its mean and RMS over the last
``--tail`` seconds in ENU and in the body's roll/pitch axes (a tilt fixed to the vehicle,
such as an accelerometer bias taken for a tilt, is constant there while the robot turns;
noise is not), the published tilt sigma at the end and the part of it the filter's
covariance holds (without ``FineStage.floor``), and the filter's accelerometer-bias
estimate against the simulated one (body x, y, mg). Parameters of the pipeline can be
overridden (``--set name=value``), e.g. ``sensor_self_check=False``.

Usage: python bench/robot_tilt.py [--key robot:rtk] [--grade mems] [--filter kf]
       [--told right] [--seeds 1000-1004] [--variants base,novib] [--tail 150]
       [--set name=value ...]
"""
import argparse
import os
import sys
from pathlib import Path

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'bench'))

import integrity  # noqa: E402
from sins_align_ros.eval.cache import simulate_cached  # noqa: E402
from sins_align_ros.eval.integrity import published_sigma  # noqa: E402
from sins_align_ros.eval.run import run_pipeline  # noqa: E402
from sins_align_ros.nav.frames import euler_to_dcm  # noqa: E402
from sins_align_ros.sim.scenario import ScenarioStream  # noqa: E402
from sins_align_ros.units import DEG, G0  # noqa: E402

AM = 60.0 / DEG     # rad -> arcmin
#: simulator fields each variant zeroes
VARIANTS = {
    'base': {},
    'novib': {'vibration_gyro_dps': 0.0, 'vibration_accel_mps2': 0.0},
    'nobias': {'accel_bias_ug': 0.0, 'accel_markov_ug': 0.0},
    'nosf': {'gyro_scale_ppm': 0.0, 'gyro_misalign_ppm': 0.0, 'accel_scale_ppm': 0.0,
             'accel_misalign_ppm': 0.0},
}
VARIANTS['novib_nobias'] = {**VARIANTS['novib'], **VARIANTS['nobias']}
VARIANTS['novib_nosf'] = {**VARIANTS['novib'], **VARIANTS['nosf']}
CACHE = Path(os.environ.get('TMPDIR', '/tmp')) / 'sins_align_robot_tilt_cache'


def scenario(key, grade, variant):
    """Return the matrix cell's scenario with the variant's simulator errors zeroed."""
    sc = integrity.scenario_of(key, grade)
    sc.imu = sc.imu.with_(**VARIANTS[variant])
    return sc


def value(text):
    """Parse a ``--set`` value: bool, number or text."""
    if text in ('True', 'False'):
        return text == 'True'
    try:
        return float(text)
    except ValueError:
        return text


def one(sc, params, seed, tail):
    """Run one seed; return the figures of the module docstring (dict)."""
    data = simulate_cached(sc, seed, CACHE)
    errors = ScenarioStream(sc, seed=seed).imu.errors      # the drawn turn-on errors
    run = run_pipeline(params, data)
    out = run.out
    t = out.t
    rows = np.flatnonzero((t >= t[-1] - tail) & np.isfinite(out.q[:, 3]))
    phi = run.phi(rows)
    C_b_n = euler_to_dcm(run.truth_euler[rows])
    phi_b = np.einsum('kji,kj->ki', C_b_n, phi)             # C_n_b phi_n
    sig = published_sigma(out.P_phi[-1])
    fine = run.pipeline.fine
    eng = run.pipeline.engine
    P_own = np.sqrt(np.diag(eng.attitude_cov()))
    nab = np.full(3, np.nan)
    if hasattr(eng, 'nab'):
        nab = eng.nab + (eng.kf.x[eng.i_nab] if hasattr(eng, 'i_nab') else 0.0)
    b_true = errors.accel_bias + errors.accel_sm @ np.array([0.0, 0.0, G0])
    return dict(end=phi[-1, :2] * AM, mean=np.mean(phi[:, :2], 0) * AM,
                rms=np.sqrt(np.mean(phi[:, :2] ** 2, 0)) * AM,
                mean_b=np.mean(phi_b[:, :2], 0) * AM,
                rms_b=np.sqrt(np.mean(phi_b[:, :2] ** 2, 0)) * AM,
                sig=sig[:2] * AM, sig_own=P_own[:2] * AM,
                floor=np.sqrt(fine.floor[:2]) * AM,
                nab=nab[:2] / G0 * 1e3, b_true=b_true[:2] / G0 * 1e3,
                phase=out.phase[-1],
                warn=[w for w in run.pipeline.warnings if 'raised' in w or 'widened' in w])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--key', default='robot:rtk')
    ap.add_argument('--grade', default='mems')
    ap.add_argument('--filter', default='kf')
    ap.add_argument('--told', default='right')
    ap.add_argument('--seeds', default='1000-1004')
    ap.add_argument('--variants', default='base')
    ap.add_argument('--tail', type=float, default=150.0)
    ap.add_argument('--set', nargs='*', default=[])
    ap.add_argument('--warnings', action='store_true')
    a = ap.parse_args(argv)
    lo, _, hi = a.seeds.partition('-')
    seeds = range(int(lo), int(hi or lo) + 1)
    over = {k: value(v) for k, v in (s.split('=', 1) for s in a.set)}
    print(f'# {a.key} {a.grade} {a.filter} told {a.told} {over or ""}; tail {a.tail:.0f} s; '
          'arcmin (E, N | body roll-axis x, pitch-axis y); bias mg (body x, y)')
    for variant in a.variants.split(','):
        sc = scenario(a.key, a.grade, variant)
        params = {**integrity.told_params(sc, a.filter, a.told), **over}
        print(f'## {variant}')
        print('seed | end E N | mean E N | rms E N | body mean x y | body rms x y | '
              'sigma E N | own sigma E N | floor | bias est x y | bias sim x y | phase')
        agg = []
        for seed in seeds:
            r = one(sc, params, seed, a.tail)
            agg.append(r)
            f = lambda v: ' '.join(f'{x:6.1f}' for x in v)  # noqa: E731
            print(f"{seed} | {f(r['end'])} | {f(r['mean'])} | {f(r['rms'])} | {f(r['mean_b'])} |"
                  f" {f(r['rms_b'])} | {f(r['sig'])} | {f(r['sig_own'])} | {f(r['floor'])} |"
                  f" {f(r['nab'])} | {f(r['b_true'])} | {r['phase']}", flush=True)
            if a.warnings:
                for w in r['warn']:
                    print('   W', w[:160])
        end = np.array([r['end'] for r in agg])
        rms = np.array([r['rms'] for r in agg])
        sig = np.array([r['sig'] for r in agg])
        print(f"{variant}: final error RMS over seeds E/N {np.sqrt(np.mean(end**2, 0))}, "
              f"tail RMS (mean of runs) {np.sqrt(np.mean(rms**2, 0))}, "
              f"sigma at the end {np.mean(sig, 0)}")


if __name__ == '__main__':
    main()

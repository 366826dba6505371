#!/usr/bin/env python3
"""External heading (issue 23, must-show 2): a 0.2 deg GNSS compass on the MEMS car and the USV.

Each scenario and seed runs twice on the same data, without and with an external heading
at 1 Hz with 0.2 deg of white noise (``sim.gnss.heading_measurements``, the variance
reported as the node would receive it): the final errors (ENU, deg), the mean final sigma,
the share ending inside 3 sigma, silent-wrong runs (``eval.integrity``), and the time from
the start of the data to the first ``aligned`` row (median over the runs that get there;
how many do). Writes ``bench/results/external_heading.md``.

Usage: python bench/external_heading.py [--runs 10] [--jobs 2] [--out FILE]
"""
import argparse
import math
import os
import subprocess
import sys
import time
from pathlib import Path

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sins_align_ros.eval.integrity import cell_stats, run_integrity  # noqa: E402
from sins_align_ros.eval.markdown import machine_summary, write_markdown  # noqa: E402
from sins_align_ros.eval.pool import monte_carlo  # noqa: E402
from sins_align_ros.eval.run import run_pipeline  # noqa: E402
from sins_align_ros.eval.scenarios import named, simulate  # noqa: E402
from sins_align_ros.sim.gnss import heading_measurements  # noqa: E402
from sins_align_ros.sim.presets import alignment_params  # noqa: E402

#: scenario -> (duration s, filters): the node's default (auto) and the seed's own filter
CASES = {
    'seed003_car': (400.0, ('auto', 'ukf')),
    'seed004_high': (300.0, ('auto', 'vbch')),
    'seed004_medium': (300.0, ('auto', 'vbch')),
    'seed004_low': (300.0, ('auto', 'vbch')),
}
SIGMA_DEG = 0.2
FIRST_SEED = 1000
RATE_HZ = 100.0


def run_job(job):
    """Worker: one scenario and seed; every filter without and with the compass."""
    name, seed = job
    duration, filters = CASES[name]
    sc = named(name, duration)
    data = simulate(sc, seed)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 23]))
    heading = heading_measurements(data.imu.t, data.imu.euler[:, 2], math.radians(SIGMA_DEG),
                                   1.0, rng)
    res = {}
    for f in filters:
        for how, hd in (('none', None), ('compass', heading)):
            run = run_pipeline(alignment_params(sc, f), data, heading=hd)
            r = run_integrity(run, RATE_HZ)
            k = np.flatnonzero(run.out.phase == 'aligned')
            r['t_aligned'] = float(run.out.t[k[0]] - data.imu.t[0]) if len(k) else math.nan
            res[(f, how)] = r
    return res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--runs', type=int, default=10)
    ap.add_argument('--jobs', type=int, default=2)
    ap.add_argument('--cases', default=','.join(CASES))
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'external_heading.md'))
    args = ap.parse_args(argv)
    cases = args.cases.split(',')
    jobs = [(c, FIRST_SEED + k) for c in cases for k in range(args.runs)]
    t0 = time.monotonic()
    results = monte_carlo(run_job, jobs, procs=args.jobs)
    cells = {}
    for (case, _), res in zip(jobs, results):
        for (f, how), r in res.items():
            cells.setdefault((case, f, how), []).append(r)
    commit = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=ROOT,
                            capture_output=True, text=True).stdout.strip()
    cmd = 'python bench/external_heading.py ' + ' '.join(
        argv if argv is not None else sys.argv[1:])
    lines = [f'# External heading: a {SIGMA_DEG} deg GNSS compass (issue 23)', '',
             f'Command: `{cmd.strip()}` on {machine_summary()}; commit {commit}; '
             f'{time.monotonic() - t0:.0f} s.', '',
             'Same seeds (from 1000) and data with and without the compass (1 Hz, '
             f'{SIGMA_DEG} deg white noise, reported variance). Errors and sigmas at the end, '
             'ENU axes (east / north / up), **deg**; *inside*: share of runs ending inside '
             '3 sigma on every axis; *silent*: runs with more than 5 % of their 1-s samples '
             'after coarse alignment outside 3 sigma on an axis, or one beyond 5 sigma '
             '(`eval.integrity`); *time to aligned*: from the first sample to the first '
             '`aligned` row, median (and how many runs got there).', '',
             '| scenario | filter | heading | runs | RMS error | mean sigma | inside | '
             'silent | time to aligned |', '|---|---|---|---|---|---|---|---|---|']
    for (case, f, how), runs in sorted(cells.items(), key=lambda kv: (
            cases.index(kv[0][0]), kv[0][1], kv[0][2] != 'none')):
        c = cell_stats(runs, np.zeros(3))
        inside = '-' if not np.isfinite(c.ended_inside) else f'{100 * c.ended_inside:.0f} %'
        ta = np.array([r['t_aligned'] for r in runs])
        got = np.isfinite(ta)
        t_al = f'{np.median(ta[got]):.0f} s ({got.sum()}/{len(ta)})' if got.any() else \
            f'never (0/{len(ta)})'
        deg = ' / '.join(f'{math.degrees(x):.3f}' for x in c.rms)
        sig = ' / '.join('unknown' if not np.isfinite(x) else f'{math.degrees(x):.3f}'
                         for x in c.sigma)
        lines.append(f'| {case} | {f} | {how} | {c.runs} | {deg} | {sig} | {inside} | '
                     f'{c.silent} | {t_al} |')
    write_markdown(args.out, lines)
    print('\n'.join(lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())

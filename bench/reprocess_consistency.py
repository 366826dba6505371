"""Whether the GNSS-aided reprocessing of the coarse window is as consistent as the default flow.

Issue 46: the integrity matrix's 10 runs per cell found the aided reprocessing
(``coarse_reprocess_aided``) silent-wrong on a few cells (seed 003's tactical car, seeds
1002 and 1008). Ten runs cannot tell a filter whose sigma is too narrow from two unlucky
seeds. This bench runs one integrity-matrix cell (``bench/integrity.py``'s scenarios,
grades and ``told`` parameters) over many seeds with the reprocessing off and on, and at
given times reports per ENU axis the mean of ``z^2 = (error / sigma)^2`` over the seeds
(1 for a consistent filter; over N seeds its 95 % band is about ``1 +- 2 sqrt(2 / N)``),
the share of runs with ``|z| > 2.5`` (1.2 % for a Gaussian) and the runs' worst share of
1-s rows outside 3 sigma (the matrix's silent-wrong rule: above 5 %).

The seeds are 1000.. as the matrix's; the sensor biases are the same constants in every
run (``sim.presets.SENSOR_GRADES``), so the runs share them and the mean ``z^2`` carries
that one draw.

Usage: python bench/reprocess_consistency.py --scenario seed003_car --grade tactical
       --filter kf [--told right] [--runs 100] [--jobs 2] [--times 40,99,130,170,250,390]
       [--out FILE.md]
"""
import argparse
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import integrity as I  # noqa: E402,E741

from sins_align_ros.eval.cache import simulate_cached  # noqa: E402
from sins_align_ros.eval.errors import attitude_errors  # noqa: E402
from sins_align_ros.eval.pool import monte_carlo  # noqa: E402
from sins_align_ros.eval.run import run_pipeline  # noqa: E402

AXES = ('E', 'N', 'U')


def one(job):
    """Run one seed of the cell; return ``(z at the times (T, 3), share outside 3 sigma)``."""
    key, grade, fine_filter, told, seed, aided, times = job
    sc = I.scenario_of(key, grade)
    data = simulate_cached(sc, seed, I.CACHE)
    prm = I.told_params(sc, fine_filter, told)
    prm['coarse_reprocess_aided'] = aided
    r = run_pipeline(prm, data)
    t = r.out.t - data.imu.t[0]
    e = attitude_errors(r.out, data.imu.euler[:len(t)], np.arange(len(t)))
    z = e / r.out.sigma
    idx = [min(int(np.searchsorted(t, tt)), len(t) - 1) for tt in times]
    fine = np.flatnonzero(np.asarray(r.out.phase) != 'coarse')
    rows = fine[::int(I.RATE_HZ)] if len(fine) else fine
    share = float(np.mean(np.any(np.abs(z[rows]) > 3.0, axis=1))) if len(rows) else 0.0
    return z[idx], share


def table(args, results):
    """Return the markdown table of both flows: a row per time."""
    lines = ['| flow | t (s) | mean z^2 E / N / U | runs with abs(z) > 2.5 E / N / U |',
             '|---|---|---|---|']
    for aided, res in results:
        Z = np.array([r[0] for r in res])
        for j, tt in enumerate(args.times):
            m2 = ' / '.join(f'{np.mean(Z[:, j, a] ** 2):.2f}' for a in range(3))
            out = ' / '.join(f'{np.mean(np.abs(Z[:, j, a]) > 2.5):.0%}' for a in range(3))
            lines.append(f'| {"reprocessed" if aided else "default"} | {tt:g} | {m2} | {out} |')
    lines += ['', '| flow | runs silent (over 5 % of 1-s rows outside 3 sigma) | worst run |',
              '|---|---|---|']
    for aided, res in results:
        share = np.array([r[1] for r in res])
        lines.append(f'| {"reprocessed" if aided else "default"} | {np.sum(share > 0.05)} of '
                     f'{len(share)} | {share.max():.1%} |')
    return '\n'.join(lines)


def main(argv=None):
    """Run the cell both ways over the seeds; print (and write) the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--scenario', default='seed003_car')
    ap.add_argument('--grade', default='tactical')
    ap.add_argument('--filter', default='kf')
    ap.add_argument('--told', default='right', choices=('right', 'defaults'))
    ap.add_argument('--runs', type=int, default=100)
    ap.add_argument('--jobs', type=int, default=2)
    ap.add_argument('--times', default='40,99,130,170,250,390')
    ap.add_argument('--out', default=None)
    args = ap.parse_args(argv)
    args.times = [float(x) for x in args.times.split(',')]
    t0 = time.time()
    results = []
    for aided in (False, True):
        jobs = [(args.scenario, args.grade, args.filter, args.told, 1000 + i, aided,
                 args.times) for i in range(args.runs)]
        results.append((aided, monte_carlo(one, jobs, procs=args.jobs)))
    commit = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], capture_output=True,
                            text=True).stdout.strip()
    head = (f'{args.filter} on {args.scenario} at {args.grade} grade, told {args.told}, '
            f'{args.runs} seeds from 1000, each with `coarse_reprocess_aided` off (default) '
            f'and on; {time.time() - t0:.0f} s on {platform.machine()}, '
            f'{subprocess.os.cpu_count()} cores, commit {commit}.\n\nCommand: `python '
            f'bench/reprocess_consistency.py {" ".join(argv if argv else sys.argv[1:])}`\n')
    text = head + '\n' + table(args, results) + '\n'
    print(text)
    if args.out:
        Path(args.out).write_text(text)


if __name__ == '__main__':
    main()

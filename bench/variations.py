#!/usr/bin/env python3
"""The node's default away from our own scenarios: sites, headings and rates (issue 21).

``auto`` (the node's default filter) told only the site, as a newcomer runs it, or the
right sensor model (``--told right``), on four of our scenarios (still base, car, ship
underway, USV in severe sea) with one thing changed at a time: the latitude (40 S, the
equator, 65 N, 78 N), the heading at the start (200, 300 deg), the IMU rate (50, 400 Hz)
or the GNSS rate (5 Hz). Each grade (navigation, tactical, MEMS) and ``--seeds`` seeds
from 2000 (the integrity matrix uses 1000-1009). A run is *flagged* when it is silent-wrong
(``eval.integrity``: more than 5 % of its 1-s samples outside 3 sigma on a published
axis, or one beyond 5 sigma) or ends outside 3 sigma.

Each checkout given by ``--roots`` runs in its own process on the same simulations, so a
fix can be shown against the commit before it (``git worktree add /tmp/old <commit>``).

Usage: python bench/variations.py [--roots OLD NEW --labels before after] [--seeds 3]
       [--told defaults|right] [--only base:variant,...] [--jobs 2] [--out FILE]
"""
import argparse
import dataclasses
import os
import pickle
import subprocess
import sys
import tempfile
from pathlib import Path

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

ROOT = Path(__file__).resolve().parents[1]
# the checkout whose package a worker runs (--root), else this one
_ROOT_ARG = sys.argv[sys.argv.index('--root') + 1] if '--root' in sys.argv else str(ROOT)
sys.path.insert(0, _ROOT_ARG)

import numpy as np  # noqa: E402

from sins_align_ros.eval.integrity import run_integrity  # noqa: E402
from sins_align_ros.eval.markdown import page_head, write_markdown  # noqa: E402
from sins_align_ros.eval.pool import monte_carlo  # noqa: E402
from sins_align_ros.eval.run import run_pipeline  # noqa: E402
from sins_align_ros.eval.scenarios import named  # noqa: E402
from sins_align_ros.sim.presets import alignment_params  # noqa: E402
from sins_align_ros.sim.scenario import ScenarioStream  # noqa: E402

#: key -> (preset, duration s)
BASES = {'still': ('static_navigation', 300.0), 'car': ('seed003_car', 400.0),
         'ship': ('ship_underway', 500.0), 'usv': ('seed004_medium', 300.0)}
#: variant -> what it changes
VARIANTS = {'as is': {}, 'lat -40': {'lat': -40.0}, 'lat 1': {'lat': 1.0},
            'lat 65': {'lat': 65.0}, 'lat 78': {'lat': 78.0}, 'heading 200': {'hdg': 200.0},
            'heading 300': {'hdg': 300.0}, 'IMU 50 Hz': {'imu': 50.0},
            'IMU 400 Hz': {'imu': 400.0}, 'GNSS 5 Hz': {'gnss': 5.0}}
GRADES = ('navigation', 'tactical', 'mems')
SITE = ('initial_latitude_deg', 'initial_longitude_deg', 'initial_height_m')
FIRST_SEED = 2000


def scenario(base, grade, variant):
    """Build the scenario of ``base`` with the IMU of ``grade`` and ``variant`` applied."""
    preset, duration = BASES[base]
    sc = named(f'{preset}@{grade}', duration)
    v = VARIANTS[variant]
    if 'lat' in v:
        sc.trajectory.lat_deg = v['lat']
    if 'hdg' in v:
        sc.trajectory.heading_deg = v['hdg']
    if 'imu' in v:
        sc.imu_rate_hz = v['imu']
    if 'gnss' in v and sc.gnss is not None:
        sc.gnss = dataclasses.replace(sc.gnss, rate_hz=v['gnss'])
    return sc


def one(job):
    """Worker: ``(base, grade, variant, seed, told)`` -> the run's integrity figures."""
    base, grade, variant, seed, told = job
    sc = scenario(base, grade, variant)
    data = ScenarioStream(sc, seed=seed).next_block(int(round(sc.duration * sc.imu_rate_hz)))
    right = alignment_params(sc, 'auto')
    p = right if told == 'right' else {'fine_filter': 'auto', **{k: right[k] for k in SITE}}
    run = run_pipeline(p, data)
    r = run_integrity(run, sc.imu_rate_hz)
    r['ran'] = run.pipeline.cfg['fine_filter']
    return job, r


def jobs_of(args):
    """Every (base, grade, variant, seed, told) of the requested runs."""
    only = [tuple(x.split(':')) for x in args.only.split(',')] if args.only else None
    return [(b, g, v, s, args.told) for b in BASES for v in VARIANTS
            if only is None or (b, v) in only for g in GRADES
            for s in range(FIRST_SEED, FIRST_SEED + args.seeds)]


def flagged(r):
    """Return the reason to flag a run, or '' when it passes."""
    if r['silent']:
        return 'silent-wrong: ' + r['why']
    if r['end_inside'] is False:
        return 'ends outside 3 sigma'
    return ''


def worker(args):
    """Run every job with this process's package and save the results to ``args.raw``."""
    res = monte_carlo(one, jobs_of(args), args.jobs, progress=False)
    with open(args.raw, 'wb') as fh:
        pickle.dump(res, fh)
    return 0


def main(argv=None):
    """Run the checkouts and write the page; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--roots', nargs='+', default=[str(ROOT)])
    ap.add_argument('--labels', nargs='+')
    ap.add_argument('--seeds', type=int, default=3)
    ap.add_argument('--told', default='defaults', choices=('defaults', 'right'))
    ap.add_argument('--only', default='', help='base:variant pairs, e.g. "usv:GNSS 5 Hz"')
    ap.add_argument('--jobs', type=int, default=2)
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'variations.md'))
    ap.add_argument('--root', help=argparse.SUPPRESS)
    ap.add_argument('--raw', help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.root:
        return worker(args)
    labels = args.labels or [Path(r).name for r in args.roots]
    per_root = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, root in enumerate(args.roots):
            raw = str(Path(tmp) / f'{k}.pkl')
            cmd = [sys.executable, str(Path(__file__).resolve()), '--root', root, '--raw', raw,
                   '--seeds', str(args.seeds), '--told', args.told, '--jobs', str(args.jobs)]
            if args.only:
                cmd += ['--only', args.only]
            subprocess.run(cmd, check=True)
            with open(raw, 'rb') as fh:
                per_root.append(dict(pickle.load(fh)))
    command = ('python bench/variations.py' + (f' --roots {" ".join(args.roots)} --labels '
                                               f'{" ".join(labels)}' if args.labels else '')
               + f' --seeds {args.seeds} --told {args.told}'
               + (f' --only "{args.only}"' if args.only else ''))
    lines = page_head('`auto` on other sites, headings and rates (issue 21)', command,
                      __doc__.split('\n\n')[1].replace('\n', ' '),
                      f'Runs per row: {len(GRADES)} grades x {args.seeds} seeds; told '
                      f'**{args.told}**. Flagged runs per checkout:')
    rows = sorted({(j[0], j[2]) for j in per_root[0]}, key=lambda bv: (
        list(BASES).index(bv[0]), list(VARIANTS).index(bv[1])))
    lines += ['| scenario | variant | runs | ' + ' | '.join(f'flagged ({x})' for x in labels)
              + ' |', '|---|---|---|' + '---|' * len(labels)]
    total = [0] * len(labels)
    for b, v in rows:
        keys = [j for j in per_root[0] if j[0] == b and j[2] == v]
        n = [sum(bool(flagged(res[j])) for j in keys) for res in per_root]
        total = [t + x for t, x in zip(total, n)]
        lines.append(f'| {b} | {v} | {len(keys)} | ' + ' | '.join(map(str, n)) + ' |')
    lines += ['', f'In all: {" / ".join(f"{t} ({x})" for t, x in zip(total, labels))} flagged '
              f'of {len(per_root[0])} runs each.', '', 'The flagged runs (final error / '
              'published sigma, arcmin, E/N/U):', '']
    for label, res in zip(labels, per_root):
        for j, r in res.items():
            why = flagged(r)
            if why:
                e = np.degrees(r['end_err']) * 60.0
                s = np.degrees(r['end_sigma']) * 60.0
                lines.append(f'- {label}: {j[0]}, {j[2]}, {j[1]}, seed {j[3]} ({r["ran"]}): '
                             f'{why}; end {" / ".join(f"{x:.1f}" for x in e)} under '
                             f'{" / ".join(f"{x:.1f}" for x in s)}')
    write_markdown(args.out, lines)
    print('\n'.join(lines[-40:]))
    return 0


if __name__ == '__main__':
    sys.exit(main())

#!/usr/bin/env python3
"""Sharpness at the last instant against sharpness over the last minutes (issue 21).

The integrity matrix (``bench/integrity.py``) calls a sigma too wide when the mean
published sigma at the end of the runs is more than 3x the RMS of the final errors over
the runs. With 10 runs on one simulated trajectory, that RMS is taken at one instant of a
time-correlated error, and all runs share the motion that makes the heading observable.
This script runs the cells it is given (the same scenarios, seeds and parameters as the
matrix) and reports, per axis, the RMS error over the runs and the mean sigma at several
times before the end, and the sharpness at the end against over the last ``--window``
seconds (RMS over runs and samples).

Usage: python bench/sharpness_window.py [--cells vbch:seed004:navigation:right,...]
                                        [--runs 10] [--window 120] [--out FILE]
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from integrity import CACHE, RATE_HZ, scenario_of, told_params  # noqa: E402

from sins_align_ros.eval.cache import simulate_cached  # noqa: E402
from sins_align_ros.eval.integrity import published_sigma, sample_rows  # noqa: E402
from sins_align_ros.eval.markdown import page_head, write_markdown  # noqa: E402
from sins_align_ros.eval.pool import monte_carlo  # noqa: E402
from sins_align_ros.eval.run import run_pipeline  # noqa: E402

CELLS = 'vbch:seed004:navigation:right,vbckf:seed004:navigation:right'
OFFSETS = (120, 90, 60, 30, 20, 10, 1)
AXES = 'ENU'


def one(job):
    """Errors and sigmas (arcmin) of the last ``window`` 1-s samples of one run."""
    f, key, grade, told, seed, window = job
    sc = scenario_of(key, grade)
    run = run_pipeline(told_params(sc, f, told), simulate_cached(sc, seed, CACHE))
    rows = sample_rows(run.out, RATE_HZ)[-window:]
    err = np.degrees(run.phi(rows)) * 60.0
    sig = np.degrees(published_sigma(run.out.P_phi[rows])) * 60.0
    return err, sig


def main(argv=None):
    """Run the cells and write the table; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--cells', default=CELLS)
    ap.add_argument('--runs', type=int, default=10)
    ap.add_argument('--window', type=int, default=120)
    ap.add_argument('--jobs', type=int, default=2)
    ap.add_argument('--out', default=str(Path(__file__).parent / 'results' /
                                         'sharpness_window.md'))
    args = ap.parse_args(argv)
    lines = page_head('Sharpness at the end against the last minutes (issue 21)',
                      f'python bench/sharpness_window.py --cells {args.cells} --runs '
                      f'{args.runs} --window {args.window}',
                      f'Seeds 1000-{999 + args.runs}, the integrity matrix\'s scenarios and '
                      'parameters. Per time before the end: the RMS error over the runs and '
                      'the mean published sigma (arcmin). Sharpness = mean sigma / RMS error, '
                      'at the end (the matrix\'s) and over the last '
                      f'{args.window} s (all runs and 1-s samples).')
    for cell in args.cells.split(','):
        f, key, grade, told = cell.split(':')
        jobs = [(f, key, grade, told, s, args.window) for s in range(1000, 1000 + args.runs)]
        res = monte_carlo(one, jobs, args.jobs, progress=False)
        E = np.array([r[0] for r in res])
        S = np.array([r[1] for r in res])
        lines += [f'## {f}, {key}, {grade} grade, told {told}', '',
                  '| s before the end | ' + ' | '.join(f'RMS {a} | sigma {a}' for a in AXES)
                  + ' |', '|---|' + '---|' * 6]
        for off in (o for o in OFFSETS if o <= E.shape[1]):
            k = E.shape[1] - off
            rms = np.sqrt(np.mean(E[:, k] ** 2, axis=0))
            sig = S[:, k].mean(axis=0)
            lines.append(f'| {off} | ' + ' | '.join(f'{r:.2f} | {s:.2f}'
                                                    for r, s in zip(rms, sig)) + ' |')
        end = S[:, -1].mean(axis=0) / np.sqrt(np.mean(E[:, -1] ** 2, axis=0))
        win = S.mean(axis=(0, 1)) / np.sqrt(np.mean(E ** 2, axis=(0, 1)))
        lines += ['', f'Sharpness E/N/U at the end: {" / ".join(f"{x:.2f}" for x in end)}; '
                  f'over the last {args.window} s: {" / ".join(f"{x:.2f}" for x in win)}.', '']
        print('\n'.join(lines[-12:]), flush=True)
    write_markdown(args.out, lines)
    return 0


if __name__ == '__main__':
    sys.exit(main())

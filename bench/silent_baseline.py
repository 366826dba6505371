#!/usr/bin/env python3
"""What a perfectly consistent filter scores under the integrity matrix's rules (issue 21).

The matrix (``bench/integrity.py``) calls a run silent-wrong when, on some axis, more than
5 % of its 1-s samples after coarse alignment lie outside 3 sigma, or one lies beyond
5 sigma (``eval.integrity.silent_wrong``). An alignment error is not white: it is a slowly
varying quantity, correlated over tens of seconds. A filter whose sigma is exactly right
still has runs whose error spends a stretch beyond 3 sigma; how many depends on that
correlation time. This script measures it: the error on each of 3 axes is a unit-variance
Gauss-Markov (Ornstein-Uhlenbeck) process of correlation time ``tau``, sampled at 1 Hz
over ``--seconds`` (the matrix's 240 s of fine alignment), the published sigma is the
truth times ``inflation`` (1: exactly consistent), and the package's own
``silent_wrong`` and ``inside_at_end`` are applied to ``--runs`` seeded runs.

Usage: python bench/silent_baseline.py [--runs 20000] [--seconds 240] [--out FILE]
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from sins_align_ros.eval.integrity import inside_at_end, silent_wrong  # noqa: E402

TAUS = (1.0, 10.0, 30.0, 60.0, 120.0)
INFLATIONS = (1.0, 1.2, 1.5)


def gauss_markov(rng, runs, seconds, tau):
    """Unit-variance Gauss-Markov samples (runs, seconds, 3) at 1 Hz, correlation ``tau`` s."""
    a = np.exp(-1.0 / tau)
    z = np.empty((runs, seconds, 3))
    z[:, 0] = rng.standard_normal((runs, 3))
    w = np.sqrt(1.0 - a * a)
    for k in range(1, seconds):
        z[:, k] = a * z[:, k - 1] + w * rng.standard_normal((runs, 3))
    return z


def main(argv=None):
    """Write the table; returns the process exit code."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--runs', type=int, default=20000)
    ap.add_argument('--seconds', type=int, default=240)
    ap.add_argument('--seed', type=int, default=21)
    ap.add_argument('--out', default=str(Path(__file__).parent / 'results' / 'silent_baseline.md'))
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    rows = []
    for tau in TAUS:
        err = gauss_markov(rng, args.runs, args.seconds, tau)
        for infl in INFLATIONS:
            sigma = np.full(3, infl)
            silent = sum(silent_wrong(e, np.broadcast_to(sigma, e.shape))[0] for e in err)
            ends = sum(bool(inside_at_end(e[-1], sigma)) for e in err)
            rows.append((tau, infl, 100.0 * silent / args.runs, 100.0 * ends / args.runs))
            print(f'tau {tau:5.0f} s  sigma x{infl}: silent {rows[-1][2]:.2f} %, '
                  f'end inside 3 sigma {rows[-1][3]:.2f} %', flush=True)
    lines = [
        '# Silent-wrong runs of a perfectly consistent filter',
        '',
        f'`python bench/silent_baseline.py --runs {args.runs} --seconds {args.seconds}` '
        f'(seed {args.seed}). The error on each of 3 axes is a unit-variance Gauss-Markov '
        'process of correlation time tau sampled at 1 Hz; the published sigma is the truth '
        'times the inflation (1: exactly consistent); the rules are the integrity matrix\'s '
        '(`eval.integrity.silent_wrong`, `inside_at_end`).',
        '',
        '| tau (s) | sigma / truth | silent-wrong runs | ending inside 3 sigma |',
        '|---|---|---|---|']
    lines += [f'| {t:g} | {i:g} | {s:.2f} % | {e:.2f} % |' for t, i, s, e in rows]
    lines += ['', 'Alignment errors are correlated over tens of seconds (the filters\' '
              'time constants): there an exactly consistent filter is silent-wrong in '
              'about 3-5 % of runs, some 100-150 of the matrix\'s 3060; a sigma 1.2x the '
              'truth brings that to about 0.3-0.7 %, 1.5x to about 0.01 %. "No '
              'silent-wrong run in 3060" asks for sigmas about 1.5x conservative wherever '
              'the error is correlated.', '']
    Path(args.out).write_text('\n'.join(lines))
    print('wrote', args.out)
    return 0


if __name__ == '__main__':
    sys.exit(main())

#!/usr/bin/env python3
"""How the pipeline's cost grows with the IMU rate (issue 22, must-show 6).

``ship_underway`` (600 s, 1 Hz GNSS position and velocity) simulated at 100, 400 and
1000 Hz and run through ``AlignmentPipeline`` (``eval.run.run_pipeline``, blocks of one
second of samples, so GNSS is never given more than 1 s ahead of the IMU, as in the
replay and the node) with each filter asked for; best of ``--repeats`` after a warm-up run. Reports
x real time and the cost per IMU sample; linear in samples means the per-sample cost
stays flat (the per-GNSS-epoch work is the same at every rate, so it falls a little).

Usage: python bench/scaling.py [--filters asckf,kf,stationary12] [--repeats 3] [--out FILE]
"""
import argparse
import dataclasses
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from sins_align_ros.eval.markdown import page_head, write_markdown  # noqa: E402
from sins_align_ros.eval.run import run_pipeline  # noqa: E402
from sins_align_ros.eval.scenarios import named, simulate  # noqa: E402
from sins_align_ros.sim.presets import alignment_params  # noqa: E402

SECONDS = 600.0
RATES = (100.0, 400.0, 1000.0)
#: filter -> scenario it runs on
CASES = {'asckf': 'ship_underway', 'kf': 'ship_underway', 'stationary12': 'static_navigation'}


def main(argv=None):
    """Time every filter at every rate and write the table; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--filters', default=','.join(CASES))
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'scaling.md'))
    args = ap.parse_args(argv)
    lines = page_head('Cost against IMU rate (issue 22, must-show 6)',
                      f'python bench/scaling.py --filters {args.filters} --repeats '
                      f'{args.repeats}',
                      f'{SECONDS:.0f} s of each scenario, pipeline only (no file input or '
                      'output), blocks of 1 s of samples, '
                      f'best of {args.repeats} after a warm-up run.')
    lines += ['| filter | scenario | IMU Hz | samples | s | x real time | us per sample |',
              '|---|---|---|---|---|---|---|']
    for f in args.filters.split(','):
        for rate in RATES:
            sc = dataclasses.replace(named(CASES[f], SECONDS), imu_rate_hz=rate)
            data = simulate(sc, 1)
            p = alignment_params(sc, f)
            block = int(rate)
            run_pipeline(p, data, block=block)
            wall = min(run_pipeline(p, data, block=block).wall for _ in range(args.repeats))
            n = len(data.imu.t)
            lines.append(f'| {f} | {CASES[f]} | {rate:.0f} | {n} | {wall:.3f} | '
                         f'{SECONDS / wall:,.0f} | {wall / n * 1e6:.2f} |')
            print(lines[-1], flush=True)
    print(write_markdown(args.out, lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())

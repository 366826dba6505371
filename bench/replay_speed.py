#!/usr/bin/env python3
"""Every fine filter's replay speed, x real time, in two checkouts side by side (issue 22).

For each fine filter (and ``auto``) a scenario it applies to is simulated (seed 1, 600 s
of 100 Hz IMU with 1 Hz GNSS position and velocity) and run through
``AlignmentPipeline`` (``eval.run.run_pipeline``, blocks of 1000 samples): coarse and fine
alignment, no file reading or writing. Each checkout given by ``--roots`` runs in its own
Python process, one filter at a time, alternating, best of ``--repeats``; the simulation
is the same in both (the simulator is not what is timed). Reports x real time per
checkout and the ratio.

Usage: python bench/replay_speed.py --roots OLD NEW [--labels before after] [--out FILE]
(``git worktree add /tmp/old <commit>`` gives an old checkout).
"""
import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from sins_align_ros.eval.markdown import machine_summary  # noqa: E402
from sins_align_ros.eval.scenarios import FILTER_SCENARIOS  # noqa: E402

SECONDS = 600.0
#: filter -> the scenario it is timed on
CASES = FILTER_SCENARIOS

CHILD = """
import sys, json
sys.path.insert(0, {root!r})
from sins_align_ros.eval.scenarios import named, simulate
from sins_align_ros.eval.run import run_pipeline
from sins_align_ros.sim.presets import alignment_params
sc = named({scenario!r}, {seconds!r})
data = simulate(sc, 1)
p = alignment_params(sc, {filt!r})
run_pipeline(p, data, block=1000)                       # compile / load caches, warm up
walls = [run_pipeline(p, data, block=1000).wall for _ in range({repeats})]
print(json.dumps(min(walls)))
"""


def rate(root, filt, repeats):
    """Return the x real time of ``filt`` on its scenario in the checkout at ``root``."""
    code = CHILD.format(root=str(root), scenario=CASES[filt], seconds=SECONDS, filt=filt,
                        repeats=repeats)
    out = subprocess.run([sys.executable, '-c', code], check=True, capture_output=True,
                         text=True, env=dict(os.environ, OPENBLAS_NUM_THREADS='1'))
    return SECONDS / json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    """Time every filter in both checkouts and write the table; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--roots', nargs=2, required=True)
    ap.add_argument('--labels', nargs=2, default=('before', 'after'))
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--filters', default=','.join(CASES))
    ap.add_argument('--out', default=str(Path(__file__).parent / 'results' / 'replay_speed.md'))
    args = ap.parse_args(argv)
    rows = []
    for f in args.filters.split(','):
        r = [rate(root, f, args.repeats) for root in args.roots]
        rows.append((f, CASES[f], *r))
        print(f'{f:13s} {CASES[f]:18s} {r[0]:8.0f} {r[1]:8.0f} x real time', flush=True)
    a, b = args.labels
    lines = ['# Replay speed of every fine filter (issue 22, must-show 3)', '',
             f'Command: `python bench/replay_speed.py --roots {" ".join(args.roots)} '
             f'--labels {a} {b} --repeats {args.repeats}` on {machine_summary()}.', '',
             f'{SECONDS:.0f} s of simulated 100 Hz IMU and 1 Hz GNSS (seed 1) per filter through '
             'the pipeline (coarse and fine, blocks of 1000 samples; no file reading or '
             'writing), each checkout in its own process, alternating, best of '
             f'{args.repeats} after a warm-up run.', '',
             f'| filter | scenario | {a} (x real time) | {b} (x real time) | {b} / {a} |',
             '|---|---|---|---|---|']
    lines += [f'| {f} | {sc} | {r0:,.0f} | {r1:,.0f} | {r1 / r0:.2f} |'
              for f, sc, r0, r1 in rows]
    lines.append('')
    Path(args.out).write_text('\n'.join(lines))
    print('\n'.join(lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())

#!/usr/bin/env python3
"""A base that starts moving without GNSS, and still bases that must not look moving (issue 43).

1. Three bases still at first, then moving, no GNSS, node defaults (``fine_filter`` auto, the
   initial latitude told): the ship underway (marine grade, still 300 s, then 0.05 m/s^2 to
   5 kn, cruise, turns), seed 003's MEMS car (still 300 s, then drives) and the small MEMS
   robot ``robot_lot`` (still 90 s, then about 1 m/s with frequent turns). Per run, over the
   1-s samples after coarse alignment (the ``eval/integrity`` rule): the share outside
   3 sigma and the worst error/sigma on a published axis, silent wrong or not; the seconds
   from the motion's start to the reason ``moving without GNSS`` (``not_aligned_reason`` on
   /diagnostics and ``~/reason``); whether any row is ``aligned`` from 3 s after the motion
   began; the final published 1-sigma.
2. Still and moored bases (the same defaults): ship_sway and static IMUs without GNSS, the
   PSINS laser-gyro recording, seed 004's USV moored in its severe sea: zero-velocity epochs
   refused, coasting, and the output against that of the commit given with ``--before``
   (a checkout of the code before the watch): identical rows or not.

Usage: python bench/moving_without_gnss.py [--runs 10] [--before DIR]
"""
import argparse
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))      # this checkout's package, not an installed copy

from sins_align_ros.align.engines.still_watch import MOVING_WITHOUT_GNSS  # noqa: E402
from sins_align_ros.eval.integrity import (published_sigma, run_integrity,  # noqa: E402
                                           sample_rows)
from sins_align_ros.eval.markdown import page_head, write_markdown  # noqa: E402
from sins_align_ros.eval.run import run_pipeline, without_gnss  # noqa: E402
from sins_align_ros.eval.scenarios import simulate  # noqa: E402
from sins_align_ros.sim.presets import scenario, starting_still  # noqa: E402

CASES = {
    'ship underway (marine)': lambda: starting_still(scenario('ship_underway'), 300.0),
    'seed 003 car (MEMS)': lambda: starting_still(scenario('seed003_car'), 270.0),
    'robot_lot (MEMS)': lambda: scenario('robot_lot'),
}


def moving_run(make, seed):
    """Integrity figures of one no-GNSS run of the scenario ``make()`` builds."""
    sc = make()
    data = without_gnss(simulate(sc, seed))
    said = []

    def watch(p):
        if not said and p.fine is not None and p.fine.moving.startswith(MOVING_WITHOUT_GNSS):
            said.append(p.t_last)
    run = run_pipeline({'initial_latitude_deg': sc.trajectory.lat_deg}, data, callback=watch)
    out = run.out
    r = run_integrity(run, sc.imu_rate_hz)
    rows = sample_rows(out, sc.imu_rate_hz)
    with np.errstate(invalid='ignore', divide='ignore'):
        z = np.abs(run.phi(rows)) / published_sigma(out.P_phi[rows])
    k = sc.trajectory.kinematics(out.t - out.t[0])
    t_move = out.t[np.argmax(np.hypot(k.v_n[:, 0], k.v_n[:, 1]) > 0.01)]
    return {'silent': r['silent'], 'outside': np.nanmax(r['outside']),
            'worst': float(np.nanmax(z)), 'delay': (said[0] - t_move) if said else np.nan,
            'aligned_late': bool(np.any(out.phase[out.t > t_move + 3.0] == 'aligned')),
            'aligned_before': bool(np.any(out.phase[out.t < t_move] == 'aligned')),
            'end_sigma': np.degrees(published_sigma(out.P_phi[-1])), 'phase': r['phase']}


STILL_SCRIPT = r'''
import hashlib, sys
from dataclasses import replace
import numpy as np
from sins_align_ros.sim.presets import scenario
from sins_align_ros.eval.scenarios import simulate
from sins_align_ros.eval.run import run_pipeline, without_gnss
from sins_align_ros.eval.recordings import read_psins_log, run_psins

def digest(run):
    out, m = run.out, hashlib.sha1()
    for a in (out.t, out.q, out.sigma, out.P_phi):
        m.update(np.ascontiguousarray(a).tobytes())
    m.update('|'.join(map(str, out.phase)).encode())
    eng = run.pipeline.engine
    return (m.hexdigest()[:12], getattr(eng, 'n_gated', '-'),
            getattr(eng, 'coast', None) is not None, str(out.phase[-1]))

cases = {'PSINS laser-gyro recording': lambda: run_psins(read_psins_log(), 'auto')}
for name in ('ship_sway', 'static_navigation', 'static_tactical', 'static_mems'):
    def go(name=name):
        sc = scenario(name)
        return run_pipeline({'initial_latitude_deg': sc.trajectory.lat_deg},
                            without_gnss(simulate(sc, 1)))
    cases[name + ', no GNSS'] = go
def usv():
    sc = scenario('seed004_medium')
    sc.trajectory = replace(sc.trajectory, speed=0.0)
    return run_pipeline({'initial_latitude_deg': 22.0}, without_gnss(simulate(sc, 1)))
cases['seed 004 USV moored (medium), no GNSS'] = usv
for name, go in cases.items():
    print(name, *digest(go()), sep='\t')
'''


def still_cases(root):
    """Run :data:`STILL_SCRIPT` on the package at ``root``.

    Returns {case: (digest, refused epochs, coasting, phase)}.
    """
    env = dict(os.environ, PYTHONPATH=str(root))
    text = subprocess.run([sys.executable, '-c', STILL_SCRIPT], cwd=root, env=env, check=True,
                          capture_output=True, text=True).stdout
    return {line.split('\t')[0]: line.split('\t')[1:] for line in text.splitlines() if line}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--runs', type=int, default=10)
    ap.add_argument('--before', help='a checkout of the code before the watch (for part 2)')
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'moving_without_gnss.md'))
    args = ap.parse_args(argv)
    cmd = f'python bench/moving_without_gnss.py --runs {args.runs}' + (
        f' --before {args.before}' if args.before else '')
    lines = page_head(
        'A base that starts moving without GNSS (issue 43)', cmd,
        'Node defaults (fine_filter auto, which runs the 7-state zero-velocity filter '
        'without GNSS), the initial latitude told. The 1-s samples after coarse alignment '
        'are judged by the rule of `eval/integrity`: silent wrong = more than 5 % outside '
        '3 sigma on a published axis, or any beyond 5 sigma.',
        '## 1. Still, then moving', '')
    lines += ['| case | runs | silent wrong | worst share outside 3 sigma | worst error/sigma '
              '| reason after motion start, s (max) | aligned from 3 s after the start | '
              'aligned at rest before | final 1-sigma roll/pitch/yaw, deg (median) |',
              '|---|---|---|---|---|---|---|---|---|']
    for name, make in CASES.items():
        rs = [moving_run(make, seed) for seed in range(args.runs)]
        sig = np.nanmedian([r['end_sigma'] for r in rs], axis=0)
        sig_txt = '/'.join('unknown' if not np.isfinite(s) else f'{s:.3g}' for s in sig)
        lines.append(
            f"| {name} | {len(rs)} | {sum(r['silent'] for r in rs)} | "
            f"{max(r['outside'] for r in rs):.1%} | {max(r['worst'] for r in rs):.2f} | "
            f"{np.nanmax([r['delay'] for r in rs]):.1f} | "
            f"{sum(r['aligned_late'] for r in rs)} runs | "
            f"{sum(r['aligned_before'] for r in rs)} runs | {sig_txt} |")
        print(lines[-1], flush=True)
    lines += ['', '## 2. Still and moored bases: the watch must not trip', '',
              'Zero-velocity epochs refused, coasting at the end, final phase, and the output '
              'rows (t, quaternion, sigma, covariance, phase) against the code before the '
              'watch.', '',
              '| case | refused epochs | coasting | phase | rows as before |',
              '|---|---|---|---|---|']
    now = still_cases(ROOT)
    before = still_cases(Path(args.before)) if args.before else {}
    for name, (digest, refused, coast, phase) in now.items():
        same = '-' if name not in before else (
            'identical' if before[name][0] == digest else 'DIFFERENT')
        lines.append(f'| {name} | {refused} | {coast} | {phase} | {same} |')
    print(write_markdown(args.out, lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())

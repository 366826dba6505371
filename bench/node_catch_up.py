#!/usr/bin/env python3
"""The live node's catch-up at a 1 kHz IMU after a 60-s still window (issue 46, must-show 7).

A still navigation-grade IMU (``static_navigation``) is played in real time at ``--rate`` Hz
into the alignment node in its own process, with the simulated sensors' parameters and a
coarse window forced to ``--window`` seconds (``coarse_min_duration`` = ``coarse_duration``),
so the still-base filter reprocesses that many seconds of stored samples in the callback
that ends the window (:mod:`sins_align_ros.align.stages.reprocess`). The publisher and the
listener are those of ``bench/node_load.py`` (three processes, local discovery, their own
``ROS_DOMAIN_ID``). Measured: the IMU messages published and the ``imu/data`` messages the
listener got (the node publishes one per input sample, so equal counts mean no input was
dropped; a gap in the received stamps says where one was); the longest gap between two
outputs and when it fell; the catch-up time, from the window's last sample's due time to
the first output after it whose latency is back under 20 ms; the worst latency.

With ``--scenario ship_underway --filter asckf`` (a navigation-grade ship under way, GNSS
position and velocity): the GNSS-aided stage runs over the window's samples and its fixes
(``coarse_reprocess_aided``, the default since session 47); ``--window-end`` starts it at
the window's end instead (the default before).

Usage: python bench/node_catch_up.py [--rate 1000] [--window 60] [--seconds 80]
[--scenario NAME --filter NAME [--window-end]] [--out FILE]
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'bench'))
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', '88')

import node_load  # noqa: E402  (bench/, after the path)

SCENARIO = 'static_navigation'
#: an output whose latency is under this is caught up, ms
CAUGHT_UP_MS = 20.0


def params_yaml(folder, window, scenario=SCENARIO, fine_filter='auto', window_end=False):
    """Write the node's parameter file (ROS layout, the window forced); return its path.

    ``window_end``: ``coarse_reprocess_aided`` off (a GNSS-aided stage starts at the
    window's end).
    """
    from sins_align_ros.eval.scenarios import named
    from sins_align_ros.sim.presets import alignment_params
    p = alignment_params(named(scenario), fine_filter)
    p.update(coarse_min_duration=float(window), coarse_duration=float(window))
    if window_end:
        p['coarse_reprocess_aided'] = False
    lines = ['alignment_node:', '  ros__parameters:']
    lines += [f'    {k}: {v!r}' if isinstance(v, str) else f'    {k}: {v}' for k, v in p.items()]
    path = Path(folder) / 'catch_up.yaml'
    path.write_text('\n'.join(lines) + '\n')
    return path


def run(args, folder):
    """Play the scenario into the node; return the measurements (dict)."""
    from sins_align_ros.ros.runner import stop_processes
    env = dict(os.environ, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS='1')
    pub = subprocess.Popen([sys.executable, '-c', node_load.PUBLISHER.format(
        root=str(ROOT), scenario=args.scenario, seconds=args.seconds, rate=float(args.rate))],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
    assert pub.stdout.readline().strip() == 'ready'
    listener = node_load.Listener()
    log = open(Path(folder) / 'node.log', 'w')
    yaml = params_yaml(folder, args.window, args.scenario, args.filter, args.window_end)
    node = subprocess.Popen([sys.executable, '-m', 'sins_align_ros.ros.alignment_node',
                             '--ros-args', '--params-file', str(yaml)],
                            env=env, stdout=subprocess.DEVNULL, stderr=log)
    time.sleep(5.0)                                   # the node is up and discovered
    pub.stdin.write('go\n')
    pub.stdin.flush()
    pub.stdout.readline()                             # 'done'
    time.sleep(3.0)
    stop_processes([node, pub])
    listener.close()
    rows = np.array(listener.rows)
    if not len(rows):
        raise RuntimeError('no imu/data arrived; node log:\n'
                           + (Path(folder) / 'node.log').read_text()[-2000:])
    rows = rows[np.argsort(rows[:, 1])]
    t_first = rows[0, 1]
    lat = (rows[:, 0] - rows[:, 1]) * 1e3
    gaps = np.diff(rows[:, 0])
    k = int(np.argmax(gaps))
    t_end = t_first + args.window                     # the window's last sample is due
    after = np.flatnonzero((rows[:, 1] >= t_end) & (lat < CAUGHT_UP_MS))
    holes = np.flatnonzero(np.diff(rows[:, 1]) > 1.5 / args.rate)
    missing = ', '.join(f'{rows[h, 1] - t_first:.3f}' for h in holes[:5]) or '-'
    caught = rows[after[0], 0] - t_end if len(after) else float('nan')
    return {'published': int(args.seconds * args.rate), 'received': len(rows),
            'gap_s': float(gaps[k]), 'gap_at_s': float(rows[k, 1] - t_first),
            'catch_up_s': float(caught), 'max_latency_ms': float(lat.max()),
            'p50_ms': float(np.percentile(lat, 50)), 'missing_after': missing}


def main(argv=None):
    """Measure and write the page; returns the exit code."""
    from sins_align_ros.eval.markdown import machine_summary, write_markdown
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--rate', type=float, default=1000.0)
    ap.add_argument('--window', type=float, default=60.0)
    ap.add_argument('--seconds', type=float, default=80.0)
    ap.add_argument('--scenario', default=SCENARIO,
                    help='a named scenario (eval.scenarios), e.g. ship_underway: a GNSS-aided '
                         'stage reprocesses the window and its fixes')
    ap.add_argument('--filter', default='auto', help='fine_filter')
    ap.add_argument('--window-end', action='store_true',
                    help='coarse_reprocess_aided false: a GNSS-aided stage starts at the '
                         'window\'s end')
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'node_catch_up.md'))
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        r = run(args, folder)
    lines = [
        '# The live node catching up at a 1 kHz IMU (issue 46)', '',
        f'Command: `python bench/node_catch_up.py --rate {args.rate:g} --window '
        f'{args.window:g} --seconds {args.seconds:g}'
        + ('' if args.scenario == SCENARIO and args.filter == 'auto' else
           f' --scenario {args.scenario} --filter {args.filter}'
           + (' --window-end' if args.window_end else ''))
        + f'` on {machine_summary()}.', '',
        __doc__.split('\n\n', 1)[1].split('\n\nUsage')[0].replace('\n', ' '), '',
        '| IMU published | imu/data received | missing after (s of data) | longest output gap '
        '(s) | at (s of data) | catch-up (s) | worst latency (ms) | median latency (ms) |',
        '|---|---|---|---|---|---|---|---|',
        f"| {r['published']} | {r['received']} | {r['missing_after']} | {r['gap_s']:.3f} | "
        f"{r['gap_at_s']:.1f} | {r['catch_up_s']:.3f} | {r['max_latency_ms']:.0f} | "
        f"{r['p50_ms']:.1f} |", '']
    write_markdown(args.out, lines)
    print('\n'.join(lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())

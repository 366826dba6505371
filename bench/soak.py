#!/usr/bin/env python3
"""Soak run (issue 7): an hour of simulated ship data at 200 Hz through the live node, with faults.

The seed 000 ship (``seed000_case1``, held at its final speed after the profile) is
simulated minute by minute, turned into messages (``sim/faults.py``), corrupted by
one fault every few minutes from a rotating list, and published by a real rclpy
publisher to a real ``AlignmentNode`` (``fine_filter: asckf``) on one executor,
as fast as the node takes them (each batch is waited for, so nothing is lost).
Measured: crashes (an exception escaping a callback ends the run), resident
memory (VmRSS) every simulated minute and its growth after a warm-up, the faults
counted by the node, and the final attitude against truth with the reported sigma.

Usage: python bench/soak.py [--minutes 60] [--rate 200] [--fault-every 5]
Writes bench/results/soak.md (``--out`` to change).
"""
import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # this checkout's package
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from sins_align_ros.eval.markdown import machine_summary, write_markdown  # noqa: E402
from sins_align_ros.nav.frames import attitude_error, euler_to_dcm  # noqa: E402
from sins_align_ros.ros.alignment_node import AlignmentNode  # noqa: E402
from sins_align_ros.ros.playback import Player  # noqa: E402
from sins_align_ros.sim.faults import MessageStream, inject  # noqa: E402
from sins_align_ros.sim.presets import scenario  # noqa: E402
from sins_align_ros.sim.scenario import ScenarioStream  # noqa: E402
from sins_align_ros.units import ARCMIN  # noqa: E402

#: the rotating faults: (name, window length s); clock jumps and gaps restart alignment
FAULT_CYCLE = [('imu_nan', 0.2), ('gnss_outliers', 5.0), ('imu_repeated', 1.0),
               ('gnss_outage', 30.0), ('imu_out_of_order', 1.0), ('imu_dropped', 0.2),
               ('gnss_no_fix', 10.0), ('imu_wrong_frame', 0.2), ('imu_saturated', 0.1),
               ('gnss_absurd_cov', 10.0), ('imu_missing_field', 0.2)]
#: faults that restart the alignment, injected once in the first half only
RESTARTING = [('imu_gap', 2.0), ('clock_back', 0.0)]


def rss_mib():
    """Resident set size of this process, MiB (Linux /proc)."""
    with open('/proc/self/status') as f:
        for line in f:
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024.0
    return float('nan')


def schedule(minutes, every_min):
    """Return ``{minute: (fault, start offset s, length s)}`` of the run."""
    plan, k = {}, 0
    for m in range(2, minutes, every_min):
        plan[m] = FAULT_CYCLE[k % len(FAULT_CYCLE)]
        k += 1
    if minutes >= 30:
        plan[13] = RESTARTING[0]
        plan[23] = RESTARTING[1]
    return plan


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--minutes', type=int, default=60)
    ap.add_argument('--rate', type=float, default=200.0)
    ap.add_argument('--fault-every', type=int, default=5, help='minutes between faults')
    ap.add_argument('--warmup', type=int, default=10, help='minutes before the RSS baseline')
    ap.add_argument('--out', default=str(Path(__file__).parent / 'results' / 'soak.md'))
    args = ap.parse_args()

    sc = scenario('seed000_case1', duration=args.minutes * 60.0)
    sim = ScenarioStream(sc, seed=7, imu_rate_hz=args.rate)
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=1 + os.getpid() % 200)
    node = AlignmentNode(context=ctx, parameter_overrides=[
        Parameter('fine_filter', value='asckf'), Parameter('gnss_pos_sigma_m', value=0.2),
        Parameter('gnss_vel_sigma_mps', value=0.02), Parameter('imu_frame_id', value='imu_link'),
        Parameter('diagnostic_period', value=1.0)])
    pub = rclpy.create_node('soak_player', context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    ex.add_node(pub)
    player = Player(pub, node)
    assert player.wait_for_subscribers(ex), 'discovery failed'
    plan = schedule(args.minutes, args.fault_every)
    n_per_min = int(round(60.0 * args.rate))
    rss, wall0, crash, shift = [], time.monotonic(), None, 0.0
    last = None
    try:
        for m in range(args.minutes):
            b = sim.next_block(n_per_min)
            s = MessageStream(b)
            t_min = b.imu.t[0]
            if m in plan:
                name, length = plan[m]
                t0 = t_min + 30.0
                inject(s, name, t0, t0 + length, size=30.0 if name == 'clock_back' else None)
            if shift:                     # an earlier clock jump shifts every later stamp
                s.imu['t'] += shift
                s.gnss['t'] += shift
            if m in plan and plan[m][0] == 'clock_back':
                shift -= 30.0
            player.play(ex, s)
            rss.append((m + 1, rss_mib(), time.monotonic() - wall0))
            last = s
            print(f'minute {m + 1:3d}: phase {node.pipeline.phase:8s} RSS {rss[-1][1]:7.1f} MiB '
                  f'wall {rss[-1][2]:7.1f} s' + (f'  fault {plan[m][0]}' if m in plan else ''),
                  flush=True)
    except Exception as exc:                              # a crash is a result here
        crash = f'{type(exc).__name__}: {exc}'
    wall = time.monotonic() - wall0
    if last is None or not rss:
        print(f'soak: no minute completed: {crash}', file=sys.stderr)
        return 1
    p = node.pipeline
    t_orig = float(last.imu['t_pub'][-1])
    err = attitude_error(p.mech.C_b_n, euler_to_dcm(last.truth_euler(t_orig)))
    sig = np.sqrt(np.diag(p.attitude_cov()))
    base = [r for m, r, _ in rss if m == args.warmup]
    base = base[0] if base else rss[0][1]
    after = [r for m, r, _ in rss if m >= args.warmup]
    growth = (max(after) - base) / base * 100.0
    imu_counts, gnss_counts = node.session.input_counts()
    counts = {f'imu {k}': v for k, v in imu_counts.items() if k != 'accepted'}
    counts.update({f'gnss {k}': v for k, v in gnss_counts.items()})
    st = p.status()
    ok_att = bool(np.all(np.abs(err) <= 3.0 * sig + np.array([0.2, 0.2, 3.0]) * ARCMIN))
    lines = [
        '# Soak run (issue 7)', '',
        f'Command: `python bench/soak.py --minutes {args.minutes} --rate {args.rate:g} '
        f'--fault-every {args.fault_every}`  ',
        f'Machine: {machine_summary()}, {platform.platform()}  ',
        f'Node: alignment_node, fine_filter asckf, {node.received["imu/data_raw"]} IMU and '
        f'{node.received["gnss/fix"]} + {node.received["gnss/vel"]} GNSS messages through a '
        f'real publisher/subscription in {wall:.0f} s wall ({args.minutes * 60 / wall:.1f}x '
        'real time, player included)', '',
        f'- crashes: {"none" if crash is None else crash}',
        f'- resident memory: {rss[0][1]:.1f} MiB after minute 1, {base:.1f} MiB after the '
        f'{args.warmup}-minute warm-up, at most {max(after):.1f} MiB afterwards, final '
        f'{rss[-1][1]:.1f} MiB: growth after warm-up **{growth:+.1f}%** (limit 10%)',
        f'- final phase {p.phase}; attitude error against truth (roll, pitch, yaw): '
        f"{err[0] / ARCMIN:+.3f}', {err[1] / ARCMIN:+.3f}', {err[2] / ARCMIN:+.2f}'; reported "
        f"1-sigma {sig[0] / ARCMIN:.3f}', {sig[1] / ARCMIN:.3f}', {sig[2] / ARCMIN:.2f}': "
        f'**{"within" if ok_att else "OUTSIDE"} 3 sigma** (+0.2\' tilt, +3\' heading margin)',
        f"- GNSS gate: {st.get('gnss_rejected', 0)} epochs rejected, "
        f"{st.get('gnss_forced', 0)} forced acceptances since the last restart (the gap and "
        'clock-jump faults restart the alignment)', '',
        '| minute | fault | window (s) |', '|---|---|---|']
    lines += [f'| {m} | {n} | {w:g} |' for m, (n, w) in sorted(plan.items())]
    lines += ['', 'Input faults counted by the node: ' + ', '.join(
        f'{k} {v}' for k, v in sorted(counts.items())), '',
        '| minute | RSS MiB | wall s |', '|---|---|---|']
    lines += [f'| {m} | {r:.1f} | {w:.0f} |' for m, r, w in rss if m % 5 == 0 or m == 1]
    write_markdown(args.out, lines)
    print('\n'.join(lines[:12]))
    ex.shutdown()
    ctx.try_shutdown()
    return 0 if crash is None and growth < 10.0 and ok_att else 1


if __name__ == '__main__':
    sys.exit(main())

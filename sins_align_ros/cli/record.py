"""sins_align_record: record a simulator scenario into a rosbag2, without a ROS graph.

    sins_align_record --scenario NAME [--grade GRADE] [--seed N] [--duration S]
                      [--imu-rate HZ] [--gnss-rate HZ] [--truth-rate HZ]
                      [--start-time S] --out DIR

Writes the topics ``imu/data_raw``, ``gnss/fix``, ``gnss/vel`` (not for a position-only
receiver) and ``sim/truth`` with the contents and stamps simulator_node publishes for the
same parameters (one code path: :mod:`sins_align_ros.io.sim_messages`), as an sqlite3
rosbag2 folder that ``sins_align_replay`` and ``ros2 bag play`` read. Each message's
receive time is its stamp. Errors end with one line on stderr and exit code 2 (usage) or 1
(cannot write).
"""
import argparse
import sys
import time
from pathlib import Path

from ..io.sim_messages import simulated_scenario, write_simulated_bag
from ..sim.presets import SCENARIOS, SENSOR_GRADES


def _parser():
    ap = argparse.ArgumentParser(
        prog='sins_align_record',
        description='Record a simulator scenario into a rosbag2 (the topics and messages '
                    'of simulator_node), without a ROS graph.')
    ap.add_argument('--scenario', required=True, choices=SCENARIOS, metavar='NAME',
                    help='scenario preset: ' + ', '.join(SCENARIOS))
    ap.add_argument('--grade', default='', metavar='GRADE',
                    help="sensor grade replacing the scenario's IMU error model: "
                         f"{', '.join(SENSOR_GRADES)} (default: the scenario's own)")
    ap.add_argument('--seed', type=int, default=0, help='random seed (default 0)')
    ap.add_argument('--duration', type=float, default=0.0, metavar='SECONDS',
                    help="simulated duration (default: the scenario's)")
    ap.add_argument('--imu-rate', type=float, default=0.0, metavar='HZ',
                    help="IMU rate (default: the scenario's, 100 Hz for most)")
    ap.add_argument('--gnss-rate', type=float, default=0.0, metavar='HZ',
                    help="GNSS rate (default: the scenario's)")
    ap.add_argument('--truth-rate', type=float, default=10.0, metavar='HZ',
                    help='rate of sim/truth (default 10 Hz, capped at the IMU rate)')
    ap.add_argument('--start-time', type=float, default=0.0, metavar='SECONDS',
                    help='stamp of t = 0, s since the epoch (default: now)')
    ap.add_argument('--out', required=True, metavar='DIR',
                    help='rosbag2 folder to create (must not exist)')
    return ap


def _check(args):
    """One line saying what is wrong with the numeric options, or None."""
    limits = (('--seed', args.seed, 0, 2 ** 31 - 1), ('--duration', args.duration, 0.0, 1e6),
              ('--imu-rate', args.imu_rate, 0.0, 4000.0),
              ('--gnss-rate', args.gnss_rate, 0.0, 50.0),
              ('--truth-rate', args.truth_rate, 0.1, 4000.0),
              ('--start-time', args.start_time, 0.0, 4e9))
    for name, value, lo, hi in limits:
        if not lo <= value <= hi:       # also false for NaN
            return f'{name} {value} is outside [{lo}, {hi}]'
    if Path(args.out).exists():
        return f'{args.out} exists already'
    return None


def main(argv=None):
    """Entry point; returns the exit code (0 ok, 1 cannot write, 2 usage error)."""
    args = _parser().parse_args(argv)
    err = _check(args)
    try:
        if err:
            raise ValueError(err)
        sc = simulated_scenario(args.scenario, args.grade, args.duration)
    except ValueError as exc:
        print(f'sins_align_record: error: {exc}', file=sys.stderr)
        return 2
    start = args.start_time or time.time()
    try:
        counts = write_simulated_bag(
            args.out, sc, seed=args.seed, imu_rate_hz=args.imu_rate or None,
            gnss_rate_hz=args.gnss_rate or None, truth_rate_hz=args.truth_rate,
            start_ns=int(round(start * 1e9)))
    except ImportError:
        print('sins_align_record: error: the rosbags library is not installed '
              '(pip install rosbags)', file=sys.stderr)
        return 1
    except OSError as exc:
        print(f'sins_align_record: error: cannot write {args.out}: {exc}', file=sys.stderr)
        return 1
    print(f"sins_align_record: {args.out}: scenario '{sc.name}' ({sc.description}), "
          f'{sc.duration:g} s, seed {args.seed}: '
          + ', '.join(f'{n} {k}' for k, n in counts.items()), file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())

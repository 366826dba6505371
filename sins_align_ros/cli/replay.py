"""sins_align_replay: the alignment pipeline on recorded data, without a ROS graph.

    sins_align_replay INPUT [--params FILE.yaml] [--set name=value ...] --out OUT.csv
                      [--out OUT.mcap [--copy-input]] [--report OUT.png]
    sins_align_replay INPUT INPUT ... | FOLDER --out DIR [--jobs N | --scheduler ADDRESS]

INPUT is a rosbag2 (folder, .mcap or .db3) with ``imu/data_raw`` (and optionally
``gnss/fix``, ``gnss/vel``, ``sim/truth``), or a PSINS ``.imu`` log. Parameters are the
alignment node's (YAML in the ROS parameter-file layout or flat; ``--set``
overrides; an unknown name is an error naming the closest parameter). A topic
option given explicitly must name a topic of the bag (an error lists its topics);
the defaults ``gnss/fix`` and ``gnss/vel`` may be absent (no GNSS). Errors end with
one line on stderr and a non-zero exit code; what was computed before a fault in
the input is still written. ``--out`` names a CSV, or with ``.mcap`` a result bag: the
node's topics as a rosbag2 for Foxglove, PlotJuggler and ``ros2 bag``
(:mod:`~sins_align_ros.io.result_bag`); give it twice for both.

Several inputs, or a folder of recordings, are a fleet (:mod:`.replay_many`): ``--out``
names a folder that gets one result per input, named after it, and ``summary.csv``; the
recordings run on ``--jobs`` processes or a Dask cluster (``--scheduler``).
"""
import argparse
import os
import sys
from pathlib import Path

import numpy as np

from ..align import param_text, params as prm
from ..io import imu_noise_file
from ..io.bag import read_bag  # noqa: F401  (bench/whole_replay.py times it from here)
from ..io.results import write_csv  # noqa: F401  (and this)
from ..nav.frames import yaw_to_heading
from . import replay_many
from .replay_one import is_rosbag2_folder, replay_bag, replay_one, replay_psins, warnings

__all__ = ['load_parameters', 'main', 'replay_bag', 'replay_psins', 'run']


def _parser():
    ap = argparse.ArgumentParser(prog='sins_align_replay',
                                 description='Run the SINS alignment pipeline on a recording.')
    ap.add_argument('input', nargs='+',
                    help='rosbag2 folder / .mcap / .db3, or a PSINS .imu log; several, or a '
                    'folder of them: a fleet (--out names a folder, docs/replay.md#fleets)')
    ap.add_argument('--params', help='YAML parameter file (alignment_node layout or flat)')
    ap.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                    help='override one parameter (repeatable)')
    ap.add_argument('--out', required=True, action='append',
                    help='result CSV; RESULT.mcap: a result bag, the folder RESULT/ '
                    '(docs/replay.md#result-bag); may be given twice')
    ap.add_argument('--copy-input', action='store_true',
                    help='copy the input bag\'s messages into the result bag')
    ap.add_argument('--report', help='PNG figure: estimate (or error vs sim/truth) +/-3 sigma')
    ap.add_argument('--every', type=int, default=1, help='write one CSV row in N (default 1)')
    ap.add_argument('--duration', type=float, default=None, metavar='SECONDS',
                    help='use only the first SECONDS of IMU data')
    ap.add_argument('--imu-topic', default='imu/data_raw')
    ap.add_argument('--fix-topic', default=None,
                    help='sensor_msgs/NavSatFix (default gnss/fix, which may be absent; a '
                         'topic given here must be in the bag)')
    ap.add_argument('--vel-topic', default=None,
                    help='geometry_msgs/TwistWithCovarianceStamped ENU velocity (default '
                         'gnss/vel, which may be absent; a topic given here must be in the '
                         'bag; empty string to ignore it)')
    ap.add_argument('--quiet', action='store_true')
    fleet = ap.add_argument_group('several inputs (a fleet)')
    fleet.add_argument('--jobs', type=int, default=1, metavar='N',
                       help='recordings at once, on a local Dask cluster of N processes '
                       '(default 1: one after the other, in this process)')
    fleet.add_argument('--scheduler', metavar='ADDRESS',
                       help='run the recordings on the Dask cluster of this scheduler '
                       '(tcp://host:8786; default $DASK_SCHEDULER_ADDRESS)')
    fleet.add_argument('--formats', default='csv', metavar='LIST',
                       help='results per input: csv, mcap (a result bag), png (the report), '
                       'comma-separated (default csv)')
    return ap


def load_parameters(params_file, sets, log=lambda m: None, node_values=None):
    """Alignment parameter dict from a YAML file and ``name=value`` overrides, validated.

    An ``imu_noise_file`` among them sets the noise parameters it gives where neither the
    file nor ``--set`` names them (:mod:`~sins_align_ros.io.imu_noise_file`; said through
    ``log``).

    Parameters of the node's ROS interface (``odom_frame_id``, ...) that a shared
    preset may hold are checked and left out (said through ``log``), or, given a dict
    ``node_values``, put there (the result bag uses them).
    """
    values = {}
    if params_file:
        values.update(param_text.load_yaml(params_file))
    for item in sets:
        if '=' not in item:
            raise ValueError(f'--set expects name=value, got {item!r}')
        k, v = item.split('=', 1)
        values[k.strip()] = param_text.parse_value(k.strip(), v.strip())
    values, node_only = prm.split_node_params(values)
    if node_values is not None:
        node_values.update(node_only)
    elif node_only:
        log(f'node-only parameters not used by the replay: {", ".join(sorted(node_only))}')
    values = prm.validate(values)
    filled, said = imu_noise_file.apply(values, set(values), prm.defaults())
    if not said:
        return values
    log(said)
    try:
        return prm.validate(filled)
    except ValueError as exc:
        raise ValueError(f'{values["imu_noise_file"]} gives a value refused: {exc}') from None


def _outputs(args, psins):
    """Return ``(CSV paths, result bag paths)`` of ``--out``; ``ValueError`` if misused.

    ``psins``: the input is a PSINS log (nothing to copy).
    """
    bags = [p for p in args.out if Path(p).suffix.lower() == '.mcap']
    csvs = [p for p in args.out if p not in bags]
    if len(bags) > 1 or len(csvs) > 1:
        raise ValueError('--out takes at most one CSV and one .mcap result bag')
    if args.copy_input and not bags:
        raise ValueError('--copy-input needs a result bag: --out RESULT.mcap')
    if args.copy_input and psins:
        raise ValueError('--copy-input needs a rosbag2 input, not a PSINS log')
    return csvs, bags


def _summary(out, pipe):
    k = len(out.t) - 1
    if k < 0:
        return 'no IMU sample was processed'
    if not np.isfinite(out.q[k, 0]):
        return (f'no attitude yet: the recording ended in phase {out.phase[k]} '
                f'({pipe.elapsed:.1f} s)')
    e = np.degrees(out.euler[k])
    s = np.degrees(out.sigma[k])
    head = np.degrees(yaw_to_heading(out.euler[k, 2]))
    return (f'final at t={out.t[k]:.3f}: roll {e[0]:.4f} pitch {e[1]:.4f} yaw {e[2]:.4f} deg '
            f'(heading {head:.3f} deg from north); 1-sigma {s[0] * 60:.2f}\' '
            f'{s[1] * 60:.2f}\' {s[2] * 60:.2f}\'; phase {out.phase[k]}')


def main(argv=None):
    """Entry point; returns the exit code (0 ok, 1 input fault, 2 usage/parameter error)."""
    args = _parser().parse_intermixed_args(argv)
    log = (lambda m: None) if args.quiet else (lambda m: print(f'sins_align_replay: {m}',
                                                               file=sys.stderr))
    node_values = {}
    fleet = len(args.input) > 1 or (Path(args.input[0]).is_dir()
                                    and not is_rosbag2_folder(args.input[0]))
    try:
        values = load_parameters(args.params, args.set, log, node_values)
        if not fleet:
            args.input = args.input[0]
            psins = Path(args.input).suffix.lower() == '.imu'
            csvs, bags = _outputs(args, psins)
    except (ValueError, OSError) as exc:
        print(f'sins_align_replay: error: {exc}', file=sys.stderr)
        return 2
    if fleet:
        return replay_many.main(args, values, node_values, log)
    unused = [o for o, given in (('--jobs', args.jobs != 1), ('--scheduler', args.scheduler),
                                 ('--formats', args.formats != 'csv')) if given]
    if unused:
        log(f'one recording: {", ".join(unused)} not used (they are for several inputs)')
    status, out, pipe, written = replay_one(
        args, values, node_values, csvs, bags, log,
        lambda text: print(f'sins_align_replay: error: {text}', file=sys.stderr))
    if pipe is None or not written:
        return status
    for w in warnings(pipe):
        log(f'warning: {w}')
    log(_summary(out, pipe))
    return status


def run():
    """Console entry point: :func:`main`, then the process ends without interpreter teardown.

    Tearing down an interpreter that has loaded numba's compiled kernels takes about
    0.3 s (LLVM and the loaded modules), a quarter of a whole 1200-s replay; the
    results are written and closed by then, so the standard streams are flushed and
    the process exits at once (``os._exit``). Under coverage measurement
    (``COVERAGE_PROCESS_START``) the normal exit is kept so that its data are saved.
    """
    status = main()
    if os.environ.get('COVERAGE_PROCESS_START'):
        sys.exit(status)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


if __name__ == '__main__':
    run()

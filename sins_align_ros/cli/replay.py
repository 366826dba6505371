"""sins_align_replay: the alignment pipeline on recorded data, without a ROS graph.

    sins_align_replay INPUT [--params FILE.yaml] [--set name=value ...] --out OUT.csv
                      [--report OUT.png]

INPUT is a rosbag2 (folder, .mcap or .db3) with ``imu/data_raw`` (and optionally
``gnss/fix``, ``gnss/vel``, ``sim/truth``), or a PSINS ``.imu`` log. Parameters are the
alignment node's (YAML in the ROS parameter-file layout or flat; ``--set``
overrides; an unknown name is an error naming the closest parameter). A topic
option given explicitly must name a topic of the bag (an error lists its topics);
the defaults ``gnss/fix`` and ``gnss/vel`` may be absent (no GNSS). Errors end with
one line on stderr and a non-zero exit code; what was computed before a fault in
the input is still written.
"""
import argparse
import os
import sys
from pathlib import Path

import numpy as np

from ..align import AlignmentSession, Output
from ..align import params as prm
from ..io import imu_noise_file
from ..io.bag import BagError, read_bag
from ..io.psins import PsinsFormatError, read_psins
from ..io.report import plot_report, truth_euler_at
from ..io.results import write_csv
from ..nav.frames import yaw_to_heading
from ..units import DEG

_CHUNK = 2000


def _parser():
    ap = argparse.ArgumentParser(prog='sins_align_replay',
                                 description='Run the SINS alignment pipeline on a recording.')
    ap.add_argument('input', help='rosbag2 folder / .mcap / .db3, or a PSINS .imu log')
    ap.add_argument('--params', help='YAML parameter file (alignment_node layout or flat)')
    ap.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                    help='override one parameter (repeatable)')
    ap.add_argument('--out', required=True, help='result CSV')
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
    return ap


def load_parameters(params_file, sets, log=lambda m: None):
    """Alignment parameter dict from a YAML file and ``name=value`` overrides, validated.

    An ``imu_noise_file`` among them sets the noise parameters it gives where neither the
    file nor ``--set`` names them (:mod:`~sins_align_ros.io.imu_noise_file`; said through
    ``log``).

    Parameters of the node's ROS interface (``odom_frame_id``, ...) that a shared
    preset may hold are checked and left out (said through ``log``).
    """
    values = {}
    if params_file:
        values.update(prm.load_yaml(params_file))
    for item in sets:
        if '=' not in item:
            raise ValueError(f'--set expects name=value, got {item!r}')
        k, v = item.split('=', 1)
        values[k.strip()] = prm.parse_value(k.strip(), v.strip())
    values, node_only = prm.split_node_params(values)
    if node_only:
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


def replay_psins(path, values, log, duration=None):
    """Run a PSINS log through an :class:`AlignmentSession`; returns (Output, pipeline, None).

    The log holds increments: they go in as they are (``AlignmentSession.increments``),
    the clock starting at the header's stamp.
    """
    rec = read_psins(path)
    v = dict(values)
    if prm.is_unset(v.get('initial_latitude_deg', float('nan'))):
        v.update(initial_latitude_deg=float(rec.pos0[0] / DEG),
                 initial_longitude_deg=float(rec.pos0[1] / DEG),
                 initial_height_m=float(rec.pos0[2]))
        log(f'position from the PSINS header: {v["initial_latitude_deg"]:.6f} deg, '
            f'{v["initial_longitude_deg"]:.6f} deg, {v["initial_height_m"]:.1f} m')
    session = AlignmentSession(v)
    session.start_clock(rec.t0)
    n = len(rec.t) if duration is None else int(np.searchsorted(rec.t, rec.t0 + duration + 1e-9))
    out = session.increments(rec.t[:n], rec.dtheta[:n], rec.dv[:n])
    return Output.concat([out, session.finish()]), session.pipeline, None


def replay_bag(path, values, args, log, with_truth=True):
    """Run a rosbag2 through an :class:`AlignmentSession`; returns (Output, pipeline, truth).

    ``truth`` is a list of (t, q) or empty (``with_truth`` False: not read). IMU and GNSS
    messages pass the node's input checks (the first occurrence of each reason is
    logged, the counts at the end), in recording order; the IMU between two GNSS
    messages goes in as one block (``AlignmentSession.imu_block``). A fault part-way
    through raises :class:`BagError` with ``.partial`` set to the (Output, pipeline,
    truth) computed from what came before it.
    """
    required = [k for k, given in (('fix', args.fix_topic), ('vel', args.vel_topic)) if given]
    rec = read_bag(path, args.imu_topic, args.fix_topic or 'gnss/fix',
                   truth_topic='sim/truth' if with_truth else None,
                   vel_topic='gnss/vel' if args.vel_topic is None else args.vel_topic,
                   required=required)
    session = AlignmentSession(values, block=_CHUNK)
    outs, truth, seen = [], [], set()
    n, events = len(rec.t), rec.events
    if args.duration is not None:
        n, events = _first_seconds(rec, args.duration)

    def report():
        for source, key, text in session.notices():
            if (source, key) not in seen:
                seen.add((source, key))
                log(f'{source}: {text} (first occurrence; counted at the end)')

    def imu(k0, k1):
        if k1 > k0:
            outs.append(session.imu_block(rec.t[k0:k1], rec.w[k0:k1], rec.f[k0:k1],
                                          rec.missing[k0:k1]))
            report()

    try:
        k = 0
        for ev, before in zip(events, rec.imu_before):
            imu(k, min(before, n))
            k = max(k, min(before, n))
            if ev.kind == 'fix':
                outs.append(session.fix(ev.t, *ev.data))
            elif ev.kind == 'vel':
                outs.append(session.velocity(ev.t, *ev.data))
            else:
                truth.append((ev.t, ev.data[0]))
            report()
        imu(k, n)
        outs.append(session.finish())
    finally:
        imu_counts, gnss_counts = session.input_counts()
        counts = {f'imu {k}': v for k, v in imu_counts.items()
                  if k not in ('accepted', 'clock_start')}
        counts.update({f'gnss {k}': v for k, v in gnss_counts.items()
                       if not k.startswith('accepted')})
        if counts:
            log('input faults: ' + ', '.join(f'{k} {v}' for k, v in sorted(counts.items())))
    result = Output.concat(outs), session.pipeline, truth
    if rec.error is not None:
        exc = BagError(rec.error)
        exc.partial = result
        raise exc
    return result


def _first_seconds(rec, duration):
    """Return ``(n_imu, events)``: recording ``rec`` cut at ``duration`` s.

    Up to the first message (of any kind, in recording order) stamped more than
    ``duration`` after the first message, as the message loop's ``break`` did.
    """
    before = rec.imu_before
    first_is_event = bool(rec.events) and (len(rec.t) == 0 or before[0] == 0)
    if not first_is_event and len(rec.t) == 0:
        return 0, []
    t_end = (rec.events[0].t if first_is_event else rec.t[0]) + duration + 1e-9
    late = np.flatnonzero(rec.t > t_end)
    i_cut = int(late[0]) if len(late) else len(rec.t)
    e_cut = next((j for j, ev in enumerate(rec.events) if ev.t > t_end), None)
    if e_cut is not None and before[e_cut] <= i_cut:
        return int(before[e_cut]), rec.events[:e_cut]
    return i_cut, rec.events[:int(np.searchsorted(before, i_cut, side='right'))]


def _truth_euler(out, truth):
    """Truth Euler angles at the output stamps, interpolated (``io.report.truth_euler_at``)."""
    if not truth:
        return None
    truth = sorted(truth, key=lambda item: item[0])
    return truth_euler_at(out.t, [t for t, _ in truth], [q for _, q in truth])


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
    args = _parser().parse_args(argv)
    log = (lambda m: None) if args.quiet else (lambda m: print(f'sins_align_replay: {m}',
                                                               file=sys.stderr))
    try:
        values = load_parameters(args.params, args.set, log)
    except (ValueError, OSError) as exc:
        print(f'sins_align_replay: error: {exc}', file=sys.stderr)
        return 2
    status, truth = 0, None
    try:
        if Path(args.input).suffix.lower() == '.imu':
            out, pipe, truth = replay_psins(args.input, values, log, args.duration)
        else:
            out, pipe, truth = replay_bag(args.input, values, args, log,
                                          with_truth=bool(args.report))
    except PsinsFormatError as exc:
        print(f'sins_align_replay: error: {exc}', file=sys.stderr)
        return 1
    except BagError as exc:
        print(f'sins_align_replay: error: {exc}', file=sys.stderr)
        partial = getattr(exc, 'partial', None)
        if partial is None:
            return 1
        out, pipe, truth = partial
        status = 1
    try:
        write_csv(args.out, out, every=args.every)
        if args.report and len(out.t):
            plot_report(args.report, out, _truth_euler(out, truth),
                        title=f"{Path(args.input).name}: {pipe.cfg['fine_filter']}")
    except OSError as exc:
        print(f'sins_align_replay: error: cannot write output: {exc}', file=sys.stderr)
        return 1
    for w in pipe.warnings + [text for _, text in pipe.conditions()]:
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

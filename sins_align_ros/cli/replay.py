"""sins_align_replay: the alignment pipeline on recorded data, without a ROS graph.

    sins_align_replay INPUT [--params FILE.yaml] [--set name=value ...] --out OUT.csv
                      [--out OUT.mcap [--copy-input]] [--report OUT.png]

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
"""
import argparse
import os
import sys
from pathlib import Path

import numpy as np

from ..align import AlignmentSession, Output
from ..align import params as prm
from ..io import imu_noise_file
from ..io.bag import BagError, imu_frame_id, read_bag
from ..io.psins import PsinsFormatError, read_psins
from ..io.report import plot_report, truth_euler_at
from ..io.result_bag import ResultBag
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
        values.update(prm.load_yaml(params_file))
    for item in sets:
        if '=' not in item:
            raise ValueError(f'--set expects name=value, got {item!r}')
        k, v = item.split('=', 1)
        values[k.strip()] = prm.parse_value(k.strip(), v.strip())
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


def replay_psins(path, values, log, duration=None, bag=None):
    """Run a PSINS log through an :class:`AlignmentSession`; returns (Output, pipeline, None).

    The log holds increments: they go in as they are (``AlignmentSession.increments``),
    the clock starting at the header's stamp. ``bag``: a
    :class:`~sins_align_ros.io.result_bag.ResultBag` that takes the node's topics (the
    rates of ``imu/data`` are the increments over their intervals).
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
    if bag is None:
        out = session.increments(rec.t[:n], rec.dtheta[:n], rec.dv[:n])
        return Output.concat([out, session.finish()]), session.pipeline, None
    dt = np.diff(rec.t[:n], prepend=rec.t0)
    dt[dt <= 0] = np.nan
    w, f = rec.dtheta[:n] / dt[:, None], rec.dv[:n] / dt[:, None]
    outs = []
    for a, b in bag.pieces(rec.t, 0, n):
        bag.before(rec.t[a], session)
        outs.append(session.increments(rec.t[a:b], rec.dtheta[a:b], rec.dv[a:b]))
        _to_bag(bag, outs[-1], rec.t, w, f, a, b, session)
    outs.append(session.finish())
    _to_bag(bag, outs[-1], rec.t, w, f, 0, n, session, end=True)
    return Output.concat(outs), session.pipeline, None


def _to_bag(bag, out, t, w, f, a, b, session, end=False):
    """Give ``bag`` the rows of ``out``, from samples ``a:b`` (stamps ``t``, rates ``w, f``).

    Each row's sample is the first of the recent ones stamped at or after it (as the
    node pairs them); ``end``: the run is over, the last period's report is written.
    """
    if len(out.t):
        lo = max(0, a - 8192)
        k = lo + np.searchsorted(t[lo:b], out.t - 1e-9)
        k = np.clip(k, 0, max(b - 1, 0))
        bag.rows(out, w[k], f[k], session)
    bag.after(session, 0 if end else b - a)
    if end and bag.now is not None:
        bag.before(bag.now + bag.p['diagnostic_period'], session)


def replay_bag(path, values, args, log, with_truth=True, bag=None):
    """Run a rosbag2 through an :class:`AlignmentSession`; returns (Output, pipeline, truth).

    ``truth`` is a list of (t, q) or empty (``with_truth`` False: not read). IMU and GNSS
    messages pass the node's input checks (the first occurrence of each reason is
    logged, the counts at the end), in recording order; the IMU between two GNSS
    messages goes in as one block (``AlignmentSession.imu_block``; cut at each diagnostic
    period's end for a result ``bag``, which takes every output). A fault part-way
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
            if bag is not None:
                bag.fault(source, key, text)
            if (source, key) not in seen:
                seen.add((source, key))
                log(f'{source}: {text} (first occurrence; counted at the end)')

    def imu(k0, k1):
        for a, b in ((k0, k1),) if bag is None else bag.pieces(rec.t, k0, k1):
            if b <= a:
                continue
            if bag is not None:
                bag.before(rec.t[a], session)
            outs.append(session.imu_block(rec.t[a:b], rec.w[a:b], rec.f[a:b],
                                          rec.missing[a:b]))
            report()
            if bag is not None:
                _to_bag(bag, outs[-1], rec.t, rec.w, rec.f, a, b, session)

    def event(out):
        outs.append(out)
        report()
        if bag is not None:
            _to_bag(bag, out, rec.t, rec.w, rec.f, k, k, session)

    try:
        k = 0
        for ev, before in zip(events, rec.imu_before):
            imu(k, min(before, n))
            k = max(k, min(before, n))
            if ev.kind == 'truth':
                truth.append((ev.t, ev.data[0]))
                continue
            if bag is not None:
                bag.before(ev.t, session)
            if ev.kind == 'fix':
                event(session.fix(ev.t, *ev.data))
            else:
                event(session.velocity(ev.t, *ev.data))
        imu(k, n)
        outs.append(session.finish())
        if bag is not None:
            _to_bag(bag, outs[-1], rec.t, rec.w, rec.f, 0, n, session, end=True)
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
    args = _parser().parse_args(argv)
    log = (lambda m: None) if args.quiet else (lambda m: print(f'sins_align_replay: {m}',
                                                               file=sys.stderr))
    node_values = {}
    try:
        values = load_parameters(args.params, args.set, log, node_values)
        psins = Path(args.input).suffix.lower() == '.imu'
        csvs, bags = _outputs(args, psins)
    except (ValueError, OSError) as exc:
        print(f'sins_align_replay: error: {exc}', file=sys.stderr)
        return 2
    status, truth, bag = 0, None, None
    try:
        if bags:
            frame = 'imu' if psins else imu_frame_id(args.input, args.imu_topic)
            bag = ResultBag(bags[0], node_values,
                            values.get('coarse_duration', prm.defaults()['coarse_duration']),
                            frame)
        if psins:
            out, pipe, truth = replay_psins(args.input, values, log, args.duration, bag)
        else:
            out, pipe, truth = replay_bag(args.input, values, args, log,
                                          with_truth=bool(args.report), bag=bag)
    except (PsinsFormatError, OSError) as exc:
        print(f'sins_align_replay: error: {exc}', file=sys.stderr)
        if bag is not None:
            bag.abort()
        return 1
    except BagError as exc:
        print(f'sins_align_replay: error: {exc}', file=sys.stderr)
        partial = getattr(exc, 'partial', None)
        if partial is None:
            if bag is not None:
                bag.abort()
            return 1
        out, pipe, truth = partial
        status = 1
    try:
        for path in csvs:
            write_csv(path, out, every=args.every)
        if bag is not None:
            if args.copy_input and not psins:
                bag.copy_input(args.input, log)
            bag.close()
            log(f'result bag: {bag.target}/ (open {bag.target / bag.target.name}.mcap)')
        if args.report and len(out.t):
            plot_report(args.report, out, _truth_euler(out, truth),
                        title=f"{Path(args.input).name}: {pipe.cfg['fine_filter']}")
    except (OSError, BagError) as exc:
        print(f'sins_align_replay: error: cannot write output: {exc}', file=sys.stderr)
        if bag is not None:
            bag.abort()
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

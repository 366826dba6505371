"""One recording through the alignment pipeline into its outputs (``sins_align_replay``).

:func:`replay_one` runs a rosbag2 (:func:`replay_bag`) or a PSINS log
(:func:`replay_psins`) through an :class:`~sins_align_ros.align.AlignmentSession` and writes
its CSV, result bag and report; the command line (:mod:`.replay`) and the fleet
(:mod:`.replay_many`) both call it, so a recording gives the same files either way.
"""
from pathlib import Path

import numpy as np

from ..align import AlignmentSession, Output
from ..align import params as prm
from ..io.bag import BagError, imu_frame_id, read_bag
from ..io.psins import PsinsFormatError, read_psins
from ..io.report import plot_report, truth_euler_at
from ..io.result_bag import ResultBag
from ..io.results import write_csv
from ..units import DEG

_CHUNK = 2000


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


def replay_one(args, values, node_values, csvs, bags, log, fail):
    """Replay ``args.input`` (one path) into ``csvs``, ``bags`` and ``args.report``.

    ``log(text)`` takes the progress lines, ``fail(text)`` each error's one line when it
    happens (an input fault before the outputs are written, as before the fleet).
    Returns ``(status, out, pipe, written)``: exit status (0 ok, 1 input or output
    fault; what was computed before a fault in the input is still written), the
    :class:`Output` and pipeline (None when nothing ran), and whether the outputs were
    written.
    """
    status, truth, bag = 0, None, None
    psins = Path(args.input).suffix.lower() == '.imu'
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
    except (PsinsFormatError, OSError, BagError) as exc:
        fail(str(exc))
        partial = getattr(exc, 'partial', None)
        if partial is None:
            if bag is not None:
                bag.abort()
            return 1, None, None, False
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
        if bag is not None:
            bag.abort()
        fail(f'cannot write output: {exc}')
        return 1, out, pipe, False
    return status, out, pipe, True


def is_rosbag2_folder(path):
    """Return True if ``path`` is a rosbag2 folder (it holds ``metadata.yaml``)."""
    return (Path(path) / 'metadata.yaml').is_file()


def warnings(pipe):
    """Return the pipeline's warnings and its conditions over the run, as text.

    The last text of each kind of condition (:attr:`~..align.forecast.report.
    ConditionReport.said`), those a result bag's /diagnostics already said among them; a
    counted one (GNSS epochs rejected) counts since the last time it was asked for, which
    with a result bag is the last diagnostic period.
    """
    pipe.conditions()
    return pipe.warnings + pipe.report.said

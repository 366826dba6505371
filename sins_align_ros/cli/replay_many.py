"""A fleet of recordings through ``sins_align_replay``: one result per input and a summary.

    sins_align_replay IN1 IN2 ... | FOLDER --out DIR [--formats csv,mcap,png]
                      [--jobs N | --scheduler ADDRESS] [the single-input options]

Inputs are recordings (rosbag2 folders, ``.mcap``, ``.db3``, PSINS ``.imu``) or folders of
them, one level deep (a folder holding ``metadata.yaml`` is one rosbag2, not a folder of
them). Each runs exactly as it would alone (:func:`.replay_one.replay_one`, same parameters)
and gets ``DIR/<name>.csv`` (and ``.mcap`` result bag, ``.png`` report, per ``--formats``),
``<name>`` being the input's name without its suffix. ``DIR/summary.csv`` has one row per
input (:data:`SUMMARY_COLUMNS`), in the order given (a folder's recordings sorted by
name). A result that would replace an input (``--out`` naming the inputs' folder with
result bags) is refused.

The recordings run one after the other in this process (``--jobs 1``, no Dask needed), on
a local Dask cluster of ``--jobs`` processes, or on a running cluster (``--scheduler`` or
``$DASK_SCHEDULER_ADDRESS``; :mod:`~sins_align_ros.eval.pool`). Each input's result depends
on it alone, so all three give the same files. On a cluster the workers read the inputs
and write ``DIR`` themselves: both must be paths that every worker sees (a shared
filesystem), as ``docs/replay.md#fleets`` says.

Exit status: 0 when every input ran clean, 1 when one had an input or output fault (its
row says which; the others still ran) or the cluster failed, 2 for a usage error (nothing
ran). Errors go to stderr even with ``--quiet``.
"""
import csv
import io
import math
import sys
from pathlib import Path

import numpy as np

from ..nav.frames import yaw_to_heading
from . import replay_one as single

#: what a folder of recordings may hold (and ``metadata.yaml`` folders: rosbag2)
SUFFIXES = ('.mcap', '.db3', '.imu')
FORMATS = ('csv', 'mcap', 'png')
#: the summary's name in the results folder (no input may take it)
SUMMARY_NAME = 'summary'
#: the columns of summary.csv: the end of each run (angles and 1-sigma in degrees, heading
#: from north clockwise) and the time from its first IMU sample to its first ``aligned``
#: row (empty if never); warnings joined by " | "
SUMMARY_COLUMNS = ('input', 'result', 'status', 'error', 'phase', 'duration_s', 'roll_deg',
                   'pitch_deg', 'yaw_deg', 'heading_deg', 'sigma_roll_deg',
                   'sigma_pitch_deg', 'sigma_yaw_deg', 'time_to_aligned_s', 'warnings')


def recordings(inputs):
    """Return the paths of the recordings ``inputs`` name, folders expanded one level.

    :class:`ValueError` for a path that does not exist or a folder with no recording.
    """
    found = []
    for item in map(Path, inputs):
        if not item.exists():
            raise ValueError(f'{item}: no such file or directory')
        if item.is_file() or single.is_rosbag2_folder(item):
            found.append(item)
            continue
        inside = sorted(p for p in item.iterdir()
                        if (p.is_file() and p.suffix.lower() in SUFFIXES)
                        or (p.is_dir() and single.is_rosbag2_folder(p)))
        if not inside:
            raise ValueError(f'{item}: a folder with no recording (rosbag2 folders, '
                             f'{", ".join(SUFFIXES)})')
        found += inside
    return found


def result_names(paths):
    """Return each recording's result name (its name without suffix); unique, or ValueError."""
    names = [p.stem if p.suffix.lower() in SUFFIXES else p.name for p in paths]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(f'two inputs would give results of one name: {", ".join(twice)} '
                         '(rename one, or replay them apart)')
    if SUMMARY_NAME in names:
        raise ValueError(f'an input named {SUMMARY_NAME!r} would write over {SUMMARY_NAME}.csv '
                         '(rename it)')
    return names


def result_paths(out_dir, name):
    """Return the result paths of input ``name`` in ``out_dir`` per format (csv, mcap, png).

    A result bag is the folder ``<name>/`` (:mod:`~sins_align_ros.io.result_bag`).
    """
    return {'csv': out_dir / f'{name}.csv', 'mcap': out_dir / name,
            'png': out_dir / f'{name}.png'}


def _no_overwrite(paths, names, out_dir, formats):
    """Raise ValueError when a result would be written over an input (``--out`` = inputs)."""
    inputs = {p.resolve() for p in paths}
    for name in names:
        for fmt, target in result_paths(out_dir, name).items():
            if fmt in formats and target.resolve() in inputs:
                raise ValueError(f'the result {target} would replace the input of that name: '
                                 '--out must name another folder')


def _formats(text):
    """Return the set of result formats of ``--formats``; ValueError naming a bad one."""
    got = {f.strip().lower() for f in text.split(',') if f.strip()}
    bad = sorted(got - set(FORMATS))
    if bad or not got:
        raise ValueError(f'--formats takes {", ".join(FORMATS)}; got {text!r}')
    return got


def _check(args):
    """Return (out folder, formats) of a fleet's ``args``; ValueError if misused."""
    fleet = ('several inputs' if len(args.input) > 1 else
             f'a folder of recordings ({args.input[0]} has no metadata.yaml: not one rosbag2)')
    if len(args.out) != 1:
        raise ValueError(f'with {fleet}, --out names one folder for the results')
    out_dir = Path(args.out[0])
    if out_dir.suffix.lower() in ('.csv', '.mcap'):
        raise ValueError(f'with {fleet}, --out names a folder, not {out_dir}')
    if args.report:
        raise ValueError(f'with {fleet}, ask for the reports with --formats csv,png')
    formats = _formats(args.formats)
    if args.copy_input and 'mcap' not in formats:
        raise ValueError('--copy-input needs result bags: --formats csv,mcap')
    if args.jobs < 1:
        raise ValueError(f'--jobs must be 1 or more, got {args.jobs}')
    return out_dir, formats


def replay_job(job):
    """Replay one recording of a fleet; returns ``(summary row dict, log lines)``.

    ``job``: ``(args, values, node_values, path, name, out_dir, formats)``. Any failure is
    in the row (``status``, ``error``), never raised: one bad recording does not stop
    the others.
    """
    args, values, node_values, path, name, out_dir, formats = job
    lines, errors = [], []
    one = type(args)(**vars(args))
    one.input, one.report = str(path), None
    target = result_paths(out_dir, name)
    csvs = [str(target['csv'])] if 'csv' in formats else []
    bags = [str(target['mcap']) + '.mcap'] if 'mcap' in formats else []
    if 'png' in formats:
        one.report = str(target['png'])
    if path.suffix.lower() == '.imu':
        one.copy_input = False                 # a PSINS log: nothing to copy
    try:
        status, out, pipe, _ = single.replay_one(one, values, node_values, csvs, bags,
                                                 lines.append, errors.append)
    except Exception as exc:                 # a fault in one recording is that row's error
        status, out, pipe = 1, None, None
        errors.append(f'{type(exc).__name__}: {exc}')
    return summary_row(str(path), name, status, '; '.join(errors), out, pipe), lines


def summary_row(path, name, status, error, out, pipe):
    """Return the summary.csv row (dict of :data:`SUMMARY_COLUMNS`) of one run."""
    row = dict.fromkeys(SUMMARY_COLUMNS, '')
    row.update(input=path, result=name, status=status, error=error or '')
    if out is None or pipe is None or not len(out.t):
        return row
    k = len(out.t) - 1
    aligned = np.flatnonzero(out.phase == 'aligned')
    row.update(phase=str(out.phase[k]), duration_s=_num(out.t[k] - out.t[0]),
               warnings=' | '.join(single.warnings(pipe)))
    if len(aligned):
        row['time_to_aligned_s'] = _num(out.t[aligned[0]] - out.t[0])
    if np.isfinite(out.q[k, 0]):
        e, s = np.degrees(out.euler[k]), np.degrees(out.sigma[k])
        row.update(roll_deg=_num(e[0]), pitch_deg=_num(e[1]), yaw_deg=_num(e[2]),
                   heading_deg=_num(math.degrees(yaw_to_heading(out.euler[k, 2]))),
                   sigma_roll_deg=_num(s[0]), sigma_pitch_deg=_num(s[1]),
                   sigma_yaw_deg=_num(s[2]))
    return row


def _num(x):
    """Format a number for summary.csv (the precision of the result CSV's angles)."""
    return f'{float(x):.6f}'


def write_summary(path, rows):
    """Write ``rows`` (dicts of :data:`SUMMARY_COLUMNS`) to ``path`` as CSV."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=SUMMARY_COLUMNS, lineterminator='\n')
    w.writeheader()
    w.writerows(rows)
    Path(path).write_text(buf.getvalue())


def main(args, values, node_values, log):
    """Replay the fleet of ``args.input`` (parameters already loaded); returns the exit code."""
    def error(text):
        print(f'sins_align_replay: error: {text}', file=sys.stderr)

    try:
        out_dir, formats = _check(args)
        # absolute: the workers of a cluster do not share this process's working directory
        paths = [p.resolve() for p in recordings(args.input)]
        names = result_names(paths)
        out_dir = out_dir.resolve()
        _no_overwrite(paths, names, out_dir, formats)
        out_dir.mkdir(parents=True, exist_ok=True)
    except (ValueError, OSError) as exc:
        error(exc)
        return 2
    # here, not at the top: a single replay imports this module and must stay light (the
    # evaluation package loads numba; test_kernels.py holds a replay to neither)
    from ..eval.pool import MissingDask, monte_carlo, scheduler_address
    address = scheduler_address(args.scheduler, args.jobs)
    where = (f'the cluster at {address}' if address
             else f'{min(args.jobs, len(paths))} processes' if args.jobs > 1
             else 'this process')
    log(f'{len(paths)} recordings in {where}; results in {out_dir}/')
    jobs = [(args, values, node_values, p, n, out_dir, formats) for p, n in zip(paths, names)]
    try:
        results = monte_carlo(replay_job, jobs, procs=args.jobs, progress=not args.quiet,
                              scheduler=args.scheduler)
    except MissingDask as exc:
        error(exc)
        return 2
    except Exception as exc:         # the cluster failed (a lost connection, a killed worker)
        error(f'the runs did not complete: {type(exc).__name__}: {exc}')
        return 1
    rows = []
    for (row, lines), name in zip(results, names):
        for line in lines:
            log(f'{name}: {line}')
        if row['error']:
            error(f'{name}: {row["error"]}')
        rows.append(row)
    summary = out_dir / f'{SUMMARY_NAME}.csv'
    try:
        write_summary(summary, rows)
    except OSError as exc:
        error(f'cannot write {summary}: {exc}')
        return 1
    bad = [r['result'] for r in rows if r['status']]
    text = (f'summary: {summary} ({len(rows) - len(bad)} of {len(rows)} clean'
            + (f'; faults in {", ".join(bad)})' if bad else ')'))
    if bad:
        error(text)
    else:
        log(text)
    return 1 if bad else 0

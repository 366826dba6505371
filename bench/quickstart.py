#!/usr/bin/env python3
"""What /diagnostics says at the end of a good and a bad run, per quickstart platform (issue 47).

For each platform of docs/quickstart.md: its preset in config/ on a simulated run of its
kind (good), and the same with one mistake a new user makes (bad). Each run is fed to an
``AlignmentSession`` as the node feeds it; at the end the /diagnostics status is built as
the node builds it (``io.diagnostic_report.alignment_status``: level, message, and the
values a user looks at first), with the final error against the simulator's truth.
Writes ``bench/results/quickstart.md``; docs/quickstart.md quotes it.

Usage: python bench/quickstart.py [--seed 1] [--out FILE]
"""
import argparse
import os
import sys
from pathlib import Path
from types import SimpleNamespace

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))      # this checkout's package, not an installed copy
sys.path.insert(0, str(ROOT / 'bench'))

from presets import (arms, compass_epochs, installation,  # noqa: E402
                     scenario_of)
from sins_align_ros.align.session import AlignmentSession  # noqa: E402
from sins_align_ros.eval.feed import feed_arrays  # noqa: E402
from sins_align_ros.eval.markdown import page_head, write_markdown  # noqa: E402
from sins_align_ros.eval.run import Run  # noqa: E402
from sins_align_ros.eval.scenarios import simulate  # noqa: E402
from sins_align_ros.io.diagnostic_report import alignment_status  # noqa: E402
from sins_align_ros.io.node_status import typed_state  # noqa: E402

LEVELS = ('OK', 'WARN', 'ERROR')
#: platform -> (preset, scenario key, [(run label, what changes, change)]); a change is
#: ``{'params': {...}}`` (replacing the file's or the installation's values) and/or
#: ``{'gnss': None}`` (the receiver off), ``{'until': s}`` (the run cut there)
PLATFORMS = {
    'ground robot': ('alignment_robot_mems.yaml', 'robot_skid_rotated', [
        ('good', 'the IMU\'s mounting told', {}),
        ('bad', 'the IMU turned (+90 deg about x, -90 about z) and not told',
         {'params': {'imu_mounting_rpy_deg': (0.0, 0.0, 0.0)}})]),
    'car': ('alignment_car_mems.yaml', 'car_consumer', [
        ('good', 'GNSS position and velocity', {}),
        ('bad', 'no GNSS (the receiver not publishing), 450 s', {'gnss': None, 'until': 450.0})]),
    'ship or USV': ('alignment_ship_asckf.yaml', 'ship_underway_mast', [
        ('good', 'mast antenna lever arm told', {}),
        ('bad', 'the 18-m mast lever arm not told',
         {'params': {'gnss_lever_arm_m': (0.0, 0.0, 0.0)}})]),
    'still base': ('alignment_stationary.yaml', 'static_navigation~nognss', [
        ('good', 'navigation-grade IMU at 34 N, the site told (no GNSS)', {}),
        ('bad', 'the site told wrong: 60 N', {'params': {'initial_latitude_deg': 60.0}})]),
}
#: the /diagnostics values quoted per run
VALUES = ('phase', 'reason', 'fine_filter', 'heading_observable', 'tilt_ready',
          'heading_ready', 'consistency_ok', 'self_check_widened', 'self_check_vehicle_tilt_deg',
          'mounting_doubt')


def run_case(preset, key, change, seed):
    """One run: ``(StatusReport, final error deg (3,), final 1-sigma deg (3,))``."""
    sc = scenario_of(key)
    data = simulate(sc, seed)
    if 'gnss' in change:
        data = SimpleNamespace(imu=data.imu, gnss=change['gnss'])
    if 'until' in change:       # end the run inside a window, not at a restart
        n = int(np.searchsorted(data.imu.t, change['until'], side='right'))
        data.imu = SimpleNamespace(**{k: v[:n] if isinstance(v, np.ndarray) else v
                                      for k, v in vars(data.imu).items()})
    heading = compass_epochs(data, seed) if key.endswith('~compass') else None
    params = {**arms(preset)[0][1], **installation(sc), **change.get('params', {})}
    session = AlignmentSession(params)
    session.start_clock(0.0)
    out = feed_arrays(session, data.imu, data.gnss, heading=heading)
    run = Run(out, data, session.pipeline, 0.0)
    s = session.status()
    report = alignment_status('/alignment_node: alignment', 'imu', s,
                              typed_state(s, stopped=False), 1.0,
                              params.get('coarse_duration', 60.0), 0.0, (1, 1), [],
                              session.conditions(), session.warnings[-2:], {})
    f = run.final
    return report, np.degrees(f.euler), np.degrees(f.sigma)


def fmt_deg(v):
    """Angles (3,) deg as text, '-' for unknown."""
    return ' / '.join('-' if not np.isfinite(x) else f'{x:.2f}' for x in v)


def main(argv=None):
    """Run every platform's good and bad case; write the page."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'quickstart.md'))
    args = ap.parse_args(argv)
    cmd = 'python bench/quickstart.py ' + ' '.join(argv if argv is not None else sys.argv[1:])
    lines = page_head(
        'What /diagnostics says on a good and a bad run, per platform (issue 47)', cmd.strip(),
        f'Each platform\'s preset on a simulated run of its kind (seed {args.seed}), and the '
        'same with one mistake. At the end of the run: the status the node publishes on '
        '/diagnostics (level, message, a few values), and the error against the '
        'simulator\'s truth (roll / pitch / yaw, deg) with the published 1-sigma.')
    for platform, (preset, key, cases) in PLATFORMS.items():
        lines += [f'## {platform}', '', f'`config/{preset}` on `{key}`.', '']
        for label, what, change in cases:
            rep, err, sig = run_case(preset, key, change, args.seed)
            vals = dict(rep.values)
            lines += [f'**{label}** ({what}): **{LEVELS[rep.level]}** `{rep.message}`', '',
                      f'- error roll / pitch / yaw: {fmt_deg(err)} deg; 1-sigma '
                      f'{fmt_deg(sig)} deg']
            lines += [f'- `{k}`: {vals[k]}' for k in VALUES if vals.get(k) not in (None, '')]
            lines.append('')
            print(platform, label, LEVELS[rep.level], rep.message, flush=True)
    write_markdown(args.out, lines)
    return 0


if __name__ == '__main__':
    sys.exit(main())

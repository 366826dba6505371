#!/usr/bin/env python3
"""Seed 004 against the USV preset (issue 21, item 6): heading accuracy and honest sigmas.

Seed 004's VBCH settings for a medium-grade USV (:data:`PRESET`, what
``config/alignment_usv_vbch.yaml`` held until issue 44 removed it: on ``seed004_medium``
the node's defaults, whose ``kf`` has no transient after the coarse stage, did better,
``bench/results/usv_vbch_preset.md``) through the whole pipeline (coarse, then
VBCH) on ``seed004_high`` / ``seed004_medium`` / ``seed004_low`` (``sim.presets``:
severe sea, GNSS velocity with Bernoulli outliers p = 0.05 at 20x the noise, 300 s),
N seeded runs per grade and for what the pipeline is told:

- ``told``: the preset with the scenario's sensor model on top
  (``sim.presets.alignment_params``: IMU grade, GNSS noise, site);
- ``preset``: the preset alone plus the site (initial latitude, longitude, height),
  i.e. what a user who takes the medium-grade preset for any USV gets.

Per run: the final ENU misalignment and its published sigma, the heading RMS over the
last 100 s, the share of the 1-s samples after coarse alignment outside 3 sigma and
silent-wrong (``sins_align_ros.eval.integrity``). Per cell: final heading RMS and the
target (seed 004 Table 3 as issue 21 quotes it: 0.2 / 0.9 / 1.5 deg for high / medium /
low), runs ending inside 3 sigma, silent-wrong runs, mean sigma / RMS error (sharpness,
at most 3) and the verdict of ``eval.integrity.verdict``. Writes
``bench/results/severe_sea_presets.md``.

Usage: python bench/severe_sea_presets.py [--runs 10] [--jobs 1] [--grades high,medium,low]
       [--told told,preset] [--set name=value ...] [--out FILE]
"""
import argparse
import os
import sys
import time
from pathlib import Path

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))      # this checkout's package, not an installed copy

from sins_align_ros.align.param_text import parse_value  # noqa: E402
from sins_align_ros.eval.evidence import limits_of  # noqa: E402
from sins_align_ros.eval.integrity import (MAX_SHARPNESS, cell_stats,  # noqa: E402
                                           published_sigma, run_integrity, sample_rows,
                                           spec_limit, verdict)
from sins_align_ros.eval.markdown import machine_summary, write_markdown  # noqa: E402
from sins_align_ros.eval.pool import monte_carlo  # noqa: E402
from sins_align_ros.eval.run import run_pipeline  # noqa: E402
from sins_align_ros.eval.scenarios import named, simulate  # noqa: E402
from sins_align_ros.sim.presets import alignment_params  # noqa: E402
from sins_align_ros.units import DEG  # noqa: E402

#: seed 004's VBCH for a USV in severe sea with GNSS outliers, medium-grade IMU
#: (``sim.presets`` usv_medium): the parameters of the removed config/alignment_usv_vbch.yaml
PRESET = {
    'fine_filter': 'vbch', 'coarse_method': 'inertial_frame', 'coarse_duration': 60.0,
    'gyro_bias_dph': 5.0, 'gyro_bias_instability_dph': 2.0, 'gyro_bias_tau_s': 100.0,
    'gyro_arw_dpsh': 0.1, 'accel_bias_ug': 500.0, 'accel_vrw_ug_rthz': 80.0,
    'gnss_pos_sigma_m': 1.0, 'gnss_vel_sigma_mps': 0.05, 'use_gnss_velocity': True,
    'vb_forgetting': 0.98, 'vb_iterations': 20, 'vbch_c': 100.0, 'vb_outlier_dof': 5.0,
    'gnss_gate_probability': 0.9999, 'gnss_lever_arm_m': (0.0, 0.0, 0.0),
    'imu_mounting_rpy_deg': (0.0, 0.0, 0.0)}
GRADES = ('high', 'medium', 'low')
TOLD = ('told', 'preset')
#: issue 21 item 6: heading target per grade, deg (seed 004 Table 3's VBCH up error for
#: medium and low; 0.2 deg for high, ten times the table's 0.02)
TARGET_DEG = {'high': 0.2, 'medium': 0.9, 'low': 1.5}
SITE = ('initial_latitude_deg', 'initial_longitude_deg', 'initial_height_m')
FIRST_SEED = 1000
RATE_HZ = 100.0
#: the heading statistics window: the last 100 s (seed 004 sec. 4)
WINDOW = 100.0


def params_for(sc, told, extra=None):
    """Pipeline parameters on scenario ``sc``: the preset, plus the sensors (``told``)."""
    pre = dict(PRESET)
    right = alignment_params(sc, pre['fine_filter'])
    if told == 'told':
        out = {**pre, **right}
    elif told == 'preset':
        out = {**pre, **{k: right[k] for k in SITE}}
    else:
        raise ValueError(f'unknown model {told!r}')
    out.update(extra or {})
    return out


def run_job(job):
    """Worker: one grade and seed, every ``told`` on the same data; ``{told: run dict}``."""
    grade, seed, tolds, extra = job
    sc = named(f'seed004_{grade}')
    data = simulate(sc, seed)
    res = {}
    for told in tolds:
        run = run_pipeline(params_for(sc, told, extra), data)
        r = run_integrity(run, RATE_HZ)
        rows = sample_rows(run.out, RATE_HZ)
        err = run.phi(rows)
        sig = published_sigma(run.out.P_phi[rows])
        last = run.out.t[rows] > run.out.t[-1] - WINDOW
        r['up_rms_window'] = float(np.sqrt(np.nanmean(err[last, 2] ** 2)))
        r['up_sigma_window'] = float(np.nanmean(sig[last, 2]))
        r['restarts'] = run.restarts
        r['wall'] = run.wall
        r['seed'] = seed
        res[told] = r
    return res


def deg(x, nd=3):
    """Angle (rad) as degrees text, '-' when not finite."""
    return '-' if not np.isfinite(x) else f'{x / DEG:.{nd}g}'


def main(argv=None):
    """Run the cells and write the results page."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--runs', type=int, default=10)
    ap.add_argument('--jobs', type=int, default=1)
    ap.add_argument('--grades', default=','.join(GRADES))
    ap.add_argument('--told', default=','.join(TOLD))
    ap.add_argument('--set', nargs='*', default=[], metavar='NAME=VALUE',
                    help='override preset parameters (both cells)')
    ap.add_argument('--commit', default='', help='the commit the code is from')
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'severe_sea_presets.md'))
    args = ap.parse_args(argv)
    grades = [g for g in args.grades.split(',') if g]
    tolds = [t for t in args.told.split(',') if t]
    extra = {k: parse_value(k, v) for k, v in (s.split('=', 1) for s in args.set)}
    jobs = [(g, FIRST_SEED + k, tuple(tolds), extra) for g in grades for k in range(args.runs)]
    t0 = time.monotonic()
    per_job = monte_carlo(run_job, jobs, args.jobs)
    wall = time.monotonic() - t0
    runs = {}
    for job, res in zip(jobs, per_job):
        for told, r in res.items():
            runs.setdefault((job[0], told), []).append(r)

    cmd = 'python bench/severe_sea_presets.py ' + ' '.join(
        argv if argv is not None else sys.argv[1:])
    lines = [
        '# Seed 004 against the USV preset (issue 21, item 6)', '',
        f'Command: `{cmd.strip()}` on {machine_summary()}'
        + (f'; commit {args.commit}' if args.commit else '') + '.', '',
        'Seed 004\'s VBCH settings for a medium-grade USV (`PRESET`, once '
        '`config/alignment_usv_vbch.yaml`) through the whole pipeline (coarse, then '
        'fine) on `seed004_<grade>`: severe sea, 300 s, GNSS velocity with Bernoulli '
        'outliers (p = 0.05, 20x the noise). **told**: the preset plus the scenario\'s '
        'sensor model (`alignment_params`); **preset**: the preset plus the site only. '
        'Seeds from 1000.', '',
        'Columns: **U RMS**: final heading (up) error RMS over the runs; **U max**: largest '
        'final |heading error|; **target**: issue 21\'s heading target; **U RMS 100 s**: '
        'RMS over the runs and the last 100 s of 1-s samples; **σU**: mean published heading '
        'sigma at the end; **sharp. E/N/U**: mean sigma / RMS error; **end in 3σ**: runs '
        'ending inside 3 sigma on every axis; **silent**: runs with > 5 % of their 1-s '
        'samples after coarse alignment outside 3 sigma on an axis or one beyond 5 sigma; '
        '**worst out**: the largest share of a run\'s samples outside 3 sigma on an axis; '
        '**verdict**: `eval.integrity.verdict` (sharpness judged where the error is at the '
        'limit; the heading\'s here at any error: a grade that cannot gyrocompass has no '
        'limit) and the heading target.', '',
        '| grade | told | runs | U RMS (deg) | U max | target | U RMS 100 s | σU (deg) '
        '| sharp. E / N / U | end in 3σ | silent | worst out | aligned | verdict |',
        '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    failing, cpu = [], 0.0
    for g in grades:
        sc = named(f'seed004_{g}')
        for told in tolds:
            rs = runs[(g, told)]
            cpu += sum(r['wall'] for r in rs)
            c = cell_stats(rs, limits_of(sc, 'ckf')[0], spec_limit(sc, 'vbch'))
            ok, text = verdict(c)
            if c.sharpness[2] > MAX_SHARPNESS:     # the heading's, judged here at any error
                ok = False
                text += f'; heading sigma {c.sharpness[2]:.1f}x its RMS error'
            end = np.array([r['end_err'] for r in rs])
            umax = float(np.nanmax(np.abs(end[:, 2])))
            win = float(np.sqrt(np.nanmean([r['up_rms_window'] ** 2 for r in rs])))
            worst = float(np.nanmax([np.nanmax(r['outside']) for r in rs]))
            hit = c.rms[2] <= TARGET_DEG[g] * DEG
            if not hit:
                ok = False
                text += f'; heading {c.rms[2] / DEG:.2f} deg > target {TARGET_DEG[g]} deg'
            sharp = ' / '.join('-' if not np.isfinite(x) else f'{x:.1f}' for x in c.sharpness)
            lines.append(
                f'| {g} | {told} | {c.runs} | {deg(c.rms[2])} | {deg(umax)} | {TARGET_DEG[g]} '
                f'| {deg(win)} | {deg(c.sigma[2])} | {sharp} | {c.ended_inside:.0%} '
                f'| {c.silent} | {worst:.0%} | {c.aligned:.0%} | {text} |')
            if not ok:
                why = f' ({"; ".join(c.silent_why)})' if c.silent_why else ''
                failing.append(f'- {g}, {told}: {text}{why}')
    lines += ['', '## Per run (final heading error / sigma, deg)', '']
    for g in grades:
        for told in tolds:
            rs = runs[(g, told)]
            lines.append(f'- {g}, {told}: ' + ', '.join(
                f'{r["end_err"][2] / DEG:+.2f}/{r["end_sigma"][2] / DEG:.2f}'
                + ('*' if r['silent'] else '') for r in rs))
    lines += ['', '(`*`: silent-wrong run.)', '', '## Failing cells', '']
    lines += failing or ['- none.']
    lines += ['', f'Wall time {wall / 60:.1f} min on {args.jobs} process(es), pipeline time '
              f'{cpu / 60:.1f} min.']
    write_markdown(args.out, lines)
    print('\n'.join(lines[-len(failing) - 8:]), file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())

"""The evidence report: ``REPORT.md`` and its figures from the cells of :mod:`.evidence`.

Every fine filter on every scenario of a mode (``quick``: 2 runs of short scenarios;
``full``: 20 runs of every scenario) against truth and the analytic limits, the
pyins-generated data and the real recordings; ``bench/report.py`` is its command line.
"""
import math
import os
import platform
import subprocess
import time
from pathlib import Path

import numpy as np

from ..align.params import MOVING_FILTERS
from ..nav.frames import dcm_to_euler, euler_error, psins_att_to_dcm
from ..units import ARCMIN, DEG
from .evidence import (ABLATION_RUNS, FILTERS, MODES, evidence, filter_extra, fine_filter_of,
                       flagged, make_scenario, why_worse, worse_axes)
from .recordings import read_fog, read_psins_log, run_fog, run_psins

#: git is asked for the commit of the checkout holding this file
_HERE = Path(__file__).resolve().parent


def against_line(source, name, sc, f, c, abl):
    """One bullet of the "against the limits" section for a flagged cell."""
    parts = [f'{label} RMS {am(c.rms_enu[ax])}\' = {c.rms_enu[ax] / c.expected[ax]:.1f}x '
             f'the limit {am(c.expected[ax])}\'' for ax, label in worse_axes(c)]
    parts.append(f'inside 3 sigma {np.nanmin(c.inside):.0%}, NEES {c.nees:.1f}'
                 + (f', {c.failed} runs without an attitude at the end' if c.failed else ''))
    text = f'- {source} `{name}`, {f}: ' + '; '.join(parts) + f' ({why_worse(sc, f, c)}).'
    if abl:
        worst = worse_axes(c)
        ax, label = (max(worst, key=lambda w: c.rms_enu[w[0]] / c.expected[w[0]]) if worst
                     else (2, 'heading'))
        causes, shown = [], []
        for a, (ca, base) in abl.items():
            shown.append(f'{a}: {label} RMS {am(base.rms_enu[ax])}\' -> '
                         f'{am(ca.rms_enu[ax])}\', NEES {base.nees:.1f} -> {ca.nees:.1f}')
            if not flagged(ca):
                causes.append(a)
        text += ' Without ' + '; without '.join(shown) + '.'
        text += (f' Cause: {" or ".join(causes)}.' if causes else
                 ' No single switched-off source explains it.')
    return text


# -- output -----------------------------------------------------------------------------
def am(x, fmt='.2f'):
    """Arcmin text of an angle in rad (or '-' when not finite)."""
    return '-' if not np.isfinite(x) else format(x / ARCMIN, fmt)


def cell_row(name, c):
    """One Markdown table row of a cell."""
    conv = ('-' if not np.isfinite(c.conv) else f'{c.conv:.0f}') + (
        '' if c.conv_frac == 1.0 else f' ({c.conv_frac:.0%})')
    fails = f' ({c.failed} failed)' if c.failed else ''
    ratio = c.rms_enu[2] / c.expected[2] if np.isfinite(c.expected[2]) else math.nan
    return (f'| {name}{fails} | {am(c.mean[0])} / {am(c.rms[0])} | {am(c.mean[1])} / '
            f'{am(c.rms[1])} | {am(c.mean[2])} / {am(c.rms[2])} | '
            f'{am(c.expected[0])} / {am(c.expected[1])} / {am(c.expected[2])} | '
            + ('-' if not np.isfinite(ratio) else f'{ratio:.2f}') + f' | {conv} | '
            + ' / '.join('-' if not np.isfinite(v) else f'{v:.2f}' for v in c.inside)
            + f' | {c.nees:.2f} | {c.speed:.0f}x |')


TABLE_HEAD = ['| filter | roll mean / RMS (\') | pitch mean / RMS (\') | heading mean / RMS (\') '
              '| limit E / N / U (\') | heading RMS / limit | conv. (s) '
              '| inside 3 sigma r / p / y | NEES | speed |',
              '|---|---|---|---|---|---|---|---|---|---|']


def figure(path, title, cells, band):
    """Heading error RMS over the runs and the mean reported sigma, per filter, vs time."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 4.2))
    for k, (name, c) in enumerate(cells.items()):
        col = f'C{k}'
        ax.semilogy(c.series_t, c.series_rms / ARCMIN, color=col, lw=1.2,
                    label=f'{name}: RMS error')
        ax.semilogy(c.series_t, c.series_sig / ARCMIN, color=col, lw=0.8, ls='--',
                    label=f'{name}: mean sigma')
    for k, (name, c) in enumerate(cells.items()):
        if np.isfinite(c.expected[2]):
            ax.axhline(c.expected[2] / ARCMIN, color=f'C{k}', lw=0.8, ls=':',
                       label=f'{name}: analytic limit')
    ax.axhline(band / ARCMIN, color='grey', lw=0.6, ls='-.', label='convergence band')
    ax.set_xlabel('time (s)')
    ax.set_ylabel('heading error (arcmin)')
    ax.set_title(title, fontsize=10)
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def recordings(psins_seconds, data_dir=None):
    """Rows of the real recordings: fog_mems (moving filters vs the FOG), the PSINS laser gyro."""
    rows = []
    rec = read_fog(data_dir)
    if rec is not None:
        for name in FILTERS:
            if fine_filter_of(name) not in MOVING_FILTERS:
                continue
            run, e = run_fog(rec, fine_filter_of(name), **filter_extra(name))
            rows.append(f"| fog_mems (car, MEMS, 100 s) | {name} | {e['roll'] * 60:+.1f} | "
                        f"{e['pitch'] * 60:+.1f} | {e['heading'] * 60:+.1f} | "
                        f"{e['sigma_yaw'] * 60:.1f} | FOG INS | {run.speed:.0f}x |")
    log = read_psins_log(data_dir)
    if log is not None:
        hint = dcm_to_euler(psins_att_to_dcm(log.att0_psins))
        for name in FILTERS:
            if fine_filter_of(name) in MOVING_FILTERS:
                continue
            run = run_psins(log, name, psins_seconds)
            out = run.out
            d = euler_error(out.euler[-1], hint)
            rows.append(f'| psins_lasergyro (still, RLG, {run.span:.0f} s) | '
                        f'{name} | ({out.euler[-1, 0] / DEG:+.3f} deg) | '
                        f'({out.euler[-1, 1] / DEG:+.3f} deg) | {d[2] / ARCMIN:+.1f} | '
                        f'{out.sigma[-1, 2] / ARCMIN:.1f} | file hint (yaw only) | '
                        f'{run.speed:.0f}x |')
    return rows


def machine():
    """One line on the machine and software the report ran on."""
    cpu = platform.processor() or platform.machine()
    try:
        with open('/proc/cpuinfo') as f:
            cpu = next(ln.split(':', 1)[1].strip() for ln in f if ln.startswith('model name'))
    except (OSError, StopIteration):
        pass
    try:
        rev = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=_HERE, text=True,
                             capture_output=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        rev = 'unknown'
    return (f'{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, '
            f'numpy {np.__version__}, commit {rev}')


def summary_table(cells, sources):
    """Compact table: heading RMS (its limit) per scenario and filter, our simulator's data."""
    names = [f for f in FILTERS if any(f in cells.get(s[:2], {}) for s in sources)]
    lines = ['| scenario | ' + ' | '.join(names) + ' |', '|---|' + '---|' * len(names)]
    for src in sources:
        if src[0] != 'sim':
            continue
        vals = []
        for f in names:
            c = cells[src[:2]].get(f)
            if c is None:
                vals.append('n/a')
                continue
            lim = am(c.expected[2]) if np.isfinite(c.expected[2]) else 'none'
            vals.append(f'{am(c.rms[2])} ({lim})' + ('' if c.inside[2] >= 0.9 else ' *'))
        lines.append(f'| {src[1]} | ' + ' | '.join(vals) + ' |')
    return lines


def build_report(out, quick=False, runs=None, procs=None, data_dir=None):
    """Run every cell of the mode, write ``out/REPORT.md`` and ``out/report/*.png``.

    ``quick``: the CI-size mode (else ``full``); ``runs`` per cell (default: the
    mode's); ``procs`` processes (default: the machine's cores); ``data_dir``: the
    recordings (default :data:`~.recordings.SHARED_DATA`). Returns the cells
    ``{(source, scenario): {filter: cell}}``.
    """
    mode = MODES['quick' if quick else 'full']
    procs = (os.cpu_count() or 1) if procs is None else procs
    command = 'python bench/report.py' + (' --quick' if quick else '') + (
        f' --runs {runs}' if runs else '')
    out_dir = Path(out)
    fig_dir = out_dir / 'report'
    fig_dir.mkdir(parents=True, exist_ok=True)
    t_start = time.monotonic()

    ev = evidence(mode, runs, procs)
    runs, cells, skipped, ablated = ev.runs, ev.cells, ev.skipped, ev.ablated
    L = ['# Evidence report: every fine filter on every scenario', '',
         f'Command: `{command}` ({runs} seeded runs per scenario, seeds 1000...; '
         f'{procs} processes). Machine: {machine()}.', '',
         'Every run goes through the whole pipeline (coarse alignment, then the fine filter) '
         'with the parameters that describe the simulated sensors '
         '(`sim.presets.alignment_params`); the error is estimate minus truth at the last '
         'sample, REP-103 roll / pitch / yaw (the heading error is the yaw error with its '
         'sign). **limit**: the still-base accuracy limit of the sensors per ENU axis '
         '(seed 002 eq. 15, `eval.limits`): sqrt(bias term^2 + noise term^2) over the '
         'fine-alignment time, the RMS a filter reaching the limit makes; '
         '"heading RMS / limit" compares the up-axis misalignment RMS with it. '
         '**conv.**: median time after which the heading error stays inside the band '
         '1.2 x bias + 3 x noise (1 deg where the gyro cannot gyrocompass); in brackets '
         'the share of runs that got there. **inside 3 sigma**: share of runs whose final '
         'error is inside 3x the reported sigma; **NEES**: average normalised estimation '
         'error squared of the ENU misalignment (3 for a consistent filter). **speed**: '
         'x real time of the pipeline alone, one core per run.', '',
         '## Summary', '',
         'Final heading error RMS in arcmin, the analytic limit in brackets (none: the gyro '
         'cannot find north, heading only from motion); * = fewer than 90% of the runs '
         'inside their reported 3 sigma; n/a: the filter\'s model does not apply.', '',
         '<!-- report:summary -->']
    L += summary_table(cells, mode.sources)
    L += ['<!-- /report:summary -->', '']
    worse = []
    for source, name, duration in mode.sources:
        sc = make_scenario(name, duration)
        key = (source, name)
        title = ('pyins-generated data (independent simulator), ' if source == 'pyins'
                 else '') + f'`{name}`'
        L += [f'## {title}: {sc.description}, {sc.duration:.0f} s', '']
        row = cells[key]
        if row:
            note = next(iter(row.values())).note
            if note:
                L += [f'Heading limit: none ({note}).', '']
            L += TABLE_HEAD + [cell_row(f, c) for f, c in row.items()]
            png = f'{source}_{name}.png'
            figure(fig_dir / png, f'{title.strip("`")}: heading error, {runs} runs', row,
                   next(iter(row.values())).band)
            L += ['', f'![heading convergence](report/{png})', '']
        for f, why in skipped.get(key, {}).items():
            L.append(f'- {f}: not run ({why}).')
        L.append('')
        for f, c in row.items():
            if flagged(c):
                worse.append(against_line(source, name, sc, f, c,
                                          ablated.get((source, name, f), {})))
    L += ['## Against the analytic limits', '',
          'Cells whose RMS is more than 1.5x the limit (and more than 0.1\' above it), or '
          'whose reported sigma does not cover the error (under 90% inside 3 sigma or NEES '
          'over 9): by how much, the reasons the measurements show, and for our simulator\'s '
          f'data an ablation: {ABLATION_RUNS} of the runs again with one error source '
          'switched off in the data (the filter told the same as before); a source whose '
          'removal brings the cell back to its limit and to a consistent sigma is named '
          'the cause. Elsewhere the filters reach the limit of their sensors (ratio near 1; '
          'below 1 where motion makes heading more observable than on a still base).', '']
    L += worse or ['- none.']
    rec = recordings(mode.psins_seconds, data_dir)
    if rec:
        L += ['', '## Real recordings (../shared/data)', '',
              'Final roll, pitch and heading error against the reference, arcmin. psins: '
              'no reference attitude; roll and pitch are the estimates (in brackets), heading '
              'is compared with the file\'s yaw hint ("maybe inaccurate").', '',
              '| recording | filter | roll | pitch | heading | sigma yaw | reference | speed |',
              '|---|---|---|---|---|---|---|---|'] + rec
    wall = time.monotonic() - t_start
    L += ['', f'Wall time of this report: {wall / 60:.1f} min.']
    (out_dir / 'REPORT.md').write_text('\n'.join(L) + '\n')
    print(f'wrote {out_dir / "REPORT.md"} in {wall / 60:.1f} min', flush=True)
    return cells


def report_block(text, tag='report:summary'):
    """Return the lines between ``<!-- tag -->`` and ``<!-- /tag -->`` of a Markdown text."""
    start, end = f'<!-- {tag} -->', f'<!-- /{tag} -->'
    return text.split(start, 1)[1].split(end, 1)[0]

#!/usr/bin/env python3
"""Every preset in config/ against the node's defaults, on scenarios of its own kind (issue 44).

Each ``config/alignment_*.yaml`` is read with ``align.param_text.load_yaml`` (as the node reads
its ``--params-file``) and run through the whole pipeline on the scenarios of its kind
(:data:`SCENARIOS_OF`), N seeded runs each, and so are the node's defaults (no parameter
at all) on the same data: each arm gets exactly its file, as the node would. A
``config/simulator_*.yaml`` builds the data of the alignment presets it pairs with (its
scenario and rates, as ``simulator_node`` would publish them).

Scenario keys: a ``sim.presets`` name (``name@grade``: with the IMU of that sensor grade),
``~nognss`` appended for the same without a receiver, ``~compass`` for the same with a
GNSS compass (:data:`COMPASS_SIGMA_DEG` at 1 Hz, in both arms); a simulator YAML in config/
(its scenario at its rates); ``fog_mems``, the
real MEMS car of ``../shared/data`` (one run: the data are the data), judged as
``bench/defaults.py`` judges it (``car_stats``: the errors less the 0.3 deg mounting
tolerance).

Per cell (``eval.integrity``): final heading and tilt error RMS over the runs (the
heading's over the runs that publish one at the end), the heading RMS over each run's
published 1-s samples, silent-wrong runs, runs ending inside 3 sigma, runs ending
``aligned``, runs ending with the heading declared unknown, the mean final heading
1-sigma, the median time to the first ``aligned`` row. The verdict rule is
:func:`compare` (its docstring, repeated on the page). ``--ablate FILE`` adds, for that
preset, one arm per parameter it sets with that parameter removed (the node's default
instead): which of its values help and which hurt.

Usage: python bench/presets.py [--runs 10] [--jobs 1] [--presets a.yaml,b.yaml]
       [--ablate FILE] [--cache] [--out bench/results/presets.md]
"""
import argparse
import hashlib
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))      # this checkout's package, not an installed copy
sys.path.insert(0, str(ROOT / 'bench'))

from defaults import FOG_FIRST_TURN_S, car_stats  # noqa: E402
from sins_align_ros.align.param_text import load_yaml  # noqa: E402
from sins_align_ros.align.params import split_node_params  # noqa: E402
from sins_align_ros.eval.cache import simulate_cached  # noqa: E402
from sins_align_ros.eval.integrity import (cell_stats, inside_at_end,  # noqa: E402
                                           published_sigma, run_integrity, sample_rows)
from sins_align_ros.eval.markdown import page_head, write_markdown  # noqa: E402
from sins_align_ros.eval.pool import monte_carlo, scheduler_address  # noqa: E402
from sins_align_ros.eval.recordings import read_fog  # noqa: E402
from sins_align_ros.eval.run import run_pipeline  # noqa: E402
from sins_align_ros.eval.scenarios import simulate  # noqa: E402
from sins_align_ros.io.sim_messages import simulated_scenario  # noqa: E402
from sins_align_ros.nav.frames import dcm_to_euler  # noqa: E402
from sins_align_ros.sim.gnss import heading_measurements  # noqa: E402
from sins_align_ros.sim.presets import alignment_params  # noqa: E402
from sins_align_ros.units import DEG  # noqa: E402

CONFIG = ROOT / 'config'
#: alignment preset -> the scenarios of its kind, and why those
SCENARIOS_OF = {
    'alignment_car_mems.yaml': (
        ('fog_mems', 'seed003_car', 'car_rtk', 'car_consumer'),
        'a car with a MEMS IMU and GNSS position + velocity: the real fog_mems car it was '
        'written for, seed 003\'s car, a car in town with RTK that stands still first (the '
        'simulated kin of issue 44\'s real RTK drive) and one with raw AHRS triads and a '
        'consumer receiver'),
    'alignment_robot_mems.yaml': (
        ('robot_lot', 'robot_skid', 'robot_skid_rotated'),
        'a small ground robot at about 1 m/s with frequent turns: a MEMS IMU still first '
        'with a consumer receiver (position and velocity at 5 Hz); raw AHRS triads on a '
        'vibrating skid-steer chassis never still, with positions only at 2.5 Hz; the same '
        'with the IMU turned as robot_localization\'s test robot'),
    'alignment_stationary.yaml': (
        ('static_navigation~nognss', 'static_tactical~nognss', 'simulator_seed002.yaml',
         'simulator_ship_sway.yaml'),
        'a base that does not translate, at the preset\'s latitude: still navigation- and '
        'tactical-grade IMUs without GNSS (where only the site tells the node its latitude), '
        'seed 002\'s still IMU, a moored swaying ship with GNSS (the README\'s pairing)'),
    'alignment_ship_asckf.yaml': (
        ('simulator_seed000.yaml', 'ship_underway'),
        'a marine-grade ship under way with GNSS: seed 000\'s ship, a ship that turns'),
}
# alignment_usv_vbch.yaml (seed 004's VBCH, USV in severe sea) was measured on seed004_medium
# and removed: no better than the defaults (bench/results/usv_vbch_preset.md)
#: seconds simulated where a scenario's own run is longer than the benchmark needs
DURATION_S = {'simulator_seed000.yaml': 600.0}
#: scenario key suffix: the vehicle carries a GNSS compass (an external heading at 1 Hz)
COMPASS = '~compass'
#: the compass's white noise, deg: a dual-antenna receiver on a 1-2 m baseline
COMPASS_SIGMA_DEG = 0.2
#: parameters of an installation, set from the scenario in every arm (:func:`installation`)
INSTALLATION = ('gnss_lever_arm_m', 'imu_mounting_rpy_deg')
#: the verdict of a preset that sets only an installation and loses nothing
INSTALLATION_ONLY = 'the defaults (installation only)'
FIRST_SEED = 1
#: simulation cache of this benchmark (``--cache``)
CACHE = Path(os.environ.get('TMPDIR', '/tmp')) / 'sins_align_presets_cache'
#: the verdict's margins: a figure 10 % apart is a change, nearer is the same
WORSE, BETTER = 1.1, 0.9
#: heading RMS differences below this are the same whatever the ratio, deg
HEADING_FLOOR_DEG = 0.02
#: tilt RMS differences below this are the same whatever the ratio, deg: about the tilt
#: limit of a 20-ug navigation-grade accelerometer bias (0.0011 deg), below what any IMU
#: resolves (the marine ship preset's 1-arcsec tilt change, 0.0016 -> 0.0019 deg, was
#: its only "loss")
TILT_FLOOR_DEG = 0.001


def params_digest(path, node_name):
    """First 12 hex digits of the SHA-1 of the parameters file ``path`` sets (not its comments)."""
    p = load_yaml(path, node_name)
    return hashlib.sha1(json.dumps(p, sort_keys=True).encode()).hexdigest()[:12]


def scenario_of(key):
    """Build scenario ``key``: a preset name or a ``simulator_*.yaml`` (None for fog_mems)."""
    if key == 'fog_mems':
        return None
    if key.endswith(COMPASS):
        return scenario_of(key[:-len(COMPASS)])
    if key.endswith('~nognss'):
        sc = scenario_of(key[:-len('~nognss')])
        sc.gnss = None
        return sc
    if not key.endswith('.yaml'):
        name, _, grade = key.partition('@')
        return simulated_scenario(name, grade, DURATION_S.get(key, 0.0))
    p = load_yaml(CONFIG / key, 'simulator_node')
    sc = simulated_scenario(p['scenario'], p.get('grade', ''),
                            DURATION_S.get(key, p.get('duration', 0.0)))
    if p.get('imu_rate_hz'):
        sc.imu_rate_hz = float(p['imu_rate_hz'])
    if p.get('gnss_rate_hz') and sc.gnss is not None:
        sc.gnss = replace(sc.gnss, rate_hz=float(p['gnss_rate_hz']))
    return sc


def installation(sc):
    """Return scenario ``sc``'s installation parameters (lever arm, IMU mounting), a dict.

    They describe where the sensors are on the vehicle, which every user sets whatever
    else they keep at the defaults: each arm gets them, replacing a preset's placeholders.
    """
    told = alignment_params(sc, 'auto')
    return {k: told[k] for k in INSTALLATION if k in told}


def compass_epochs(data, seed):
    """Return a GNSS compass's epochs on ``data``'s vehicle: 1 Hz, :data:`COMPASS_SIGMA_DEG`."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 23]))
    return heading_measurements(data.imu.t, data.imu.euler[:, 2],
                                np.radians(COMPASS_SIGMA_DEG), 1.0, rng)


def installation_only(preset):
    """Tell whether ``preset`` sets nothing but an installation (and frame names).

    Such a file is the node's defaults with the places a user fills in (the platforms
    where no tuning beat the defaults): measured, its verdict is :data:`INSTALLATION_ONLY`
    when it has no loss.
    """
    values, _ = split_node_params(load_yaml(CONFIG / preset))
    return set(values) <= set(INSTALLATION)


def arms(preset, ablate=False):
    """``[(label, params)]`` of a preset: itself, and each parameter removed when ``ablate``."""
    p = split_node_params(load_yaml(CONFIG / preset))[0]   # frame names etc. aside
    out = [('preset', p)]
    if ablate:
        out += [(f'without {k}', {n: v for n, v in p.items() if n != k}) for k in p]
    return out


def time_to_aligned(out, t0):
    """Seconds from ``t0`` to the first ``aligned`` row (NaN if none)."""
    k = np.flatnonzero(out.phase == 'aligned')
    return float(out.t[k[0]] - t0) if len(k) else float('nan')


def sim_run(run, rate):
    """:func:`run_integrity` of a simulated run, with the heading RMS while published."""
    r = run_integrity(run, rate)
    rows = sample_rows(run.out, rate)
    err, sig = run.phi(rows), published_sigma(run.out.P_phi[rows])
    pub = np.isfinite(err[:, 2]) & np.isfinite(sig[:, 2])
    r['head_sq'] = (float(np.sum(err[pub, 2] ** 2)), int(pub.sum()))
    # each published 1-s row's heading error by its stamp (ms), for the common span
    r['head_rows'] = dict(zip(np.round(run.out.t[rows][pub] * 1e3).astype(np.int64).tolist(),
                              err[pub, 2].tolist()))
    r['t_aligned'] = time_to_aligned(run.out, 0.0)
    return r


def run_job(job):
    """Worker: scenario ``key``, one seed, every arm on the same data; ``{arm: run dict}``.

    ``job``: ``(key, seed, [(arm, params)], cached)``.
    """
    key, seed, todo, cached = job
    sc = scenario_of(key)
    data = simulate_cached(sc, seed, CACHE) if cached else simulate(sc, seed)
    heading = compass_epochs(data, seed) if key.endswith(COMPASS) else None
    installed = installation(sc)
    res = {}
    for arm, params in todo:
        run = run_pipeline({**params, **installed}, data, heading=heading)
        res[arm] = sim_run(run, sc.imu_rate_hz)
        res[arm]['ran'] = run.pipeline.status()['fine_filter']
    return res


def fog_run(rec, params, tol_deg=0.3):
    """Return the fog_mems car under ``params`` as a run dict.

    Silent-wrong and ended inside 3 sigma as ``bench/defaults.py`` judges this car
    (``car_stats``: the errors less the mounting tolerance ``tol_deg``); the heading RMS
    while published as on the simulated cars, the FOG reference as the truth.
    """
    imu = rec.imu_like()
    hi = np.clip(np.searchsorted(rec.ref_t, imu.t), 1, len(rec.ref_t) - 1)
    near = np.where(imu.t - rec.ref_t[hi - 1] < rec.ref_t[hi] - imu.t, hi - 1, hi)
    imu.euler = dcm_to_euler(rec.ref_C[near])
    run = run_pipeline(params, SimpleNamespace(imu=imu, gnss=rec.gnss_like()),
                       use_velocity=True, t0=rec.t[0] - 0.01)
    r = sim_run(run, 1.0 / np.median(np.diff(rec.t)))
    r['t_aligned'] = time_to_aligned(run.out, rec.t[0])
    _, _, _, r['silent'], e, _ = car_stats(
        run.out, lambda t: rec.ref_C[int(np.argmin(np.abs(rec.ref_t - t)))],
        rec.t[0] + FOG_FIRST_TURN_S, tol_deg)
    r['why'] = 'car_stats' if r['silent'] else ''
    less = np.sign(e) * np.maximum(np.abs(e) - tol_deg, 0.0)
    r['end_inside'] = inside_at_end(np.radians(less), r['end_sigma'])
    r['ran'] = run.pipeline.status()['fine_filter']
    return r


def summary(rs):
    """Figures of one cell (a list of run dicts) for the table and :func:`compare`."""
    c = cell_stats(rs, np.full(3, np.nan))
    end = np.array([r['end_err'] for r in rs])
    sig = np.array([r['end_sigma'] for r in rs])
    pub = np.isfinite(end[:, 2]) & np.isfinite(sig[:, 2])
    sq = sum(r['head_sq'][0] for r in rs)
    n = sum(r['head_sq'][1] for r in rs)
    ta = [r['t_aligned'] for r in rs if np.isfinite(r['t_aligned'])]
    inside = [r['end_inside'] for r in rs if r['end_inside'] is not None]
    return SimpleNamespace(
        runs=len(rs), silent=c.silent, inside=int(sum(inside)), with_att=len(inside),
        aligned=int(sum(r['phase'] == 'aligned' for r in rs)), unknown=c.heading_unknown,
        head=float(np.sqrt(np.mean(end[pub, 2] ** 2)) / DEG) if pub.any() else float('nan'),
        head_run=float(np.sqrt(sq / n) / DEG) if n else float('nan'),
        tilt=float(np.sqrt(np.nanmean(end[:, :2] ** 2)) / DEG),
        sigma=float(np.mean(sig[pub, 2]) / DEG) if pub.any() else float('nan'),
        t_aligned=float(np.median(ta)) if ta else float('nan'), n_aligned=len(ta),
        ran=sorted({r['ran'] for r in rs}), why=c.silent_why)


def common_rms(rs_p, rs_d):
    """Heading RMS (deg) of two cells over the 1-s rows both publish: ``(p, d)``.

    ``rs_p``, ``rs_d``: the run dicts of the two arms, run k of each on the same data.
    An arm that is aligned sooner publishes earlier, less accurate rows; its RMS over
    its own rows (the table's "while published") mixes that speed with accuracy, so the
    verdict compares the rows both have.
    """
    sq_p = sq_d = 0.0
    n = 0
    for a, b in zip(rs_p, rs_d):
        both = a['head_rows'].keys() & b['head_rows'].keys()
        sq_p += sum(a['head_rows'][t] ** 2 for t in both)
        sq_d += sum(b['head_rows'][t] ** 2 for t in both)
        n += len(both)
    if not n:
        return float('nan'), float('nan')
    return float(np.sqrt(sq_p / n) / DEG), float(np.sqrt(sq_d / n) / DEG)


def _ratio_change(p, d, floor=0.0):
    """-1 (smaller), +1 (larger) or 0: ``p`` against ``d`` with the 10 % margins."""
    if not (np.isfinite(p) and np.isfinite(d)) or abs(p - d) <= floor:
        return 0
    return 1 if p > WORSE * d else -1 if p < BETTER * d else 0


def compare(p, d):
    """Preset cell ``p`` against the defaults' ``d`` on one scenario: ``(losses, gains)``.

    Losses: more silent-wrong runs; fewer runs ending inside 3 sigma; fewer ending
    ``aligned``; more ending with the heading unknown; final heading, heading-while-both-
    publish (:func:`common_rms`) or tilt RMS more than 10 % larger (heading differences
    under 0.02 deg, tilt differences under 0.001 deg are the same). Gains: the opposite
    of any loss, a mean final heading 1-sigma 10 % smaller, a median time to ``aligned``
    10 % shorter. A
    preset is **better** when it has no loss on any of its scenarios and a gain on at
    least one, else **no better**; a preset that sets only an installation (lever arm,
    mounting: the scenario's in both arms) and loses nothing is **the defaults
    (installation only)**.
    """
    losses, gains = [], []

    def count(name, pv, dv, more_is_better):
        if pv != dv:
            good = (pv > dv) == more_is_better
            (gains if good else losses).append(f'{name} {dv} -> {pv}')

    count('silent-wrong', p.silent, d.silent, False)
    count('ended inside 3σ', p.inside, d.inside, True)
    count('ended aligned', p.aligned, d.aligned, True)
    count('heading unknown', p.unknown, d.unknown, False)
    for name, pv, dv, floor, lower_good in (
            ('heading RMS', p.head, d.head, HEADING_FLOOR_DEG, True),
            ('heading RMS while both publish', p.head_common, d.head_common,
             HEADING_FLOOR_DEG, True),
            ('tilt RMS', p.tilt, d.tilt, TILT_FLOOR_DEG, True),
            ('heading σ', p.sigma, d.sigma, 0.0, None),
            ('time to aligned', p.t_aligned, d.t_aligned, 0.0, None)):
        ch = _ratio_change(pv, dv, floor)
        if ch == 0:
            continue
        text = f'{name} {dv:.3g} -> {pv:.3g}'
        if lower_good is None:      # smaller is a gain, larger no loss by itself
            if ch < 0:
                gains.append(text)
        else:
            (gains if ch < 0 else losses).append(text)
    return losses, gains


def fmt(x, nd=3):
    """Return a number as text, '-' when not finite."""
    return '-' if not np.isfinite(x) else f'{x:.{nd}g}'


def row(preset, key, arm, s):
    """One table row."""
    return (f'| {preset} | {key} | {arm} | {"/".join(s.ran)} | {s.runs} | {fmt(s.head)} '
            f'| {fmt(s.head_run)} | {fmt(s.tilt)} | {s.silent} | {s.inside}/{s.with_att} '
            f'| {s.aligned} | {s.unknown} | {fmt(s.sigma)} '
            f'| {fmt(s.t_aligned, 4)} ({s.n_aligned}) |')


HEADER = ['| preset | scenario | parameters | filter run | runs | heading RMS (deg) '
          '| heading RMS while published (deg) | tilt RMS (deg) | silent-wrong '
          '| ended inside 3σ | ended aligned | heading unknown at end | heading 1σ (deg) '
          '| time to aligned, s (runs) |', '|---|---|---|---|---|---|---|---|---|---|---|---|'
          '---|---|']


def main(argv=None):
    """Run every preset's cells and write the results page."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--runs', type=int, default=10)
    ap.add_argument('--jobs', type=int, default=1,
                    help='processes: a local Dask cluster of N workers (default 1: this one)')
    ap.add_argument('--scheduler', metavar='ADDRESS',
                    help='run on the Dask cluster of this scheduler (default '
                         '$DASK_SCHEDULER_ADDRESS; docs/testing.md#a-cluster)')
    ap.add_argument('--presets', default=','.join(SCENARIOS_OF))
    ap.add_argument('--ablate', default='', help='a preset file: one arm per parameter removed')
    ap.add_argument('--cache', action='store_true', help='keep the simulations on disk')
    ap.add_argument('--scenarios', default='',
                    help='scenario keys replacing the preset\'s (one preset only; a page of '
                         'its own, e.g. a case a preset is not written for)')
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'presets.md'))
    args = ap.parse_args(argv)
    presets = [p for p in args.presets.split(',') if p]
    scenarios_of = dict(SCENARIOS_OF)
    if args.scenarios:
        if len(presets) != 1:
            raise SystemExit('--scenarios takes one preset (--presets FILE)')
        scenarios_of[presets[0]] = (tuple(args.scenarios.split(',')), 'given with --scenarios')
    unknown = sorted({p.name for p in CONFIG.glob('alignment_*.yaml')} - set(SCENARIOS_OF))
    if unknown:
        raise SystemExit(f'no scenario for {", ".join(unknown)}: add it to SCENARIOS_OF')
    todo = {}       # scenario key -> {arm label: params}
    for pre in presets:
        for key in scenarios_of[pre][0]:
            cell = todo.setdefault(key, {'defaults': {}})
            for arm, params in arms(pre, pre == args.ablate):
                cell[f'{pre}: {arm}'] = params
    t0 = time.monotonic()
    results = {}    # (key, arm) -> [run dicts]
    rec = read_fog() if 'fog_mems' in todo else None
    for arm, params in todo.pop('fog_mems', {}).items():
        if rec is not None:
            results[('fog_mems', arm)] = [fog_run(rec, params)]
    jobs = [(key, FIRST_SEED + k, list(cells.items()), args.cache)
            for key, cells in todo.items() for k in range(args.runs)]
    for job, res in zip(jobs, monte_carlo(run_job, jobs, args.jobs, scheduler=args.scheduler)):
        for arm, r in res.items():
            results.setdefault((job[0], arm), []).append(r)
    wall = time.monotonic() - t0
    cmd = 'python bench/presets.py ' + ' '.join(argv if argv is not None else sys.argv[1:])
    lines = page_head(
        'Presets against the node\'s defaults (issue 44, item 7)', cmd.strip(),
        f'Each `config/alignment_*.yaml`, read as the node reads its `--params-file`, '
        f'through the whole pipeline on scenarios of its kind, {args.runs} seeded runs '
        f'each (seeds from {FIRST_SEED}; the real fog_mems car: one run), against the '
        'node\'s defaults (no parameter at all) on the same data. A `simulator_*.yaml` '
        'gives the data of the presets it pairs with (its scenario at its rates). A '
        'scenario\'s installation (GNSS lever arm, IMU mounting) is set in both arms, '
        'replacing a preset\'s placeholders: every user sets theirs. `~compass`: both arms '
        f'get a GNSS compass, {COMPASS_SIGMA_DEG} deg white at 1 Hz.',
        '**heading RMS**: final heading (up) error over the runs publishing a heading at '
        'the end; **while published**: over every 1-s sample after coarse alignment with '
        'a published heading (fog_mems: against the FOG reference); **tilt RMS**: final '
        'east/north error; **silent-wrong**, '
        '**ended inside 3σ**: `eval.integrity` (fog_mems: less its 0.3 deg mounting '
        'tolerance); **heading 1σ**: the mean final published heading sigma; **time to '
        'aligned**: median to the first `aligned` row (runs reaching it).',
        '**Verdict rule** (`compare`): ' + ' '.join(compare.__doc__.split('\n\n')[1].split()))
    verdicts = {}
    for pre in presets:
        keys, why = scenarios_of[pre]
        lines += [f'## {pre}', '', f'Scenarios: {", ".join(f"`{k}`" for k in keys)} ({why}).',
                  ''] + HEADER
        losses, gains, common = [], [], []
        for key in keys:
            if (key, 'defaults') not in results:
                lines.append(f'| {pre} | {key} | (recording absent: skipped) |')
                continue
            d = summary(results[(key, 'defaults')])
            lines.append(row(pre, key, 'defaults', d))
            for arm in (a for (k, a) in results if k == key and a.startswith(pre + ': ')):
                s = summary(results[(key, arm)])
                lines.append(row(pre, key, arm.split(': ', 1)[1], s))
                if arm == f'{pre}: preset':
                    s.head_common, d.head_common = common_rms(results[(key, arm)],
                                                              results[(key, 'defaults')])
                    common.append(f'{key} {fmt(s.head_common)} against '
                                  f'{fmt(d.head_common)}')
                    lo, ga = compare(s, d)
                    losses += [f'{key}: {x}' for x in lo]
                    gains += [f'{key}: {x}' for x in ga]
        better = not losses and bool(gains)
        verdicts[pre] = ('better' if better else INSTALLATION_ONLY if installation_only(pre)
                         and not losses else 'no better')
        lines += ['', 'Heading RMS (deg) over the 1-s rows both publish, preset against '
                  'defaults: ' + '; '.join(common) + '.',
                  '', f'**Verdict: {verdicts[pre]}.** Losses: '
                  + ('; '.join(losses) or 'none') + '. Gains: ' + ('; '.join(gains) or 'none')
                  + '.', '']
    lines += ['## Verdicts', '', 'Digest: `params_digest`, the parameters the verdict was '
              'measured with (test/test_presets.py compares it with the file).', '',
              '| file | verdict | digest |', '|---|---|---|']
    lines += [f'| {p} | {v} | {params_digest(CONFIG / p, "alignment_node")} |'
              for p, v in verdicts.items()]
    for f in sorted(CONFIG.glob('simulator_*.yaml')):
        users = [p for p in presets if f.name in scenarios_of[p][0]]
        lines.append(f'| {f.name} | simulator data (of {", ".join(users) or "no preset"}) '
                     f'| {params_digest(f, "simulator_node")} |')
    address = scheduler_address(args.scheduler, args.jobs)
    lines += ['', f'Wall time {wall / 60:.1f} min on '
              + (f'the Dask cluster at {address}.' if address else f'{args.jobs} process(es).')]
    write_markdown(args.out, lines)
    print('\n'.join(lines[-len(verdicts) - 8:]))
    return 0


if __name__ == '__main__':
    sys.exit(main())

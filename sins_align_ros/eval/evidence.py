"""Evidence cells: every fine filter on every scenario, N seeded runs, against the limits.

A cell is one (data source, scenario, filter): the filter runs through the whole
pipeline (coarse + fine, the parameters the scenario's sensors call for) on N
seeded simulations; :func:`aggregate` turns the runs into the cell's statistics
(final error mean / RMS, the analytic limit beside it, convergence time,
consistency). Cells worse than their limit are run again with one error source at
a time switched off in the data (:data:`ABLATIONS`). :func:`evidence` does all of
it; :mod:`.report` writes it as ``REPORT.md``.
"""
import math
import sys
import warnings
from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from ..align import params as prm
from .limits import alignment_limits
from ..align.params import AVAILABLE_FINE_FILTERS, MOVING_FILTERS
from ..sim.presets import alignment_params, scenario, translates
from ..units import ARCMIN, DEG
from .pool import monte_carlo
from .run import run_pipeline
from .scenarios import simulate as simulate_ours
from .stats import error_summary, mean_nees

#: report name -> parameters over the scenario's (srckf = asckf without its improvements)
FILTERS = {'reduced7': {}, 'stationary10': {}, 'stationary12': {}, 'ckf': {},
           'srckf': {'fine_filter': 'asckf', 'asckf_fading': False, 'asckf_adaptive': False},
           'asckf': {}}
FILTERS = {k: v for k, v in FILTERS.items()
           if v.get('fine_filter', k) in AVAILABLE_FINE_FILTERS}
#: scenarios of the full report; seed002_5deg/10deg and seed000_case2 differ from
#: seed002_1deg / seed000_case1 only by the misalignment the papers give the fine filter
#: directly, which the whole pipeline (coarse first) does not use
FULL_SCENARIOS = ('static_navigation', 'static_tactical', 'static_mems', 'seed002_1deg',
                  'ship_sway', 'ship_underway', 'seed000_case1', 'seed001_flight',
                  'seed003_car', 'seed004_high', 'seed004_medium', 'seed004_low')
#: report size: runs per cell, seconds of the PSINS recording (None: all) and the data
#: sources ``(source, scenario, duration or None)``, source ``sim`` (ours) or ``pyins``
MODES = {
    'full': SimpleNamespace(runs=20, psins_seconds=None, sources=(
        [('sim', n, None) for n in FULL_SCENARIOS]
        + [('pyins', 'static_navigation', None), ('pyins', 'ship_sway', None)])),
    'quick': SimpleNamespace(runs=2, psins_seconds=300.0, sources=(
        ('sim', 'static_navigation', 240.0), ('sim', 'ship_sway', 240.0),
        ('sim', 'seed000_case1', 300.0), ('pyins', 'static_navigation', 240.0))),
}
#: heading band for the convergence time when the sensors cannot gyrocompass, rad
MOTION_HEADING_BAND = 1.0 * DEG
#: a heading bias term above this means the gyro cannot find north on a still base, rad
NO_GYROCOMPASS = 0.1
#: an excess over the limit below this is not listed (the limit can be ~0 by symmetry), rad
SMALL_EXCESS = 0.1 * ARCMIN
#: heading error samples kept per run (for convergence and figures), s
SERIES_STEP = 1.0
#: first seed of the runs of a cell
FIRST_SEED = 1000


# -- one run ------------------------------------------------------------------------
def fine_filter_of(name):
    """Return the ``fine_filter`` parameter value of a report filter name."""
    return FILTERS[name].get('fine_filter', name)


def filter_extra(name):
    """Parameters of report filter ``name`` other than ``fine_filter``."""
    return {k: v for k, v in FILTERS[name].items() if k != 'fine_filter'}


def not_applicable(sc, name):
    """Reason why filter ``name`` cannot run on scenario ``sc``, or None."""
    if fine_filter_of(name) in MOVING_FILTERS:
        return None if sc.gnss is not None else 'needs GNSS'
    return 'vehicle translates (still-base model)' if translates(sc) else None


#: error sources an ablation switches off in the data (the filter is told the same as
#: before): name -> (present in the scenario?, switch it off in place)
ABLATIONS = {
    'accelerometer bias': (lambda sc: np.any(np.asarray(sc.imu.accel_bias_ug) != 0.0),
                           lambda sc: setattr(sc, 'imu', sc.imu.with_(accel_bias_ug=0.0))),
    'Gauss-Markov biases': (
        lambda sc: sc.imu.gyro_markov_dph > 0.0 or sc.imu.accel_markov_ug > 0.0,
        lambda sc: setattr(sc, 'imu', sc.imu.with_(gyro_markov_dph=0.0, accel_markov_ug=0.0))),
    'GNSS outliers': (lambda sc: sc.gnss is not None and sc.gnss.outlier_prob > 0.0,
                      lambda sc: setattr(sc, 'gnss', replace(sc.gnss, outlier_prob=0.0))),
    'GNSS noise change': (lambda sc: 'gnss_noise_profile' in sc.extra,
                          lambda sc: sc.extra.pop('gnss_noise_profile')),
    'sway': (lambda sc: sc.trajectory.sway is not None,
             lambda sc: setattr(sc, 'trajectory', replace(sc.trajectory, sway=None))),
}
#: runs per ablation (the first seeds of the cell)
ABLATION_RUNS = 5


def make_scenario(name, duration, ablation=None):
    """Build the named scenario, shortened to ``duration`` s when given, ablated if asked."""
    sc = scenario(name) if duration is None else scenario(name, duration=duration)
    if ablation is not None:
        sc.extra = dict(sc.extra)
        ABLATIONS[ablation][1](sc)
    return sc


def simulate(source, sc, seed):
    """IMU and GNSS data of one run: our simulator (``sim``) or pyins with our error models."""
    if source == 'pyins':
        from .pyins_sim import simulate_with_pyins
        return simulate_with_pyins(sc, seed)
    return simulate_ours(sc, seed)


def evaluate(sc, data, name):
    """Run filter ``name`` through the pipeline on ``data``; errors against its truth.

    Returns a dict: ``err`` (final Euler error), ``sigma``, ``phi`` (final ENU
    misalignment), ``nees``, the heading error series (``series_t``, ``series_phi``,
    ``series_sig``, every :data:`SERIES_STEP` s), ``speed``, ``restarts``, ``t_fine``
    and the final ``phase``.
    """
    run = run_pipeline(alignment_params(sc, fine_filter_of(name), **filter_extra(name)), data)
    out = run.out
    step = max(1, int(round(SERIES_STEP * sc.imu_rate_hz)))
    keep = np.arange(step - 1, len(out.t), step)
    fe = run.final
    return {'speed': run.speed, 'restarts': run.restarts, 't_fine': run.t_fine,
            'series_t': out.t[keep], 'series_phi': run.phi(keep),
            'series_sig': out.sigma[keep, 2], 'phase': str(out.phase[-1]),
            'err': fe.euler, 'sigma': fe.sigma, 'phi': fe.phi, 'nees': fe.nees}


def run_job(job):
    """Worker: simulate a job ``(source, scenario, duration, seed, filters[, ablation])``, run it.

    With an ablation the data lack one error source; the filters get the parameters of
    the full scenario, so the difference is that source's share of the error.
    Returns ``((source, scenario, ablation), {filter: run dict with its seed})``.
    """
    source, name, duration, seed, filters, ablation = (tuple(job) + (None,))[:6]
    sc = make_scenario(name, duration)
    data = simulate(source, make_scenario(name, duration, ablation), seed)
    res = {f: {**evaluate(sc, data, f), 'seed': seed} for f in filters}
    return (source, name, ablation), res


def run_all(jobs, procs):
    """Run ``jobs`` (:func:`run_job`) with a progress bar.

    Returns ``{(source, name, ablation): {filter: [run dicts]}}``, runs in job order.
    """
    per_run = {}
    for key, res in monte_carlo(run_job, jobs, procs):
        for f, r in res.items():
            per_run.setdefault(key, {}).setdefault(f, []).append(r)
    return per_run


# -- aggregation ----------------------------------------------------------------------
def limits_of(sc, name):
    """Return the expected final error per ENU axis (rad), the heading band and a note.

    Still-base limit (``eval.limits``, seed 002 eq. 15) with the biases projected at
    the final attitude: bias term and IMU noise term over the fine time (duration
    minus coarse time), plus, for the GNSS-aided filters, the heading noise of the
    GNSS velocity reference (``velocity_reference_heading_noise``; a still base's
    zero velocity is exact); expected RMS = root sum of squares.
    """
    cfg = {**prm.defaults(), **alignment_params(sc, fine_filter_of(name))}
    T = max(sc.duration - cfg['coarse_duration'], 1.0)
    band = alignment_limits(sc, T, fine_filter_of(name), t_att=sc.duration)
    expected = np.hypot(band.bias, band.noise)
    if band.bias[2] > NO_GYROCOMPASS:
        expected[2] = math.nan
        return expected, MOTION_HEADING_BAND, 'cannot gyrocompass: heading only from motion'
    return expected, band.tolerance()[2], None


def convergence_time(series_t, phi_u, band):
    """Time after which ``|phi_u| <= band`` for good (inf if it ends outside), s."""
    bad = ~(np.abs(phi_u) <= band)
    if bad[-1]:
        return math.inf
    idx = np.flatnonzero(bad)
    return float(series_t[0]) if len(idx) == 0 else float(series_t[idx[-1] + 1])


def worse_axes(c):
    """Axes (index, label) whose RMS is over 1.5x the limit and more than 0.1' above it."""
    return [(ax, label) for ax, label in ((2, 'heading'), (0, 'east tilt'), (1, 'north tilt'))
            if np.isfinite(c.expected[ax]) and c.rms_enu[ax] > 1.5 * c.expected[ax]
            and c.rms_enu[ax] - c.expected[ax] > SMALL_EXCESS]


def flagged(c):
    """Tell whether a cell is worse than its limit or its sigma does not cover its error."""
    return bool(worse_axes(c)) or c.failed > 0 or (
        np.nanmin(c.inside) < 0.9 if np.any(np.isfinite(c.inside)) else True) or c.nees > 9.0


def aggregate(sc, name, runs):
    """Statistics of one (scenario, filter) cell from its per-run results."""
    expected, band, note = limits_of(sc, name)
    err = np.array([r['err'] for r in runs])
    ok = np.all(np.isfinite(err), axis=1)
    e, sig = err[ok], np.array([r['sigma'] for r in runs])[ok]
    phi = np.array([r['phi'] for r in runs])[ok]
    summary = error_summary(e, sig)
    conv = [convergence_time(r['series_t'], r['series_phi'][:, 2], band) for r in runs]
    with warnings.catch_warnings():         # all-NaN columns: before coarse alignment ends
        warnings.simplefilter('ignore', RuntimeWarning)
        phi_u = np.array([r['series_phi'][:, 2] for r in runs])
        series_rms = np.sqrt(np.nanmean(phi_u ** 2, axis=0))
        series_sig = np.nanmean(np.array([r['series_sig'] for r in runs]), axis=0)
    return SimpleNamespace(
        runs=len(runs), failed=int(np.sum(~ok)), restarts=sum(r['restarts'] for r in runs),
        mean=summary.mean, rms=summary.rms,
        rms_enu=error_summary(phi, sig).rms, sigma=summary.sigma, inside=summary.inside,
        nees=mean_nees([r['nees'] for r in runs]),
        conv=float(np.median(conv)), conv_frac=float(np.mean(np.isfinite(conv))),
        speed=float(np.median([r['speed'] for r in runs])),
        expected=expected, band=band, note=note,
        t_fine=float(np.nanmedian([r['t_fine'] for r in runs])),
        series_t=runs[0]['series_t'], series_rms=series_rms, series_sig=series_sig)


def why_worse(sc, name, cell):
    """Measured reason why a cell's heading (or tilt) RMS is above its expected limit."""
    reasons = []
    if fine_filter_of(name) not in MOVING_FILTERS and not np.allclose(
            sc.trajectory.kinematics(np.linspace(0, 60, 61)).euler,
            sc.trajectory.kinematics(0.0).euler):
        reasons.append('the base sways: the still-base model takes sway and heave velocity '
                       'for errors')
    ratio_sig = cell.sigma[2] / cell.expected[2]
    if np.isfinite(ratio_sig) and ratio_sig > 1.5:
        reasons.append(f'not converged in the time available: its own final yaw sigma is '
                       f'{ratio_sig:.1f}x the limit')
    if np.isfinite(cell.nees) and cell.nees > 9.0:
        reasons.append(f'over-confident (NEES {cell.nees:.1f}): the error exceeds its sigma')
    if fine_filter_of(name) in MOVING_FILTERS and not translates(sc):
        reasons.append('GNSS-aided model on a base that does not translate: heading is '
                       'gyrocompassed through GNSS position/velocity noise (m, cm/s) instead '
                       'of the still-base models\' 0.01 m/s zero-velocity update')
    return '; '.join(reasons) or 'not identified'


# -- the whole evidence ---------------------------------------------------------------
def evidence(mode, runs=None, procs=None):
    """Run every cell of ``mode`` (a :data:`MODES` entry) and the ablations of the flagged ones.

    ``runs`` per cell (default: the mode's), over ``procs`` processes (default: the
    machine's cores). Returns a namespace: ``runs``; ``cells``
    ``{(source, scenario): {filter: cell}}``; ``skipped``
    ``{(source, scenario): {filter: reason}}``; ``ablated``
    ``{(source, scenario, filter): {ablation: (ablated cell, same seeds without)}}``.
    """
    runs = runs or mode.runs
    jobs, skipped = [], {}
    for source, name, duration in mode.sources:
        sc = make_scenario(name, duration)
        filters = []
        for f in FILTERS:
            why = not_applicable(sc, f)
            if why:
                skipped.setdefault((source, name), {})[f] = why
            else:
                filters.append(f)
        jobs += [(source, name, duration, FIRST_SEED + k, tuple(filters)) for k in range(runs)]
    per_run = run_all(jobs, procs)
    cells = {}
    for source, name, duration in mode.sources:
        sc = make_scenario(name, duration)
        cells[(source, name)] = {f: aggregate(sc, f, rs) for f, rs in
                                 per_run.get((source, name, None), {}).items()}
    # second pass: each cell worse than its limit or over-confident, with one error
    # source at a time switched off in the data
    abl_jobs = []
    for source, name, duration in mode.sources:
        bad = tuple(f for f, c in cells[(source, name)].items() if flagged(c))
        if source != 'sim' or not bad:
            continue
        sc = make_scenario(name, duration)
        for a, (present, _) in ABLATIONS.items():
            if present(sc):
                abl_jobs += [(source, name, duration, FIRST_SEED + k, bad, a)
                             for k in range(min(ABLATION_RUNS, runs))]
    print(f'ablations: {len(abl_jobs)} runs', file=sys.stderr, flush=True)
    abl_runs = run_all(abl_jobs, procs)
    ablated = {}
    durations = dict((s[1], s[2]) for s in mode.sources)
    for (source, name, a), row in abl_runs.items():
        sc = make_scenario(name, durations[name])
        for f, rs in row.items():
            base = [r for r in per_run[(source, name, None)][f]
                    if r['seed'] in {x['seed'] for x in rs}]
            ablated.setdefault((source, name, f), {})[a] = (aggregate(sc, f, rs),
                                                            aggregate(sc, f, base))
    return SimpleNamespace(runs=runs, cells=cells, skipped=skipped, ablated=ablated)

"""Integrity of a published attitude sigma over seeded runs (issue 21's matrix).

The published claim is the misalignment covariance about the ENU axes (``P_phi``, the
``orientation_covariance`` of ``imu/data``): on every axis the real error must lie
inside 3 sigma. Per run (:func:`run_integrity`), from the output rows and the truth:

- the **1-s samples after coarse alignment**: every ``rate`` th row from the first
  fine row on, where the output has an attitude (rows of a restart back in coarse
  alignment publish no attitude and are not samples);
- an axis is **published** at a sample unless its variance is that of an unknown
  angle (``pi^2/3``, :data:`~sins_align_ros.align.output.HEADING_UNKNOWN_VAR`):
  a heading declared unknown claims nothing;
- **silent wrong** (:func:`silent_wrong`): on some published axis more than 5 % of
  the samples outside 3 sigma, or any sample beyond 5 sigma;
- **ended inside** (:func:`inside_at_end`): the last row inside 3 sigma on every
  published axis.

Per cell (:func:`cell_stats`): runs, the share that ended inside 3 sigma (of the runs
with an attitude at the end), the silent-wrong count, the final RMS error per ENU axis
against the analytic limit, the sharpness (mean reported sigma at the end / RMS error)
and the share of runs ending ``aligned``; :func:`verdict` applies issue 21's rules.

Sharpness is judged against the larger of the RMS error and :func:`spec_limit`: the
simulated biases are the same constants in every run, and projected on the ENU axes
they can nearly cancel (north tilt at heading 45 deg, equal biases on every axis), so
that the error of a consistent filter is far below its 1-sigma; a sigma is called
uselessly wide only when it is more than 3x what the sensors' 1-sigma biases allow.
"""
from types import SimpleNamespace

import numpy as np

from ..align import HEADING_UNKNOWN_VAR
from .limits import alignment_limits
from ..align.params import defaults
from ..nav import earth
from ..units import DEG, DPH, UG
from .stats import rms

#: sigma multiple of the claim, and of a sample no consistent filter should ever show
K_INSIDE, K_SILENT = 3.0, 5.0
#: share of a run's samples allowed outside ``K_INSIDE`` sigma on an axis
MAX_OUTSIDE = 0.05
#: share of a cell's runs that must end inside ``K_INSIDE`` sigma
MIN_ENDED_INSIDE = 0.95
#: largest mean sigma / RMS error where the error is at the limit
MAX_SHARPNESS = 3.0
#: "at the limit": RMS error at most this factor above the analytic limit
AT_LIMIT = 1.5
#: a variance at least this share of an unknown angle's is not a published sigma
UNKNOWN_SHARE = 0.999


def published_sigma(P_phi):
    """1-sigma per ENU axis (..., 3) of covariances ``P_phi`` (..., 3, 3); NaN where unknown.

    An axis whose variance is (capped at) that of an angle anywhere in a circle,
    ``pi^2/3``, publishes no sigma.
    """
    var = np.diagonal(np.asarray(P_phi, dtype=float), axis1=-2, axis2=-1)
    sig = np.sqrt(np.maximum(var, 0.0))
    return np.where(var >= UNKNOWN_SHARE * HEADING_UNKNOWN_VAR, np.nan, sig)


def outside_shares(err, sigma, k=K_INSIDE):
    """Share of samples per axis with ``|err| > k sigma`` (3,), over published samples only.

    ``err``, ``sigma`` (n, 3); a NaN sigma (unpublished) or error (no attitude) is not
    a sample of that axis; NaN where an axis has none.
    """
    e, s = np.asarray(err, float), np.asarray(sigma, float)
    ok = np.isfinite(e) & np.isfinite(s)
    n = ok.sum(axis=0)
    out = (ok & (np.abs(np.where(ok, e, 0.0)) > k * np.where(ok, s, 0.0))).sum(axis=0)
    with np.errstate(invalid='ignore', divide='ignore'):
        return np.where(n > 0, out / np.maximum(n, 1), np.nan)


def silent_wrong(err, sigma, k=K_INSIDE, max_share=MAX_OUTSIDE, k_max=K_SILENT):
    """Tell whether a run's samples are silently wrong; return ``(bool, reason)``.

    Silent wrong: on some published axis more than ``max_share`` of the samples are
    outside ``k`` sigma, or a sample is beyond ``k_max`` sigma. ``reason`` names the
    axis and rule ('' when the run is not silently wrong).
    """
    e, s = np.asarray(err, float), np.asarray(sigma, float)
    share = outside_shares(e, s, k)
    worst = outside_shares(e, s, k_max)
    for ax, name in enumerate('ENU'):
        if share[ax] > max_share:
            return True, f'{name}: {share[ax]:.0%} of samples outside {k:g} sigma'
        if worst[ax] > 0.0:
            return True, f'{name}: a sample beyond {k_max:g} sigma'
    return False, ''


def inside_at_end(err, sigma, k=K_INSIDE):
    """Tell whether a final error (3,) is inside ``k`` sigma on every published axis.

    None when there is no attitude at the end (error NaN).
    """
    e, s = np.asarray(err, float), np.asarray(sigma, float)
    if not np.all(np.isfinite(e)):
        return None
    pub = np.isfinite(s)
    return bool(np.all(np.abs(e[pub]) <= k * s[pub]))


def sample_rows(out, rate):
    """Output rows of the 1-s samples after coarse alignment (every ``rate`` th from fine on)."""
    fine = np.flatnonzero(np.isin(out.phase, ('fine', 'aligned')))
    if not len(fine):
        return np.zeros(0, dtype=int)
    rows = np.arange(fine[0], len(out.t), max(1, int(round(rate))))
    return rows[np.isfinite(out.q[rows, 3])]


def run_integrity(run, rate):
    """Integrity figures of one :class:`~.run.Run` (output rows at ``rate`` Hz).

    Returns a dict: ``silent`` (bool) and ``why``; ``end_err`` and ``end_sigma`` (3,)
    ENU misalignment and published sigma at the last row (NaN without an attitude,
    sigma NaN where unpublished); ``end_inside`` (bool or None); ``phase`` of the last
    row; ``n_samples``; ``heading_unknown`` (the last row declares the heading unknown);
    ``outside`` (3,) share of samples outside 3 sigma per axis.
    """
    out = run.out
    rows = sample_rows(out, rate)
    err = run.phi(rows)
    sig = published_sigma(out.P_phi[rows])
    silent, why = silent_wrong(err, sig)
    last = np.array([len(out.t) - 1])
    end_err = run.phi(last)[0]
    end_sig = published_sigma(out.P_phi[-1])
    if not np.all(np.isfinite(end_err)):
        end_sig = np.full(3, np.nan)
    return {'silent': silent, 'why': why, 'end_err': end_err, 'end_sigma': end_sig,
            'end_inside': inside_at_end(end_err, end_sig), 'phase': str(out.phase[-1]),
            'n_samples': int(len(rows)),
            'heading_unknown': bool(np.isfinite(end_err[2]) and np.isnan(end_sig[2])),
            'outside': outside_shares(err, sig)}


def cell_stats(runs, limit, spec=None):
    """Statistics of one cell from :func:`run_integrity` dicts and the ENU ``limit`` (3,), rad.

    ``spec``: :func:`spec_limit` (3,) rad, or None (sharpness then judged against the RMS
    error alone).

    Returns a namespace: ``runs``; ``with_attitude`` (runs with an attitude at the end);
    ``ended_inside`` (share of those inside 3 sigma on every published axis, NaN
    without any); ``silent`` (count) and ``silent_why`` (first reasons); ``rms`` (3,)
    final RMS error; ``limit``; ``sigma`` (3,) mean published sigma at the end (NaN
    for an axis no run publishes); ``sharpness`` (3,) ``sigma / rms``; ``aligned``
    (share of runs ending ``aligned``); ``heading_unknown`` (runs ending with the
    heading declared unknown); ``refused`` (runs refused by the filter, when the dicts
    carry ``refused``).
    """
    n = len(runs)
    end = np.array([r['end_err'] for r in runs]).reshape(n, 3)
    sig = np.array([r['end_sigma'] for r in runs]).reshape(n, 3)
    has = np.all(np.isfinite(end), axis=1)
    inside = [r['end_inside'] for r in runs if r['end_inside'] is not None]
    e = end[has]
    err_rms = rms(e) if len(e) else np.full(3, np.nan)
    with np.errstate(invalid='ignore', divide='ignore'):
        s = np.array([np.nanmean(col) if np.any(np.isfinite(col)) else np.nan
                      for col in sig[has].T]) if len(e) else np.full(3, np.nan)
        sharp = s / err_rms
    return SimpleNamespace(
        runs=n, with_attitude=int(has.sum()),
        ended_inside=float(np.mean(inside)) if inside else float('nan'),
        silent=int(sum(r['silent'] for r in runs)),
        silent_why=[r['why'] for r in runs if r['silent']][:3],
        rms=err_rms, limit=np.asarray(limit, float), sigma=s, sharpness=sharp,
        spec=np.full(3, np.nan) if spec is None else np.asarray(spec, float),
        aligned=float(np.mean([r['phase'] == 'aligned' for r in runs])) if n else float('nan'),
        heading_unknown=int(sum(r['heading_unknown'] for r in runs)),
        refused=int(sum(r.get('refused', False) for r in runs)))


def spec_limit(sc, fine_filter, coarse_duration=None):
    """RMS error per ENU axis (3,) a consistent filter may show, biases at their full 1 sigma.

    The evidence limit (:func:`~sins_align_ros.eval.limits.alignment_limits`, seed 002
    eq. 15) projects the scenario's actual bias vectors on the ENU axes; here each bias
    term is its unprojected magnitude (accelerometer constant and Gauss-Markov bias /
    g for tilt, gyro constant and Gauss-Markov bias / (W cos L) for heading), the
    noise terms unchanged: ``sqrt(bias^2 + noise^2)``.
    """
    cd = defaults()['coarse_duration'] if coarse_duration is None else coarse_duration
    T = max(sc.duration - cd, 1.0)
    band = alignment_limits(sc, T, fine_filter, t_att=sc.duration)
    lat = sc.trajectory.lat_deg * DEG
    g = earth.gravity(lat, sc.trajectory.h)
    imu = sc.imu
    acc = np.hypot(np.max(np.abs(imu.accel_bias_ug)), imu.accel_markov_ug) * UG / g
    gyro = (np.hypot(np.max(np.abs(imu.gyro_bias_dph)), imu.gyro_markov_dph) * DPH
            / (earth.OMEGA_IE * np.cos(lat)))
    return np.hypot(np.array([acc, acc, gyro]), band.noise)


def judged_sharpness(c):
    """Mean published sigma / max(RMS error, spec limit) per axis (3,), where it is judged.

    Judged (else NaN): the limit is finite (the gyro can find north) and the error is
    at the limit, RMS at most :data:`AT_LIMIT` x max(limit, spec limit).
    """
    spec = getattr(c, 'spec', np.full(3, np.nan))
    ref = np.fmax(c.rms, spec)
    with np.errstate(invalid='ignore', divide='ignore'):
        ok = np.isfinite(c.limit) & (c.rms <= AT_LIMIT * np.fmax(c.limit, spec))
        return np.where(ok, c.sigma / ref, np.nan)


def verdict(c):
    """Issue 21's rules on a cell: ``(ok, text)``.

    Fails: a silent-wrong run; fewer than 95 % of the runs with an attitude at the end
    inside 3 sigma; a judged sharpness (:func:`judged_sharpness`) above 3. Not
    failures, said as such: every run refused by the filter; no run with an attitude
    at the end; the heading declared unknown.
    """
    if c.runs and c.refused == c.runs:
        return True, 'refused (correctly: stationary model on a moving base)'
    fails = []
    if c.silent:
        fails.append(f'{c.silent} silent-wrong')
    if c.with_attitude and c.ended_inside < MIN_ENDED_INSIDE:
        fails.append(f'ended inside 3 sigma {c.ended_inside:.0%}')
    judged = judged_sharpness(c)
    sharp = judged > MAX_SHARPNESS
    if np.any(sharp):
        fails.append('sigma too wide: ' + ', '.join(f'{"ENU"[ax]} {judged[ax]:.1f}x'
                                                    for ax in np.flatnonzero(sharp)))
    notes = []
    if not c.with_attitude:
        notes.append('no attitude at the end')
    elif c.with_attitude < c.runs:
        notes.append(f'{c.runs - c.with_attitude} without attitude at the end')
    if c.refused and c.refused < c.runs:
        notes.append(f'{c.refused} refused')
    if c.heading_unknown:
        notes.append('heading declared unknown' + (
            '' if c.heading_unknown == c.with_attitude else f' in {c.heading_unknown}'))
    with np.errstate(invalid='ignore', divide='ignore'):
        worse = np.isfinite(c.limit) & (c.rms > AT_LIMIT * c.limit)
    if np.any(worse):
        notes.append('RMS > 1.5x limit: ' + ''.join('ENU'[ax] for ax in np.flatnonzero(worse)))
    text = ('FAIL: ' + '; '.join(fails) if fails else 'ok') + (
        f' ({"; ".join(notes)})' if notes else '')
    return not fails, text

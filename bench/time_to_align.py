"""Time to ``aligned`` and its steadiness (issue 46): when it comes, how often it is left.

For each scenario and filter, over seeded runs with the parameters that describe the
scenario's sensors (``sim.presets.alignment_params``; the thresholds are the node's
defaults): the time of the first ``aligned`` row (s from the first IMU sample), the
number of ``aligned`` -> ``fine`` switches in the run, whether the run ends ``aligned``,
and the share of ``aligned`` rows whose error lies inside 3 sigma (worst axis: the ENU
misalignment against the published roll, pitch and yaw 1-sigma).

Usage: python bench/time_to_align.py [--runs 10] [--jobs 2] [--out bench/results/time_to_align.md]
"""
import argparse
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
# this checkout's package, not install/'s copy: that one looks for ../shared/data beside
# install/ and found no fog_mems recording (session 47's run lost its fog rows so)
sys.path.insert(0, str(ROOT))

from sins_align_ros.eval.errors import attitude_errors  # noqa: E402
from sins_align_ros.eval.run import run_scenario  # noqa: E402
from sins_align_ros.eval.scenarios import named  # noqa: E402
from sins_align_ros.eval.pool import monte_carlo  # noqa: E402
from sins_align_ros.align.params import MOVING_FILTERS  # noqa: E402
from sins_align_ros.eval.limits import (alignment_limits, gnss_heading_bound,  # noqa: E402
                                        scenario_limits, sways_in_place)
from sins_align_ros.nav import earth  # noqa: E402
from sins_align_ros.sim.presets import scenario, starting_still, translates  # noqa: E402

#: (scenario, filter, what it is)
CASES = (
    ('car_rtk', 'auto', 'MEMS car, RTK, still 30 s then driving'),
    ('car_rtk_rest90', 'auto', 'the same car still 90 s (a still-base filter runs when it '
     'drives)'),
    ('car_consumer', 'auto', 'MEMS car, consumer receiver'),
    ('seed003_car@mems', 'kf', "seed 003's car with a MEMS IMU"),
    ('ship_underway', 'asckf', 'navigation-grade ship under way'),
    ('seed004_medium', 'vbckf', "seed 004's USV, medium sea"),
    ('ship_sway', 'auto', 'moored swaying ship (still-base filter)'),
    ('still_nav_35', 'auto', 'still navigation-grade base at 35 deg N'),
    ('still_nav_60', 'auto', 'still navigation-grade base at 60 deg N'),
    # the GNSS-aided stage started at the window's end (coarse_reprocess_aided false: the
    # default until session 47)
    ('car_rtk+window_end', 'auto', 'car_rtk, the aided stage from the window\'s end'),
    ('car_consumer+window_end', 'auto', 'car_consumer, the aided stage from the window\'s end'),
    ('ship_underway+window_end', 'asckf', 'ship_underway, the aided stage from the window\'s '
     'end'),
    ('seed004_medium+window_end', 'vbckf', 'seed004_medium, the aided stage from the '
     'window\'s end'),
    # the vertical drift left unmeasured at rest (zero_rate_at_rest false: the flow until
    # session 50)
    ('car_rtk+no_zero_rate', 'auto', 'car_rtk without the zero-rate epochs at rest'),
    ('car_rtk+no_zero_rate', 'asckf', 'car_rtk without the zero-rate epochs at rest'),
    ('car_rtk', 'asckf', 'MEMS car, RTK, still 30 s then driving'),
)
#: a case name's suffix -> the parameters it adds
VARIANTS = {'window_end': {'coarse_reprocess_aided': False},
            'no_zero_rate': {'zero_rate_at_rest': False}}
#: seconds after the motion's start at which the heading is judged (issue 46: the MEMS car
#: with RTK that stands still, then drives, has its heading inside 1 deg and covered 15 s
#: after it starts)
AFTER_MOTION_S = 15.0
FIRST_SEED = 1000
#: scenarios built here (hard cases of issue 46), by name
BUILT = {'car_rtk_rest90': lambda: starting_still(scenario('car_rtk'), 60.0),
         'still_nav_35': lambda: _still_navigation(35.0),
         'still_nav_60': lambda: _still_navigation(60.0)}


def _still_navigation(lat):
    """Return a still, level navigation-grade IMU at ``lat`` deg N, 120 s."""
    sc = scenario('static_navigation', duration=120.0)
    sc.trajectory.lat_deg = lat
    sc.name = f'static_navigation_{lat:g}'
    return sc


def heading_limit(sc, t, sway=None):
    """Return the analytic heading limit (rad) of a still base after ``t`` (s) of data.

    The band of issue 3 (``eval.limits.scenario_limits``): 1.2 x the heading error the
    east gyro bias leaves plus 3 x the noise term over ``t`` (N,): the angle random walk's
    over the horizontal Earth rate on a still base (seed 002 eq. 15), the issue-46 limit;
    on a base that sways in place (``sway`` None: decided from ``sc``) the accelerometers'
    route with it (``eval.limits.sway_heading_noise``: its gyros cannot tell the Earth
    rate from the sway); ``sway=False``: the still base's whatever the scenario.
    """
    band = scenario_limits(sc, np.maximum(np.asarray(t, float), 1e-3), sway=sway)
    return 1.2 * band.bias[2] + 3.0 * band.noise[2]


def ship_bound(sigma60=None, threshold_deg=2.0):
    """Return a sentence: the heading the ship's GNSS allows over its straight first minute.

    ``eval.limits.gnss_heading_bound`` with the scenario's receiver (positions and
    velocities, white): no estimator without a heading prior beats it; ``aligned`` with
    the default heading threshold needs the 1-sigma at ``threshold_deg``. ``sigma60``: the
    runs' heading 1-sigma at 60 s (deg, (N,)), or None.
    """
    sc = named('ship_underway', None)
    lat = np.radians(sc.trajectory.lat_deg)
    g = earth.gravity(lat, sc.trajectory.h)
    gs = sc.gnss

    def bound(T):
        return np.degrees(gnss_heading_bound(gs.pos_sigma_h, gs.vel_sigma, gs.rate_hz, T, lat, g))
    return (f'**The ship under way cannot be `aligned` by 60 s**: it runs straight at constant '
            f'speed until 60 s, when it starts to accelerate at 0.05 m/s^2. From GNSS alone '
            f'({gs.pos_sigma_h:g} m, {gs.vel_sigma:g} m/s at {gs.rate_hz:g} Hz) no estimator '
            f'has its heading 1-sigma under {bound(60.0):.1f} deg at 60 s (the Cramer-Rao '
            f'bound of eval.limits.gnss_heading_bound; with the GNSS track\'s {10:g}-deg '
            f'heading prior {1.0 / np.hypot(1.0 / bound(60.0), 0.1):.1f} deg), against the '
            f'default {threshold_deg:g}-deg threshold'
            + ('.' if sigma60 is None else
               f'; `asckf` publishes {_span(sigma60)} deg there, then {threshold_deg:g} deg '
               f'about 10 s into the acceleration (the "aligned at" column).'))


def sc_of(name):
    """Return the scenario of a case name (its ``+variant`` suffix left off)."""
    scen = name.partition('+')[0]
    return BUILT[scen]() if scen in BUILT else named(scen, None)


def one(job):
    """Run a (scenario, filter, seed) job; return its figures."""
    scen, filt, seed = job
    scen, _, variant = scen.partition('+')
    sc = sc_of(scen)
    run = run_scenario(sc, seed, filt, cached=True, **VARIANTS.get(variant, {}))
    t = run.out.t - run.data.imu.t[0]
    al = np.asarray(run.out.phase) == 'aligned'
    idx = np.flatnonzero(al)
    inside = in_limit = in_still_limit = np.nan
    if len(idx):
        err = attitude_errors(run.out, run.truth_euler, idx)
        inside = float(np.min(np.mean(np.abs(err) <= 3.0 * run.out.sigma[idx], axis=0)))
        if not translates(sc):          # a still or moored base: its analytic limit
            in_limit = float(np.mean(np.abs(err[:, 2]) <= heading_limit(sc, t[idx])))
            in_still_limit = float(np.mean(np.abs(err[:, 2])
                                           <= heading_limit(sc, t[idx], sway=False)))
    # the motion's start (truth speed above 0.2 m/s) and, after it, the time from which
    # the heading stays inside 1 deg and inside its 3 sigma
    speed = np.linalg.norm(run.data.imu.v_n[run.rows][:, :2], axis=1)
    moving = np.flatnonzero(speed > 0.2)
    t_move = float(t[moving[0]]) if len(moving) else np.nan
    e_up = np.abs(attitude_errors(run.out, run.truth_euler, np.arange(len(t)))[:, 2])

    def good_from(band):
        """Return the time from which the heading stays inside ``band`` (rad) and 3 sigma.

        ``band``: a bound, or one per row (N,).
        """
        bad = np.flatnonzero(~((e_up <= band) & (e_up <= 3.0 * run.out.sigma[:, 2])))
        return float(t[bad[-1] + 1]) if len(bad) and bad[-1] + 1 < len(t) else (
            float(t[0]) if not len(bad) else np.nan)

    # a moving base: 3' or the aided limit for the data seen, if that is wider (issue 46's
    # ship under way; eval.limits.alignment_limits, the heading a velocity reference leaves
    # a base that does not manoeuvre)
    t_aided_limit = np.nan
    if translates(sc):
        aided = filt if filt in MOVING_FILTERS else 'kf'
        secs = np.arange(1, int(t[-1]) + 2)
        tol = np.array([alignment_limits(sc, float(T), aided).tolerance()[2] for T in secs])
        band = np.maximum(np.radians(3.0 / 60.0),
                          np.interp(np.maximum(t, 1.0), secs, tol))
        t_aided_limit = good_from(band)
    i60 = min(int(np.searchsorted(t, 60.0)), len(t) - 1)
    after = np.nan, np.nan
    if len(moving):
        i = min(int(np.searchsorted(t, t_move + AFTER_MOTION_S)), len(t) - 1)
        after = float(e_up[i]), float(run.out.sigma[i, 2])
    return dict(t_aligned=float(t[idx[0]]) if len(idx) else np.nan, after=after,
                sigma60=float(np.degrees(run.out.sigma[i60, 2])),
                switches=int(np.sum(al[:-1] & ~al[1:])), end_aligned=bool(al[-1]),
                inside=inside, in_limit=in_limit, in_still_limit=in_still_limit,
                t_move=t_move,
                t_heading=good_from(np.radians(1.0)),
                t_heading_3am=good_from(np.radians(3.0 / 60.0)), t_aided_limit=t_aided_limit)


#: the fog_mems car recording (../shared/data): what it is run with
FOG_CASES = (('node defaults', {}), ('fog parameters (auto)', 'FOG'),
             ('fog parameters, asckf', 'FOG_ASCKF'),
             ('node defaults, aided stage from the window\'s end',
              {'coarse_reprocess_aided': False}),
             ('fog parameters (auto), from the window\'s end', 'FOG_WINDOW_END'),
             ('fog parameters, asckf, from the window\'s end', 'FOG_ASCKF_WINDOW_END'))


def fog_rows():
    """Table rows of the real fog_mems car: time to ``aligned`` and its steadiness.

    Time from the first IMU sample; "inside": the share of the 1-Hz ``aligned`` samples
    whose error against the FOG reference is inside 3 sigma + 0.3 deg on every axis (the
    mounting, as bench/defaults.py). Returns [] without the recording.
    """
    from types import SimpleNamespace
    from sins_align_ros.eval.recordings import FOG_PARAMS, read_fog
    from sins_align_ros.eval.run import run_pipeline
    from sins_align_ros.nav.frames import attitude_error, quat_to_dcm
    rec = read_fog(None)
    if rec is None:
        return []
    data = SimpleNamespace(imu=rec.imu_like(), gnss=rec.gnss_like())
    named = {'FOG': dict(FOG_PARAMS), 'FOG_ASCKF': {**FOG_PARAMS, 'fine_filter': 'asckf'}}
    named.update({k + '_WINDOW_END': {**v, 'coarse_reprocess_aided': False}
                  for k, v in list(named.items())})
    rows = []
    for name, params in FOG_CASES:
        params = named.get(params, params) if isinstance(params, str) else params
        out = run_pipeline(params, data, use_velocity=True, t0=rec.t[0] - 0.01).out
        ph = np.asarray(out.phase)
        al = ph == 'aligned'
        t = out.t - rec.t[0]
        ins = []
        for k in np.flatnonzero(al)[::100]:
            j = int(np.argmin(np.abs(rec.ref_t - out.t[k])))
            e = np.degrees(attitude_error(quat_to_dcm(out.q[k]), rec.ref_C[j]))
            ins.append(np.all(np.abs(e) <= 3.0 * np.degrees(np.sqrt(np.diag(out.P_phi[k])))
                              + 0.3))
        first = f'{t[al][0]:.1f}' if al.any() else '-'
        inside = f'{100 * np.mean(ins):.0f}%' if ins else '-'
        sig = np.degrees(np.sqrt(np.diag(out.P_phi[-1])))
        rows.append(f'| fog_mems | {name} | {first} | {int(np.sum(al[:-1] & ~al[1:]))} | '
                    f'{ph[-1]} | {sig[0]:.2f} / {sig[1]:.2f} / {sig[2]:.2f} | {inside} |')
    return rows


def _span(x):
    """Median (range) of the finite values of ``x``, '-' if none."""
    x = np.asarray(x)[np.isfinite(x)]
    return f'{np.median(x):.1f} ({np.min(x):.1f}-{np.max(x):.1f})' if len(x) else '-'


def main():
    """Run the cases and write the page."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--runs', type=int, default=10)
    ap.add_argument('--jobs', type=int, default=1)
    ap.add_argument('--out', default='bench/results/time_to_align.md')
    ap.add_argument('--cases', default=None,
                    help='comma-separated case names (e.g. car_consumer,ship_underway); '
                         'default all')
    ap.add_argument('--fog-only', action='store_true',
                    help='print the fog_mems rows only (e.g. with PYTHONPATH at an older '
                         'checkout, for a before/after)')
    args = ap.parse_args()
    if args.fog_only:
        print('\n'.join(fog_rows()))
        return 0
    cases = CASES if args.cases is None else tuple(
        c for c in CASES if c[0] in args.cases.split(','))
    jobs = [(s, f, FIRST_SEED + k) for s, f, _ in cases for k in range(args.runs)]
    w0 = time.perf_counter()
    res = monte_carlo(one, jobs, args.jobs)
    rows, sigma60 = [], None
    for i, (scen, filt, what) in enumerate(cases):
        rs = res[i * args.runs:(i + 1) * args.runs]
        ta = np.array([r['t_aligned'] for r in rs])
        sw = np.array([r['switches'] for r in rs])
        ins = np.array([r['inside'] for r in rs])
        ok = np.isfinite(ta)
        tm = np.array([r['t_move'] for r in rs])
        th = np.array([r['t_heading'] for r in rs])
        th3 = np.array([r['t_heading_3am'] for r in rs])
        tal = np.array([r['t_aided_limit'] for r in rs])
        if (scen, filt) == ('ship_underway', 'asckf'):
            sigma60 = [r['sigma60'] for r in rs]
        lim = np.array([r['in_limit'] for r in rs])
        slim = np.array([r['in_still_limit'] for r in rs])
        e15, s15 = np.array([r['after'] for r in rs]).T
        good15 = (np.isfinite(e15) & (e15 <= np.radians(1.0))
                  & (e15 <= 3.0 * s15))
        after = (f'{good15.sum()}/{len(rs)}; {np.degrees(np.nanmedian(e15)):.2f} / '
                 f'{np.degrees(np.nanmedian(s15)):.2f}' if np.isfinite(e15).any() else '-')
        rows.append(f'| {scen} | {filt} | {what} | {ok.sum()}/{len(rs)} | {_span(ta)} | '
                    f'{_span(tm)} | {after} | {_span(th)} | {_span(th3)} | {_span(tal)} | '
                    f'{sw.max()} ({sw.sum()}) | '
                    f'{sum(r["end_aligned"] for r in rs)} | '
                    + (f'{100 * np.nanmin(ins):.1f}%' if ok.any() else '-') + ' | '
                    + (f'{100 * np.nanmin(lim):.1f}% ({np.sum(lim == 1.0)}/{len(rs)})'
                       if np.isfinite(lim).any() else '-')
                    + ' | ' + (f'{100 * np.nanmin(slim):.1f}% ({np.sum(slim == 1.0)}/{len(rs)})'
                               if sways_in_place(sc_of(scen)) else '-')
                    + ' |')
    commit = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], capture_output=True,
                            text=True).stdout.strip()
    page = [
        '# Time to `aligned` and its steadiness (issue 46)', '',
        f'Command: `python bench/time_to_align.py --runs {args.runs} --jobs {args.jobs}` on '
        f'{platform.machine()}, Python {platform.python_version()}; commit {commit}; '
        f'{time.perf_counter() - w0:.0f} s.', '', ship_bound(sigma60), '',
        'Seeds from 1000; the parameters describe the scenario\'s sensors, the thresholds '
        'are the defaults (1 deg tilt, 2 deg heading). "aligned at": median (range) of the '
        'first `aligned` row, s from the first IMU sample; "switches": most `aligned` -> '
        '`fine` switches in one run (all runs); "inside 3 sigma": the worst run\'s share of '
        '`aligned` rows with every axis inside 3 sigma; "moving from": the truth speed first '
        'above 0.2 m/s (- for a base that never moves); "15 s after": the runs whose heading '
        'error 15 s after that start is inside 1 deg and inside its 3 sigma; the median error '
        '/ median 1-sigma there (deg); "heading good from": the time from '
        'which the heading error stays inside 1 deg and inside its 3 sigma (- never); "inside 3\' '
        'from": the same with 3 arcmin (the ship under way\'s target, issue 46); "or the aided '
        'limit": the same with 3 arcmin or, where wider, the aided heading limit for the data '
        'seen (eval.limits.alignment_limits at t: 1.2 x the bias terms + 3 x the noise '
        'terms, the GNSS velocity reference\'s included; issue 46 allows it for the ship), '
        'on a moving base; '
        '"in limit": on a still or moored base, the worst run\'s share of `aligned` rows '
        'whose heading error is inside the analytic limit for the data seen so far, '
        '(1.2 x east gyro bias + 3 x ARW / sqrt(t)) / (Earth rate x cos L) on a still '
        'base, and the runs wholly inside it; on a base that sways in place the noise '
        'term is eval.limits.'
        'sway_heading_noise\'s (its gyros cannot tell the Earth rate from the sway, so the '
        'accelerometers\' route adds: 13\' at 20 s on ship_sway against 2.2\'); "in the still '
        'limit": for such a base, the same share against the still base\'s formula (issue '
        '46\'s band), and the runs wholly inside it.', '',
        '| scenario | filter | what | runs aligned | aligned at (s) | moving from (s) '
        '| 15 s after | heading good from (s) | inside 3\' from (s) | 3\' or the aided limit, '
        'from (s) | switches, max (sum) '
        '| end aligned | inside 3 sigma | in limit | in the still limit |',
        '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|', *rows, '',
        '## The fog_mems car (real MEMS IMU, 100 s, ../shared/data)', '',
        'The recording as bench/defaults.py runs it (GNSS-like position and velocity from the '
        'FOG reference). "aligned at": s from the first IMU sample (- never); "switches": '
        '`aligned` -> `fine`; "inside": the 1-Hz `aligned` samples inside 3 sigma + 0.3 deg '
        '(mounting) on every axis against the reference.', '',
        '| recording | parameters | aligned at (s) | switches | final phase | final 1-sigma '
        'E/N/U (deg) | inside |',
        '|---|---|---|---|---|---|---|', *fog_rows(), '']
    with open(args.out, 'w') as f:
        f.write('\n'.join(page))
    print('\n'.join(page))


if __name__ == '__main__':
    sys.exit(main())

#!/usr/bin/env python3
"""Navigation-filter figures (issue 5): seeds 001 and 003 through the whole pipeline.

1. Seed 001 sec. 3 (``seed001_flight``): 3600 s flight with acceleration, deceleration,
   climb, dive and turns, tactical IMU, GNSS 1 Hz whose noise steps to 4x (1200-1500 s)
   and ramps to 3x (2400-3000 s) without the receiver saying so; every filter runs with
   Q nine times the truth (``nav_q_scale`` 9) and the nominal R. Position, velocity
   (eq. 40, 3-D) and roll, pitch, heading RMSE after coarse alignment (t >= 60 s) for
   KF, VBAKF and MVBAKF (both posterior moments), mean over N seeded runs, next to the
   paper's; the GNSS gate off (the paper has none) and on (the package default); and
   the R-estimate curves of one run as a PNG (the paper's Fig. 2).
2. Seed 001 Fig. 4-5: MVBAKF position and velocity RMSE for tau = 2..10 (N = 5) and
   N = 1..10 (tau = 10).
3. Seed 003 sec. 3-4 (``seed003_car``): MEMS car, receiver 10 m / 5 m / 0.1 m/s; the
   18-state UKF's position, velocity and attitude RMSE with its output rate, and the same
   data through the ASCKF-aligned pipeline (its mechanization's position) for comparison.
4. Replay speed (x real time, 100 Hz IMU, 1 Hz GNSS) of every navigation filter through
   the pipeline, block feed (replay) and one sample per call (the live node's path).

1b. (``--only headroom``, not in the default set) KF, VBAKF and MVBAKF on the flight with
   Q = 9x and with the true Q: what correcting the inflated Q can gain at most.

Usage: python bench/navigation.py [--runs 10] [--procs 2] [--only flight,tuning,car,speed]
       [--imu GRADE]  (the flight with another IMU preset, e.g. mems)
"""
import argparse
import os
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))      # this checkout's package, not an installed copy

from sins_align_ros.eval.cache import simulate_cached as simulate_profile  # noqa: E402
from sins_align_ros.eval.errors import navigation_rmse  # noqa: E402
from sins_align_ros.eval.markdown import machine_summary, write_markdown  # noqa: E402
from sins_align_ros.eval.pool import monte_carlo  # noqa: E402
from sins_align_ros.eval.run import replay_rate, run_pipeline  # noqa: E402
from sins_align_ros.eval.scenarios import named  # noqa: E402
from sins_align_ros.sim.presets import SENSOR_GRADES, alignment_params, scenario  # noqa: E402

#: seed 001 sec. 3.2: (position m, velocity m/s, roll, pitch, heading deg)
PAPER = {'vbakf': (10.8, 0.304, 0.043, 0.042, 0.26), 'mvbakf': (9.7, 0.278, 0.041, 0.035, 0.24)}
#: name -> (fine_filter, extra parameters)
FLIGHT_FILTERS = {'kf': ('kf', {}), 'vbakf': ('vbakf', {}),
                  'mvbakf (mean)': ('mvbakf', {}),
                  'mvbakf (inverse)': ('mvbakf', {'mvbakf_moment': 'inverse'})}
T_START = 60.0
#: a second window, after the alignment transient (the heading converges in a few minutes)
T_LATE = 600.0


def simulate_cached(name, seed):
    """Return ``(scenario, arrays)``, simulated once per (scenario, seed) (``eval.cache``).

    ``name`` is a scenario preset, optionally with ``@grade``: the preset with the IMU of
    ``SENSOR_GRADES[grade]`` instead of its own (``--imu``).
    """
    sc = named(name)
    return sc, simulate_profile(sc, seed)


def run(name, seed, fine_filter, extra, record=False):
    """One run through the pipeline; RMSE after ``T_START`` and optionally the R curve."""
    sc, b = simulate_cached(name, seed)
    curve, track = [], []

    def cb(pp):
        eng = pp.engine
        if eng is None:
            return
        m = pp.mech
        track.append((pp.t_last, m.lat, m.lon, m.h))
        if record:
            curve.append((pp.t_last, *np.sqrt(np.diag(eng.kf.R))))

    fed = run_pipeline(alignment_params(sc, fine_filter, **extra), b, use_velocity=True,
                       block=100, callback=cb)
    out = fed.out
    res = {'speed': sc.duration / fed.wall, 'restarts': getattr(fed.pipeline, 'n_restarts', 0),
           'phase': str(out.phase[-1])}
    for suffix, t_from in (('', T_START), ('_late', T_LATE)):
        res.update({k + suffix: v
                    for k, v in navigation_rmse(out, b.imu, t_from, track).items()})
    if out.nav is not None:
        res['rate_hz'] = float(1.0 / np.median(np.diff(out.t[np.isfinite(out.nav[:, 0])])))
    else:
        res['rate_hz'] = float('nan')
    if record:
        res['curve'] = np.array(curve)
    return res


def _job(args):
    return run(*args)


def _pool(jobs, procs):
    """``[(job, run(*job))]`` over ``procs`` processes."""
    return list(zip(jobs, monte_carlo(_job, jobs, procs)))


def _mean(rows, key):
    v = np.array([r[key] for r in rows], dtype=float)
    return float(np.nanmean(v, axis=0)) if v.ndim == 1 else np.nanmean(v, axis=0)


def flight(runs, procs, scen='seed001_flight'):
    """Section 1; returns lines and the R curves of seed 1."""
    lines = [f'## 1. Seed 001 flight ({scen}: 3600 s, filter Q = 9x truth, GNSS noise 4x at '
             '1200-1500 s and ramping to 3x over 2400-3000 s)', '',
             f'RMSE after coarse alignment (t >= {T_START:.0f} s), mean over {runs} seeded '
             'runs; position and velocity 3-D (seed 001 eq. 40). Restarts: runs in which the '
             'pipeline went back to coarse alignment.', '']
    curves = {}
    for gate, gp in (('off (the paper)', 1.0), ('on (default 0.9999)', 0.9999)):
        filters = {k: v for k, v in FLIGHT_FILTERS.items()
                   if gp == 1.0 or 'inverse' not in k}     # (it diverges without the gate)
        jobs = [(scen, s, ff, {**ex, 'nav_q_scale': 9.0, 'gnss_gate_probability': gp},
                 s == 1 and gp == 1.0)
                for name, (ff, ex) in filters.items() for s in range(1, runs + 1)]
        res = _pool(jobs, procs)
        lines += [f'GNSS innovation gate {gate}:', '',
                  '| filter | window | position (m) | velocity (m/s) | roll (deg) | '
                  'pitch (deg) | heading (deg) | runs restarted |',
                  '|---|---|---|---|---|---|---|---|']
        for name, (ff, ex) in filters.items():
            rows = [r for (a, r) in res if a[2] == ff and a[3].get('mvbakf_moment', 'mean')
                    == ex.get('mvbakf_moment', 'mean')]
            for suffix, win in (('', f't >= {T_START:.0f} s'), ('_late', f't >= {T_LATE:.0f} s')):
                att = _mean(rows, 'att' + suffix)
                lines.append(f"| {name} | {win} | {_mean(rows, 'pos' + suffix):.2f} | "
                             f"{_mean(rows, 'vel' + suffix):.3f} | {att[0]:.4f} | "
                             f"{att[1]:.4f} | {att[2]:.3f} | "
                             f"{sum(r['restarts'] > 0 for r in rows)}/{len(rows)} |")
            for r in rows:
                if 'curve' in r:
                    curves[name] = r['curve']
        for name, v in PAPER.items():
            lines.append(f'| paper {name} | whole run | {v[0]} | {v[1]} | {v[2]} | {v[3]} | '
                         f'{v[4]} | |')
        lines.append('')
    return lines, curves


def headroom(runs, procs, scen='seed001_flight'):
    """Section 1b: what knowing the true Q is worth in this flight (gate off).

    KF, VBAKF and MVBAKF with the paper's Q = 9x truth and with the true Q
    (``nav_q_scale`` 1): the KF with the true Q bounds what any method that corrects the
    inflated Q (MVBAKF's purpose) can gain.
    """
    names = ('kf', 'vbakf', 'mvbakf')
    jobs = [(scen, s, ff, {'nav_q_scale': q, 'gnss_gate_probability': 1.0}, False)
            for q in (9.0, 1.0) for ff in names for s in range(1, runs + 1)]
    res = _pool(jobs, procs)
    lines = ['## 1b. What the true Q is worth (gate off)', '',
             f'The flight of section 1 ({scen}), RMSE from t >= {T_START:.0f} s, mean over '
             f'{runs} seeded runs, each filter with the paper\'s Q = 9x truth and with the '
             'true Q. The KF with the true Q bounds the gain of any method that corrects the '
             'inflated Q.', '',
             '| filter | filter Q | position (m) | velocity (m/s) | roll (deg) | pitch (deg) '
             '| heading (deg) |', '|---|---|---|---|---|---|---|']
    for q in (9.0, 1.0):
        for ff in names:
            rows = [r for (a, r) in res if a[2] == ff and a[3]['nav_q_scale'] == q]
            att = _mean(rows, 'att')
            lines.append(f"| {ff} | {q:g}x | {_mean(rows, 'pos'):.3f} | "
                         f"{_mean(rows, 'vel'):.4f} | {att[0]:.4f} | {att[1]:.4f} | "
                         f"{att[2]:.3f} |")
    return lines + ['']


def plot_curves(curves, path):
    """Seed 001 Fig. 2 layout: estimated GNSS noise sigma against the truth.

    The adaptive filters only (the KF's R is constant; the inverse-moment MVBAKF diverges
    and would set the scale).
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    sc = scenario('seed001_flight')
    prof = np.asarray(sc.extra['gnss_noise_profile'])
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    t = np.linspace(0, sc.duration, 3601)
    scale = np.interp(t, prof[:, 0], prof[:, 1])
    for ax, col, true, label in ((axes[0], 1, sc.gnss.pos_sigma_h, 'east position sigma (m)'),
                                 (axes[1], 4, sc.gnss.vel_sigma, 'east velocity sigma (m/s)')):
        ax.plot(t, true * scale, 'k-', lw=2, label='true')
        for name, c in curves.items():
            if name.startswith('kf') or 'inverse' in name:
                continue
            ax.plot(c[:, 0], c[:, col], lw=1, label=name)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc='upper left')
    axes[1].set_xlabel('time (s)')
    fig.suptitle('Seed 001 flight: estimated GNSS noise (filter Q = 9x truth), seed 1')
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def tuning(runs, procs, moment='mean'):
    """Section 2: the tau and N study of seed 001 Fig. 4-5."""
    taus = list(range(2, 11))
    ns = list(range(1, 11))
    base = {'nav_q_scale': 9.0, 'gnss_gate_probability': 1.0, 'mvbakf_moment': moment}
    cfgs = ([{**base, 'mvbakf_tau': float(t), 'nav_iterations': 5} for t in taus]
            + [{**base, 'mvbakf_tau': 10.0, 'nav_iterations': n} for n in ns])
    jobs = [('seed001_flight', s, 'mvbakf', c) for c in cfgs for s in range(1, runs + 1)]
    res = _pool(jobs, procs)
    lines = [f'## 2. MVBAKF tuning (seed 001 Fig. 4-5; moment {moment}; gate off; mean of '
             f'{runs} runs)', '', '| tau (N = 5) | position (m) | velocity (m/s) |',
             '|---|---|---|']
    for t in taus:
        rows = [r for a, r in res if a[3]['mvbakf_tau'] == t and a[3]['nav_iterations'] == 5]
        lines.append(f"| {t} | {_mean(rows, 'pos'):.2f} | {_mean(rows, 'vel'):.3f} |")
    lines += ['', '| N (tau = 10) | position (m) | velocity (m/s) |', '|---|---|---|']
    for n in ns:
        rows = [r for a, r in res if a[3]['mvbakf_tau'] == 10.0 and a[3]['nav_iterations'] == n]
        lines.append(f"| {n} | {_mean(rows, 'pos'):.2f} | {_mean(rows, 'vel'):.3f} |")
    return lines + ['']


def car(runs, procs):
    """Section 3: seed 003's car, UKF against the ASCKF-aligned pipeline."""
    cases = {'ukf (18 states)': ('ukf', {}), 'kf (15 states)': ('kf', {}),
             'asckf (alignment filter)': ('asckf', {})}
    jobs = [('seed003_car', s, ff, ex) for (ff, ex) in cases.values()
            for s in range(1, runs + 1)]
    res = _pool(jobs, procs)
    lines = [f'## 3. Seed 003 car (700 s, MEMS IMU, receiver 10 m / 5 m / 0.1 m/s; mean of '
             f'{runs} runs, t >= {T_START:.0f} s)', '',
             '| filter | position 3-D (m) | horizontal (m) | velocity (m/s) | roll / pitch / '
             'heading (deg) | output rate (Hz) |', '|---|---|---|---|---|---|']
    for name, (ff, ex) in cases.items():
        rows = [r for a, r in res if a[2] == ff]
        att = _mean(rows, 'att')
        lines.append(f"| {name} | {_mean(rows, 'pos'):.2f} | {_mean(rows, 'pos_h'):.2f} | "
                     f"{_mean(rows, 'vel'):.3f} | {att[0]:.3f} / {att[1]:.3f} / {att[2]:.3f} | "
                     f"{_mean(rows, 'rate_hz'):.0f} |")
    lines += ['', 'Paper (seed 003 sec. 4, real car): position accuracy about 6 m, output '
              '100 Hz. The ASCKF row is the alignment filter of seed 000: its mechanization\'s '
              'position (reset to GNSS horizontally, height held to GNSS) at 1 Hz, no '
              'navigation output.', '']
    return lines


def speed(repeats=3):
    """Section 4: x real time through the pipeline (600 s of the flight)."""
    sc, b = simulate_cached('seed001_flight', 1)
    n = 60000
    imu = SimpleNamespace(t=b.imu.t[:n], dtheta=b.imu.dtheta[:n], dv=b.imu.dv[:n])
    cols = {k: getattr(b.gnss, k)[:600] for k in ('t', 'lat', 'lon', 'h', 'v_n', 'fix')}
    gn = SimpleNamespace(**cols, pos_cov=b.gnss.pos_cov, vel_cov=b.gnss.vel_cov)
    lines = ['## 4. Replay speed (600 s of the flight, 100 Hz IMU, 1 Hz GNSS, incl. coarse; '
             f'median of {repeats})', '',
             '| filter | x real time, block feed (replay) | x real time, one sample per call '
             '(live node path) |', '|---|---|---|']
    data = SimpleNamespace(imu=imu, gnss=gn)
    for ff in ('kf', 'vbakf', 'mvbakf', 'ukf'):
        rates = {block: replay_rate(alignment_params(sc, ff), data,
                                    repeats if block > 1 else 1, span=600.0,
                                    use_velocity=True, block=block)
                 for block in (1000, 1)}
        lines.append(f'| {ff} | {rates[1000]:.0f} | {rates[1]:.0f} |')
    return lines + ['']


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--runs', type=int, default=10)
    ap.add_argument('--tuning-runs', type=int, default=2)
    ap.add_argument('--procs', type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument('--only', default='flight,tuning,car,speed')
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'navigation.md'))
    ap.add_argument('--imu', choices=sorted(SENSOR_GRADES), default=None,
                    help='fly the flight section with this IMU preset instead of tactical')
    args = ap.parse_args()
    parts = args.only.split(',')
    t0 = time.time()
    lines = ['# Navigation filters (issue 5)', '',
             f'`python bench/navigation.py --runs {args.runs} --tuning-runs {args.tuning_runs} '
             f'--only {args.only}{f" --imu {args.imu}" if args.imu else ""}`; '
             f'{machine_summary()}.', '']
    flight_scen = 'seed001_flight' + (f'@{args.imu}' if args.imu else '')
    if 'flight' in parts:
        fl, curves = flight(args.runs, args.procs, flight_scen)
        lines += fl
        png = Path(args.out).with_name(Path(args.out).stem + '_R.png')
        plot_curves(curves, png)
        lines += [f'R estimate of seed 1 (gate off): `{png.name}`.', '']
    if 'headroom' in parts:
        lines += headroom(args.runs, args.procs, flight_scen)
    if 'tuning' in parts:
        lines += tuning(args.tuning_runs, args.procs)
    if 'car' in parts:
        lines += car(args.runs, args.procs)
    if 'speed' in parts:
        lines += speed()
    lines.append(f'Wall time {time.time() - t0:.0f} s.')
    print(write_markdown(args.out, lines))


if __name__ == '__main__':
    main()

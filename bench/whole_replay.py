#!/usr/bin/env python3
"""The whole replay process against pyins's feedback EKF on the same data (issue 22, must-show 1).

Case: ``ship_underway`` (marine IMU, accelerating and turning ship with sway) for
1200 s at 100 Hz with 1 Hz GNSS position and velocity, recorded once into a rosbag2
(``io.bag.write_scenario_bag``, seed 1; kept in ``--cache``).

- ``ours``: the replay *process*, ``python -m sins_align_ros.cli.replay BAG --params
  P.yaml --out OUT.csv --quiet``, timed from launch to exit: interpreter start-up and
  imports, reading and decoding the bag, coarse and fine alignment, writing the CSV
  (one row per IMU sample). The parameters are the simulated sensors'
  (``sim.presets.alignment_params``) with ``fine_filter`` set.
- ``pyins``: ``pyins.filters.run_feedback_filter`` (python-ins, PyPI; a bench and test
  dependency only) on the IMU and GNSS arrays read from the same bag, timed around that
  call alone (its inputs are built beforehand, its start-up not counted): position and
  NED velocity measurements with the simulated sigmas, the simulated sensors as its
  estimation models, the initial attitude 0.1/0.1/1 deg off the truth, its default
  covariance time step 0.1 s (and 1 s, reported too).

Each timing alternates ours and pyins; the median of ``--repeats`` after one warm-up
run of each (numba caches filled). Reports the seconds, x real time, and pyins / ours.

Usage: python bench/whole_replay.py [--repeats 3] [--filters asckf,kf] [--out FILE]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from sins_align_ros.eval.markdown import machine_summary, write_markdown  # noqa: E402
from sins_align_ros.eval.scenarios import named  # noqa: E402
from sins_align_ros.io.bag import read_bag, write_scenario_bag  # noqa: E402
from sins_align_ros.nav.frames import quat_to_euler, yaw_to_heading  # noqa: E402
from sins_align_ros.sim.presets import alignment_params  # noqa: E402

SCENARIO, SECONDS, RATE_HZ, SEED = 'ship_underway', 1200.0, 100.0, 1


def recording(cache):
    """Return the path of the case's rosbag2, writing it into ``cache`` the first time."""
    path = Path(cache) / f'{SCENARIO}_{SECONDS:.0f}s_seed{SEED}'
    if not path.exists():
        Path(cache).mkdir(parents=True, exist_ok=True)
        write_scenario_bag(str(path), named(SCENARIO, SECONDS), seed=SEED)
    return path


def params_file(folder, fine_filter):
    """Write the flat parameter YAML the replay is given; return its path."""
    p = alignment_params(named(SCENARIO, SECONDS), fine_filter)
    path = Path(folder) / f'{fine_filter}.yaml'
    path.write_text(''.join(f'{k}: {v!r}\n' if isinstance(v, str) else f'{k}: {v}\n'
                            for k, v in p.items()))
    return path


def process_env(root, **extra):
    """Environment of a measured process: ``root`` on the path, bytecode cached as usual.

    Python writes the compiled bytecode of what it imports next to the sources (here
    under ``PYTHONPYCACHEPREFIX``, outside the checkout) and reads it at the next start,
    unless ``PYTHONDONTWRITEBYTECODE`` is set, as it is in some sandboxes and containers
    (this project's CI machines among them): there every start compiles every imported
    module again, 0.1-0.15 s of a replay. The bench measures the usual installation, so
    it clears that variable for the processes it times; the warm-up run fills the cache.
    """
    env = dict(os.environ, PYTHONPATH=str(root),
               PYTHONPYCACHEPREFIX=str(Path(tempfile.gettempdir()) / 'sins_align_pycache'),
               **extra)
    env.pop('PYTHONDONTWRITEBYTECODE', None)
    # the BLAS thread settings a user has by default: none (the replay limits the pool
    # itself since session 29, ``sins_align_ros.single_thread_blas``; before, numpy's
    # OpenBLAS started a thread per core at import, 55 ms on 2 cores)
    for var in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
        if var not in extra:
            env.pop(var, None)
    return env


def ours(bag, params, out_csv, root=ROOT):
    """Seconds of one replay process of the checkout at ``root``, launch to exit."""
    cmd = [sys.executable, '-m', 'sins_align_ros.cli.replay', str(bag), '--params',
           str(params), '--out', str(out_csv), '--quiet']
    env = process_env(root)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, cwd=str(root))
    return time.perf_counter() - t0


STAGES = """
import json, sys, time
t0 = time.perf_counter()
sys.path.insert(0, {root!r})
from sins_align_ros.cli import replay as R
from sins_align_ros.nav import kernels
t1 = time.perf_counter()
kernels.warm_up()
t2 = time.perf_counter()
args = R._parser().parse_args([{bag!r}, '--params', {params!r}, '--out', {csv!r}, '--quiet'])
values = R.load_parameters(args.params, args.set, lambda m: None)
R.read_bag({bag!r}, args.imu_topic, args.fix_topic, truth_topic=None, vel_topic=args.vel_topic)
t3 = time.perf_counter()
out, pipe, _ = R.replay_bag({bag!r}, values, args, lambda m: None, with_truth=False)
t4 = time.perf_counter()
R.write_csv({csv!r}, out)
t5 = time.perf_counter()
print(json.dumps({{'imports': t1 - t0, 'numba first call': t2 - t1, 'read bag': t3 - t2,
                  'align': (t4 - t3) - (t3 - t2), 'write CSV': t5 - t4}}))
"""


def stages(bag, params, out_csv, root=ROOT):
    """Seconds of each stage of one replay in a fresh process (the replay's own functions).

    ``align`` is ``replay_bag`` less a separate timing of its bag read (input checks,
    coarse and fine alignment); ``numba first call`` the kernels' one-time start
    (loading compiled code from the cache) that the replay otherwise pays at its first
    kernel call; interpreter start-up and exit are the process time less their sum.
    """
    code = STAGES.format(root=str(root), bag=str(bag), params=str(params), csv=str(out_csv))
    env = process_env(root)
    out = subprocess.run([sys.executable, '-c', code], check=True, env=env, cwd=str(root),
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def pyins_inputs(bag):
    """Return the bag's IMU and GNSS as pyins inputs: ``(pva0, increments, meas, models)``."""
    import pandas as pd
    from pyins.inertial_sensor import EstimationModel
    from pyins.measurements import NedVelocity, Position
    rec = read_bag(str(bag))
    fix = [(ev.t, *ev.data[1:4]) for ev in rec.events if ev.kind == 'fix']
    vel = [(ev.t, *ev.data[0]) for ev in rec.events if ev.kind == 'vel']
    truth = [(ev.t, *ev.data[0]) for ev in rec.events if ev.kind == 'truth']
    t, w, f = rec.t, rec.w, rec.f
    t0 = t[0]
    dt = np.diff(t, prepend=t[0] - 1.0 / RATE_HZ)
    flu_to_frd = np.array([1.0, -1.0, -1.0])
    inc = pd.DataFrame(np.column_stack([dt, w * flu_to_frd * dt[:, None],
                                        f * flu_to_frd * dt[:, None]]),
                       index=t - t0, columns=['dt', 'theta_x', 'theta_y', 'theta_z',
                                              'dv_x', 'dv_y', 'dv_z'])
    fix = np.array(fix)
    vel = np.array(vel)
    sc = named(SCENARIO, SECONDS)
    pos = Position(pd.DataFrame(fix[:, 1:4], index=fix[:, 0] - t0,
                                columns=['lat', 'lon', 'alt']), sc.gnss.pos_sigma_h)
    ned = NedVelocity(pd.DataFrame(np.column_stack([vel[:, 2], vel[:, 1], -vel[:, 3]]),
                                   index=vel[:, 0] - t0, columns=['VN', 'VE', 'VD']),
                      sc.gnss.vel_sigma)
    q0 = np.array(truth[0][1:])
    roll, pitch, yaw = np.degrees(quat_to_euler(q0[None, :])[0])
    heading = float(np.degrees(yaw_to_heading(np.radians(yaw))))
    # ENU/FLU roll, pitch, yaw -> NED/FRD roll, pitch, heading; 0.1/0.1/1 deg off the truth
    pva0 = pd.Series({'lat': fix[0, 1], 'lon': fix[0, 2], 'alt': fix[0, 3],
                      'VN': vel[0, 2], 'VE': vel[0, 1], 'VD': -vel[0, 3],
                      'roll': roll + 0.1, 'pitch': -pitch + 0.1, 'heading': heading + 1.0})
    pva0.name = -float(dt[0])          # the state before the first increment
    s = sc.imu
    gyro = EstimationModel(bias_sd=max(float(np.max(s.gyro_bias_dph)), 1e-3) / 3600.0,
                           noise=s.gyro_arw_dpsh / 60.0)
    accel = EstimationModel(bias_sd=max(float(np.max(s.accel_bias_ug)), 1.0) * 9.8e-6,
                            noise=s.accel_vrw_ug_rthz * 9.8e-6)
    return pva0, inc, [pos, ned], (gyro, accel)


def pyins_run(inputs, time_step):
    """Seconds of one ``run_feedback_filter`` call."""
    from pyins.filters import run_feedback_filter
    pva0, inc, meas, (gyro, accel) = inputs
    t0 = time.perf_counter()
    run_feedback_filter(pva0, 1.0, 0.1, 0.1, 1.0, inc, gyro, accel, meas, time_step=time_step)
    return time.perf_counter() - t0


def main(argv=None):
    """Time both and write the table; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--filters', default='asckf,kf')
    ap.add_argument('--before', default=None, metavar='ROOT',
                    help='also time the replay of an older checkout (e.g. a git worktree)')
    ap.add_argument('--cache', default=str(Path(tempfile.gettempdir()) / 'sins_align_bench'))
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'whole_replay.md'))
    args = ap.parse_args(argv)
    bag = recording(args.cache)
    inputs = pyins_inputs(bag)
    filters = args.filters.split(',')
    with tempfile.TemporaryDirectory() as tmp:
        params = {f: params_file(tmp, f) for f in filters}
        csv = Path(tmp) / 'out.csv'
        roots = {f: ROOT for f in filters}
        if args.before:
            roots.update({f'{f} (before)': Path(args.before) for f in filters})
            params.update({f'{f} (before)': params[f] for f in filters})
        for f in roots:                                       # warm-up: caches filled
            ours(bag, params[f], csv, roots[f])
        pyins_run(inputs, 1.0)                                # compiles its kernels
        times = {k: [] for k in list(roots) + ['pyins 0.1 s', 'pyins 1 s']}
        for _ in range(args.repeats):
            for f in roots:
                times[f].append(ours(bag, params[f], csv, roots[f]))
            times['pyins 0.1 s'].append(pyins_run(inputs, 0.1))
            times['pyins 1 s'].append(pyins_run(inputs, 1.0))
        rows = sum(1 for _ in open(csv)) - 1
        split = {f: [stages(bag, params[f], csv, roots[f]) for _ in range(args.repeats)]
                 for f in roots}
    med = {k: statistics.median(v) for k, v in times.items()}
    ref, ref1 = med['pyins 0.1 s'], med['pyins 1 s']
    before = (' --before OLD', f'; "(before)": the checkout at {args.before}') \
        if args.before else ('', '')
    lines = ['# Whole replay against pyins (issue 22, must-show 1)', '',
             f'Command: `python bench/whole_replay.py --repeats {args.repeats} --filters '
             f'{args.filters}{before[0]}` on {machine_summary()}{before[1]}.', '',
             f'Case: `{SCENARIO}`, {SECONDS:.0f} s of {RATE_HZ:.0f} Hz IMU with 1 Hz GNSS '
             f'position and velocity, one rosbag2 (seed {SEED}). "ours" is the replay '
             'process from launch to exit (start-up, bag read and decode, coarse and fine '
             f'alignment, a CSV of {rows} rows); "pyins" is the '
             '`pyins.filters.run_feedback_filter` call alone on the same arrays (time step '
             '0.1 s, its default, and 1 s). Median of '
             f'{args.repeats}, alternating, after a warm-up run of each.', '',
             '| run | median s | all runs s | x real time | pyins 1 s / this | '
             'pyins 0.1 s / this |', '|---|---|---|---|---|---|']
    for k, v in times.items():
        lines.append(f'| {k} | {med[k]:.2f} | {", ".join(f"{x:.2f}" for x in v)} | '
                     f'{SECONDS / med[k]:,.0f} | {ref1 / med[k]:.1f} | {ref / med[k]:.1f} |')
    lines.append('')
    for f in filters:
        lines.append(f'- `{f}`: {ref1 / med[f]:.1f}x faster than pyins with a 1 s time step '
                     f'({ref / med[f]:.1f}x with its default 0.1 s; target >= 10), '
                     f'{SECONDS / med[f]:,.0f}x real time (target >= 1000).')
    names = list(next(iter(split.values()))[0])
    lines += ['', f'Where the time of a replay goes (seconds, median of {args.repeats} runs '
              'in fresh processes, the replay\'s own functions timed one after the other; '
              '"rest" is the process time above less their sum: interpreter start-up '
              'and exit):', '',
              '| run | ' + ' | '.join(names) + ' | rest |',
              '|---|' + '---|' * (len(names) + 1)]
    for f, runs in split.items():
        parts = [statistics.median(r[k] for r in runs) for k in names]
        lines.append(f'| {f} | ' + ' | '.join(f'{x:.2f}' for x in parts)
                     + f' | {med[f] - sum(parts):.2f} |')
    text = write_markdown(args.out, lines)
    print(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())

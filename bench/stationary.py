#!/usr/bin/env python3
"""Stationary alignment figures (issue 3): seed 002 table, Monte Carlo, speed, live node.

1. Seed 002 sec. 4 (34 N, 10 min, navigation grade, initial misalignment 1/5/10 deg applied
   to the fine filter): final heading/pitch/roll errors and convergence time of the 12-, 10-
   and 7-state filters beside the paper's Table 2, with the bias- and noise-driven limit
   terms; the 7-state filter also without staged re-initialisation.
2. Honest uncertainty: N seeded Monte Carlo runs with random biases, fraction of runs whose
   final error is inside the reported 3 sigma, and the average NEES.
3. Replay speed of each model (x real time at 100 Hz), pipeline alone and through the CLI on
   the PSINS recording.
4. The live alignment_node over real DDS at 200 Hz and 1000 Hz: CPU use and IMU-in to
   imu/data-out latency (p50/p99). Needs the colcon build sourced (scripts/test.sh does it;
   or `source install/setup.bash`); skipped otherwise.

Usage: python bench/stationary.py [--runs 50] [--node-seconds 30] [--out bench/results/...]
"""
import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))      # this checkout's package, not an installed copy

from sins_align_ros.eval.limits import scenario_limits  # noqa: E402
from sins_align_ros.align.pipeline import AlignmentPipeline  # noqa: E402
from sins_align_ros.eval.markdown import machine_summary, write_markdown  # noqa: E402
from sins_align_ros.eval.pool import monte_carlo as run_seeds  # noqa: E402
from sins_align_ros.eval.run import replay_rate, run_pipeline, without_gnss  # noqa: E402
from sins_align_ros.eval.scenarios import simulate  # noqa: E402
from sins_align_ros.eval.stats import error_summary  # noqa: E402
from sins_align_ros.nav.frames import (attitude_error, dcm_to_euler, euler_error,  # noqa: E402
                                       euler_to_dcm, quat_to_dcm, rotvec_to_dcm)
from sins_align_ros.sim.presets import SENSOR_GRADES, misalignment_rad, scenario  # noqa: E402
from sins_align_ros.sim.scenario import ScenarioStream  # noqa: E402
from sins_align_ros.units import ARCMIN  # noqa: E402

PAPER = {  # seed 002 Table 2 (deg): heading, pitch, roll per model and misalignment
    ('reduced7', 1): (0.045827, 0.014187, -0.017084),
    ('stationary10', 1): (0.047166, 0.014579, -0.015390),
    ('stationary12', 1): (0.047184, 0.014578, -0.015387),
    ('reduced7', 5): (-0.170625, 0.209733, -0.232563),
    ('stationary10', 5): (-0.168615, 0.210063, -0.230654),
    ('stationary12', 5): (-0.166924, 0.207806, -0.232389),
    ('reduced7', 10): (-1.02261, 0.739549, -0.884715),
    ('stationary10', 10): (-1.01784, 0.739037, -0.882453),
    ('stationary12', 10): (-1.46877, 0.616231, -0.982469),
}
SEED002 = {'initial_latitude_deg': 34.0, 'initial_longitude_deg': 75.0,
           'initial_height_m': 100.0}


def seed002_case(model, mis, seed=1, stages=3):
    """One seed 002 run; returns a dict of errors (arcmin), convergence time, limits, speed."""
    sc = scenario(f'seed002_{mis}deg')
    b = ScenarioStream(sc, seed=seed).next_block(60000)
    p = AlignmentPipeline({**SEED002, 'fine_filter': model, 'max_stages': stages})
    phi0 = misalignment_rad(sc)
    p.start_fine(rotvec_to_dcm(-phi0) @ euler_to_dcm(b.imu.euler[0]), phi0, 0.0)
    t0 = time.perf_counter()
    out = p.process(b.imu.t, b.imu.dtheta, b.imu.dv)
    wall = time.perf_counter() - t0
    C = quat_to_dcm(out.q)
    err = attitude_error(C, euler_to_dcm(b.imu.euler))
    eul_err = euler_error(dcm_to_euler(C[-1]), b.imu.euler[-1])
    band = scenario_limits(sc, 600.0)
    tol = band.tolerance()
    outside = np.nonzero(np.abs(err[:, 2]) > tol[2])[0]
    t_conv = 0.0 if len(outside) == 0 else out.t[min(outside[-1] + 1, len(out.t) - 1)]
    return {'heading': -eul_err[2] / ARCMIN, 'pitch': -eul_err[1] / ARCMIN,
            'roll': eul_err[0] / ARCMIN, 'err_enu': err[-1] / ARCMIN, 'conv': t_conv,
            'tol': tol / ARCMIN, 'bias': band.bias / ARCMIN, 'noise': band.noise / ARCMIN,
            'inside': bool(np.all(np.abs(err[-1]) <= tol)), 'speed': 600.0 / wall,
            'phase': out.phase[-1]}


def replay_speed(model, repeats=3):
    """Median x-real-time of the whole pipeline (coarse + fine) on 600 s of 100 Hz data."""
    b = simulate(scenario('seed002_1deg'), 1)
    return replay_rate({**SEED002, 'fine_filter': model}, without_gnss(b), repeats,
                       span=600.0, block=None)


def still_run(job):
    """One Monte Carlo run of section 2: ``(model, seed, seconds)`` -> final error."""
    model, seed, seconds = job
    sc = scenario('static_navigation', duration=seconds,
                  imu=SENSOR_GRADES['navigation'].with_(random_bias=True))
    return run_pipeline({'initial_latitude_deg': 34.0, 'initial_longitude_deg': 108.0,
                         'initial_height_m': 50.0, 'use_gnss_position': False,
                         'fine_filter': model}, without_gnss(simulate(sc, seed)),
                        block=None).final


def monte_carlo(runs, model='reduced7', seconds=600.0):
    """Fraction of final errors inside 3 sigma per angle, and mean NEES (3 dof)."""
    finals = run_seeds(still_run, [(model, 1000 + k, seconds) for k in range(runs)], procs=1)
    st = error_summary([f.euler for f in finals], [f.sigma for f in finals])
    return st.inside, float(np.mean([f.nees for f in finals]))


def psins_cli_speed():
    """Wall time of the replay CLI on the PSINS recording (reading + pipeline + CSV)."""
    data = ROOT.parent / 'shared' / 'data' / 'psins_lasergyro.imu'
    if not data.exists():
        return None
    t0 = time.perf_counter()
    subprocess.run([sys.executable, '-m', 'sins_align_ros.cli.replay', str(data), '--out',
                    '/tmp/bench_psins.csv', '--every', '100', '--quiet'], check=True, cwd=ROOT)
    return 1847.18 / (time.perf_counter() - t0)


def node_load(rate_hz, seconds):
    """CPU share and latency percentiles of alignment_node at ``rate_hz`` over real DDS."""
    if not os.environ.get('AMENT_PREFIX_PATH'):
        return None
    import threading

    import rclpy
    from ament_index_python.packages import get_package_prefix
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import Imu

    from sins_align_ros.nav import earth
    from sins_align_ros.ros.runner import stop_processes
    exe = os.path.join(get_package_prefix('sins_align_ros'), 'lib', 'sins_align_ros',
                       'alignment_node')
    domain = 60 + (os.getpid() + int(rate_hz)) % 60
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    node_proc = subprocess.Popen([exe, '--ros-args', '-p', 'coarse_duration:=2.0', '-p',
                                  'initial_latitude_deg:=34.0'], env=env,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    n = rclpy.create_node('bench_load', context=ctx)
    pub = n.create_publisher(Imu, 'imu/data_raw', 1000)
    lat = []
    clock = n.get_clock()

    def on_out(m):
        stamp = m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec
        lat.append(clock.now().nanoseconds - stamp)

    n.create_subscription(Imu, 'imu/data', on_out, 1000)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(n)
    end_setup = time.monotonic() + 20
    while pub.get_subscription_count() == 0 and time.monotonic() < end_setup:
        ex.spin_once(timeout_sec=0.05)
    g = earth.gravity(34.0 * np.pi / 180, 0.0)
    stop = threading.Event()
    sent = [0]

    def publish_loop():
        period = 1.0 / rate_hz
        nxt = time.monotonic()
        rng = np.random.default_rng(0)
        while not stop.is_set():
            now = time.monotonic()
            if now < nxt:
                time.sleep(min(nxt - now, 0.0005))
                continue
            m = Imu()
            m.header.stamp = clock.now().to_msg()
            m.header.frame_id = 'imu_link'
            w = rng.normal(0, 1e-6, 3)
            m.angular_velocity.x, m.angular_velocity.y = 5e-5 + w[0], w[1]
            m.angular_velocity.z = 4e-5 + w[2]
            m.linear_acceleration.z = g
            pub.publish(m)
            sent[0] += 1
            nxt += period

    th = threading.Thread(target=publish_loop, daemon=True)
    th.start()
    warm = time.monotonic() + 5.0
    while time.monotonic() < warm:
        ex.spin_once(timeout_sec=0.01)
    lat.clear()
    stat0 = _cpu_seconds(node_proc.pid)
    t0 = time.monotonic()
    sent0 = sent[0]
    while time.monotonic() - t0 < seconds:
        ex.spin_once(timeout_sec=0.01)
    cpu = (_cpu_seconds(node_proc.pid) - stat0) / (time.monotonic() - t0)
    n_sent = sent[0] - sent0
    stop.set()
    th.join()
    stop_processes([node_proc])
    ex.shutdown()
    ctx.try_shutdown()
    lat_ms = np.array(lat) * 1e-6
    return {'rate': rate_hz, 'cpu': cpu, 'p50': float(np.percentile(lat_ms, 50)),
            'p99': float(np.percentile(lat_ms, 99)), 'received': len(lat), 'sent': n_sent}


def _cpu_seconds(pid):
    with open(f'/proc/{pid}/stat') as f:
        fields = f.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def main():
    """Run everything, print and write bench/results/stationary.md."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--runs', type=int, default=50)
    ap.add_argument('--node-seconds', type=float, default=30.0)
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'stationary.md'))
    args = ap.parse_args()
    t_start = time.perf_counter()
    L = ['# Stationary alignment (seed 002 filters)', '',
         f'Command: `python bench/stationary.py --runs {args.runs}`; machine: '
         f'{machine_summary()}', '',
         '## 1. Seed 002 scenario: 34 N, 10 min, navigation grade', '',
         'Final errors in arcmin (heading, pitch, roll as in the paper\'s Table 2, whose values '
         'are degrees x 60 here). Convergence: time after which the heading error stays inside '
         'the limit band. Limit terms per ENU axis: bias (tilt a/g, heading eps_E/(W cos L)) '
         'and noise (VRW/(g sqrt T), ARW/(W cos L sqrt T)), band = 1.2 bias + 3 noise.', '',
         '| model | mis. | heading | pitch | roll | paper heading/pitch/roll | conv. (s) '
         '| bias E/N/U | noise E/N/U | band E/N/U | in band |',
         '|---|---|---|---|---|---|---|---|---|---|---|']
    speeds = {}
    for mis in (1, 5, 10):
        for model in ('stationary12', 'stationary10', 'reduced7'):
            r = seed002_case(model, mis)
            speeds.setdefault(model, []).append(r['speed'])
            ph = PAPER[(model, mis)]
            L.append(f"| {model} | {mis} deg | {r['heading']:.2f}' | {r['pitch']:.2f}' | "
                     f"{r['roll']:.2f}' | {ph[0] * 60:.1f}' / {ph[1] * 60:.1f}' / "
                     f"{ph[2] * 60:.1f}' | {r['conv']:.0f} | "
                     + '/'.join(f'{v:.2f}' for v in r['bias']) + "' | "
                     + '/'.join(f'{v:.2f}' for v in r['noise']) + "' | "
                     + '/'.join(f'{v:.2f}' for v in r['tol']) + "' | "
                     + ('yes' if r['inside'] else 'NO') + ' |')
            print(L[-1], flush=True)
    L += ['', 'Without staged re-initialisation (`max_stages: 1`), reduced7:', '',
          '| mis. | heading | pitch | roll | in band |', '|---|---|---|---|---|']
    for mis in (1, 5, 10):
        r = seed002_case('reduced7', mis, stages=1)
        L.append(f"| {mis} deg | {r['heading']:.2f}' | {r['pitch']:.2f}' | {r['roll']:.2f}' | "
                 + ('yes' if r['inside'] else 'NO') + ' |')
    print('\n'.join(L[-4:]), flush=True)
    L += ['', f'## 2. Honest uncertainty: {args.runs} Monte Carlo runs', '',
          'static_navigation (34 N, heading 30 deg), navigation grade with biases drawn per run '
          '(N(0, 0.01 deg/h), N(0, 100 ug)), 600 s (60 s coarse + fine), seeds 1000...', '',
          '| model | inside 3 sigma roll | pitch | yaw | mean NEES (3 dof, ideal 3) |',
          '|---|---|---|---|---|']
    for model in ('reduced7', 'stationary10'):
        runs = args.runs if model == 'reduced7' else max(10, args.runs // 2)
        frac, nees = monte_carlo(runs, model)
        L.append(f'| {model} ({runs} runs) | {frac[0]:.2f} | {frac[1]:.2f} | {frac[2]:.2f} | '
                 f'{nees:.2f} |')
        print(L[-1], flush=True)
    L += ['', '## 3. Replay speed (100 Hz IMU, 600 s: 60 s coarse + fine, pipeline only)', '',
          '| model | x real time (median of 3) |', '|---|---|']
    for model in speeds:
        L.append(f'| {model} | {replay_speed(model):.0f}x |')
    cli = psins_cli_speed()
    if cli:
        L.append('')
        L.append(f'Through the CLI on psins_lasergyro.imu (1847 s at 100 Hz, reading the text '
                 f'file, reduced7, CSV every 100th row): {cli:.0f}x real time.')
    print('\n'.join(L[-6:]), flush=True)
    L += ['', '## 4. Live alignment_node over DDS (Fast DDS, localhost)', '']
    rows = [node_load(rate, args.node_seconds) for rate in (200.0, 1000.0)]
    if rows[0] is None:
        L.append('Skipped: AMENT_PREFIX_PATH not set (source install/setup.bash).')
    else:
        L += ['| IMU rate | node CPU (cores) | latency p50 | latency p99 | received / sent |',
              '|---|---|---|---|---|']
        for r in rows:
            L.append(f"| {r['rate']:.0f} Hz | {r['cpu']:.2f} | {r['p50']:.2f} ms | "
                     f"{r['p99']:.2f} ms | {r['received']} / {r['sent']} |")
        L.append('')
        L.append('Latency: stamp of the input message (taken when published) to reception of '
                 'the matching imu/data in the publishing process.')
    L += ['', f'Wall time of this benchmark: {time.perf_counter() - t_start:.0f} s.']
    print('\n'.join(L[-10:]))
    write_markdown(args.out, L)


if __name__ == '__main__':
    main()

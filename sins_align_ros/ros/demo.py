"""sins_align_demo: the simulator and the alignment node together over real DDS topics.

Starts ``simulator_node`` and ``alignment_node`` as separate processes (the
executables ``ros2 run`` would start, found through the ament index) on a
private ROS domain, follows ``/diagnostics``, ``sim/truth`` and ``imu/data``,
prints each phase change and a progress line, and ends with the final attitude
error against the simulator's truth (and, for the navigation filters, the final
position and velocity error of ``~/odom``).
"""
import argparse
import os
import subprocess
import sys
import time

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu

from .conversions import stamp_to_ns
from .runner import stop_processes
from ..nav.frames import attitude_error, quat_to_dcm, quat_to_euler, yaw_to_heading
from ..eval.limits import alignment_limits
from ..align.params import AVAILABLE_FINE_FILTERS, MOVING_FILTERS, NAV_FILTERS
from ..nav import earth
from ..sim.presets import alignment_params, scenario, translates
from ..units import ARCMIN

#: scenarios the demo offers: still bases, the moored ship, two ships underway, a car with a
#: MEMS IMU and an aircraft (for the navigation filters)
DEMO_SCENARIOS = ('ship_sway', 'static_navigation', 'static_tactical', 'seed002_1deg',
                  'seed002_5deg', 'seed002_10deg', 'ship_underway', 'seed000_case1',
                  'seed003_car', 'seed001_flight')


def _executable(name):
    from ament_index_python.packages import get_package_prefix
    return os.path.join(get_package_prefix('sins_align_ros'), 'lib', 'sins_align_ros', name)


class _Watcher:
    def __init__(self, ctx):
        self.node = rclpy.create_node('demo_watcher', context=ctx)
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.truth = {}
        self.truth_nav = {}
        self.odom = None
        #: published attitudes by stamp (ns): the report takes the last one the truth also has
        self.att = {}
        self.n_att = 0
        self.status = None
        #: (phase, expected_aligned_at_s) of each progress report; elapsed s at ``aligned``
        self.expected = []
        self.aligned_at = None
        self.phases = []
        self.node.create_subscription(Odometry, 'sim/truth', self._on_truth, qos)
        self.node.create_subscription(Imu, 'imu/data', self._on_att, 50)
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 10)
        self.node.create_subscription(Odometry, 'alignment_node/odom', self._on_odom, 50)

    def _on_truth(self, m):
        q = m.pose.pose.orientation
        ns = stamp_to_ns(m.header.stamp)
        self.truth[ns] = np.array([q.x, q.y, q.z, q.w])
        p, v = m.pose.pose.position, m.twist.twist.linear
        self.truth_nav[ns] = (np.array([p.x, p.y, p.z]), np.array([v.x, v.y, v.z]), m)
        if len(self.truth) > 20000:
            self.truth.pop(next(iter(self.truth)))
            self.truth_nav.pop(next(iter(self.truth_nav)))

    def _on_odom(self, m):
        self.odom = m

    def _on_att(self, m):
        if m.orientation_covariance[0] >= 0.0:
            q = m.orientation
            self.n_att += 1
            self.att[stamp_to_ns(m.header.stamp)] = (np.array([q.x, q.y, q.z, q.w]),
                                                     np.array(m.orientation_covariance))
            if len(self.att) > 20000:
                self.att.pop(next(iter(self.att)))

    def _on_diag(self, m):
        for st in m.status:
            if st.name.endswith(': alignment'):
                self.status = {kv.key: kv.value for kv in st.values}
                self.status['message'] = st.message
                ph = self.status.get('phase')
                if ph and (not self.phases or self.phases[-1] != ph):
                    self.phases.append(ph)
                    el = float(self.status.get('elapsed_s', 0))
                    if ph == 'aligned' and self.aligned_at is None:
                        self.aligned_at = el
                    print(f'  phase -> {ph:8s} (elapsed {el:7.1f} s)  {st.message}', flush=True)


def _expectation(s):
    """One line of the node's forecast (``expected_*`` on /diagnostics)."""
    when = s.get('expected_aligned_at_s', 'unknown')
    when = f'{float(when):.0f} s' if when not in ('never', 'unknown') else when
    sig = ', '.join(f"{k[15:-4]} {float(s[k]) * 60:.2f}'" for k in (
        'expected_sigma_roll_deg', 'expected_sigma_pitch_deg', 'expected_sigma_yaw_deg')
        if k in s)
    note = s.get('expectation_note', '')
    return (f"aligned at {when} of data, 1-sigma then {sig or 'unknown'} "
            f"({s.get('expectation_basis', '?')}){'; ' + note if note else ''}")


def _report_expectation(w):
    """Print the first forecast of the time to ``aligned`` against when it came."""
    first = next((e for _, e in w.expected if e is not None), None)
    got = w.aligned_at
    first = first if first in (None, 'never', 'unknown') else f'{float(first):.0f} s'
    print(f"Forecast of the time to aligned at the first report: {first} of data; actual: "
          f"{'not reached in this run' if got is None else f'{got:.0f} s'}")


def _report_navigation(w, sc):
    """Print the last ~/odom's position and velocity error against the truth (ENU)."""
    m = w.odom
    s = w.status or {}
    if m is None or 'odom_origin_lat_deg' not in s or not w.truth_nav:
        print('\nNo navigation output (~/odom) was received.')
        return
    t_ns = stamp_to_ns(m.header.stamp)
    tt = min(w.truth_nav, key=lambda k: abs(k - t_ns))
    p_true, _, truth_msg = w.truth_nav[tt]
    tr = sc.trajectory
    origin = earth.local_offset_m(np.radians(tr.lat_deg), np.radians(tr.lon_deg), tr.h,
                                  np.radians([float(s['odom_origin_lat_deg'])]),
                                  np.radians([float(s['odom_origin_lon_deg'])]),
                                  np.array([float(s['odom_origin_h_m'])]))[0]
    p = m.pose.pose.position
    err = origin + np.array([p.x, p.y, p.z]) - p_true
    sig = np.sqrt(np.diag(np.array(m.pose.covariance).reshape(6, 6))[:3])
    q = m.pose.pose.orientation
    C = quat_to_dcm(np.array([q.x, q.y, q.z, q.w]))
    v = m.twist.twist.linear
    v_n = C @ np.array([v.x, v.y, v.z])
    tq = truth_msg.pose.pose.orientation
    tv = truth_msg.twist.twist.linear
    v_true = quat_to_dcm(np.array([tq.x, tq.y, tq.z, tq.w])) @ np.array([tv.x, tv.y, tv.z])
    print(f'Navigation (~/odom) at the end: position error E {err[0]:+.2f} m, N {err[1]:+.2f} m, '
          f'U {err[2]:+.2f} m (1-sigma {sig[0]:.2f}, {sig[1]:.2f}, {sig[2]:.2f} m; GNSS noise '
          f'{sc.gnss.pos_sigma_h:g} m); velocity error '
          f'{np.linalg.norm(v_n - v_true):.3f} m/s')


def _report(w, sc, fine_time, fine_filter):
    if not w.att:
        print('\nNo attitude was published on imu/data: the alignment did not finish coarse '
              'alignment (see the diagnostics above).')
        return 1
    # the truth comes at 10 Hz and a swaying ship turns degrees a second: compare at a stamp
    # both have, never at the nearest truth (50 ms apart can be 0.2 deg of roll)
    common = set(w.att) & set(w.truth)
    if not common:
        print('\nNo published attitude has the stamp of a received truth message.')
        return 1
    t_ns = max(common)
    q, cov = w.att[t_ns]
    late = (max(w.att) - t_ns) * 1e-9
    if late > 0.0:
        print(f'\n(the last attitude with a truth message is {late:.2f} s before the last '
              f'one published)')
    err = attitude_error(quat_to_dcm(q), quat_to_dcm(w.truth[t_ns]))
    e = np.degrees(quat_to_euler(q))
    sig = np.sqrt(np.clip(np.diag(cov.reshape(3, 3)), 0, None))
    band = alignment_limits(sc, fine_time, fine_filter, t_att=sc.duration)
    tol = band.tolerance()
    print(f'\nFinal attitude (REP-103): roll {e[0]:.4f} deg, pitch {e[1]:.4f} deg, yaw {e[2]:.4f} '
          f'deg (heading {np.degrees(yaw_to_heading(np.radians(e[2]))):.3f} deg from north)')
    print(f'Error against the simulator truth and the analytic limit of this {sc.name} sensor '
          f'({fine_time:.0f} s of fine alignment):')
    if fine_filter in MOVING_FILTERS:
        print('  (GNSS-aided: the up-axis noise term includes the GNSS velocity noise; a base '
              'that manoeuvres can do better than this still-base limit)')
    print('  axis   error     1-sigma   bias term  noise term  limit (1.2 bias + 3 noise)')
    ok = True
    for k, axis in enumerate(('east', 'north', 'up')):
        inside = abs(err[k]) <= tol[k]
        ok &= bool(inside)
        print(f"  {axis:5s} {err[k] / ARCMIN:7.3f}'  {sig[k] / ARCMIN:7.3f}'  "
              f"{band.bias[k] / ARCMIN:8.3f}'  {band.noise[k] / ARCMIN:9.3f}'  "
              f"{tol[k] / ARCMIN:8.3f}'  {'within' if inside else 'OUTSIDE'}")
    return 0 if ok else 1


def main(argv=None):
    """Run the demo; returns the process exit code."""
    ap = argparse.ArgumentParser(prog='sins_align_demo', description=__doc__.split('\n')[0])
    ap.add_argument('--scenario', default='ship_sway', choices=DEMO_SCENARIOS,
                    help='simulated scenario (default: a moored ship swaying in the sea)')
    ap.add_argument('--duration', type=float, default=300.0, help='simulated seconds')
    # 10x = 1000 IMU messages/s: the live node takes about 2000-4000 a second on a 2-core
    # machine with the simulator beside it, so 20x lost samples there now and then
    ap.add_argument('--rate', type=float, default=10.0, help='real-time factor')
    ap.add_argument('--coarse', type=float, default=60.0, help='coarse alignment time, s')
    ap.add_argument('--filter', choices=AVAILABLE_FINE_FILTERS,
                    help='fine filter (default: reduced7 on a base that does not translate, '
                         'asckf with GNSS on one that does)')
    ap.add_argument('--seed', type=int, default=1)
    args = ap.parse_args(argv)

    domain = 150 + os.getpid() % 50
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    watcher = _Watcher(ctx)
    ex = rclpy.executors.SingleThreadedExecutor(context=ctx)
    ex.add_node(watcher.node)
    print(f'sins_align_demo: scenario {args.scenario}, {args.duration:.0f} s simulated at '
          f'{args.rate:g}x real time, ROS domain {domain}', flush=True)
    procs = []
    try:
        sc = scenario(args.scenario, duration=args.duration)
        if args.filter is None:
            args.filter = 'asckf' if translates(sc) else 'reduced7'
        print(f'  fine filter {args.filter}: {sc.description}', flush=True)
        align_args = alignment_params(sc, args.filter, coarse_duration=args.coarse)
        cmd = [_executable('alignment_node'), '--ros-args']
        for k, v in align_args.items():
            cmd += ['-p', f'{k}:={v}']
        procs.append(subprocess.Popen(cmd, env=env))
        time.sleep(1.0)                  # let the node subscribe before data flows
        procs.append(subprocess.Popen([
            _executable('simulator_node'), '--ros-args',
            '-p', f'scenario:={args.scenario}', '-p', f'duration:={args.duration}',
            '-p', f'real_time_factor:={args.rate}', '-p', f'seed:={args.seed}',
            '-p', 'shutdown_when_done:=true'], env=env))
        sim = procs[-1]
        last = time.monotonic()
        while sim.poll() is None:
            ex.spin_once(timeout_sec=0.1)
            if time.monotonic() - last > 5.0 and watcher.status:
                last = time.monotonic()
                s = watcher.status
                sig = ', '.join(f"{k[6:-4]} {float(s[k]) * 60:.2f}'" for k in
                                ('sigma_roll_deg', 'sigma_pitch_deg', 'sigma_yaw_deg') if k in s)
                print(f"  t = {float(s.get('elapsed_s', 0)):7.1f} s  phase {s.get('phase'):8s} "
                      f"1-sigma {sig or '-'}  IMU {s.get('imu_count')}", flush=True)
                print(f'             expect: {_expectation(s)}', flush=True)
                watcher.expected.append((s.get('phase'), s.get('expected_aligned_at_s')))
        # the node may still be working through its queue: wait until the attitudes stop
        # (1 s without one), at most 30 s
        end = time.monotonic() + 30.0
        quiet_since, n_att = time.monotonic(), watcher.n_att
        while time.monotonic() < end and time.monotonic() - quiet_since < 1.0:
            ex.spin_once(timeout_sec=0.1)
            if watcher.n_att != n_att:
                quiet_since, n_att = time.monotonic(), watcher.n_att
        code = _report(watcher, sc, args.duration - args.coarse, args.filter)
        _report_expectation(watcher)
        if args.filter in NAV_FILTERS:
            _report_navigation(watcher, sc)
        return code
    except KeyboardInterrupt:
        return 130
    finally:
        stop_processes(procs)
        ex.shutdown()
        ctx.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())

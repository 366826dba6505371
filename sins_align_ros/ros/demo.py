"""sins_align_demo: the simulator and the alignment node together over real DDS topics.

Starts ``simulator_node`` and ``alignment_node`` as separate processes (the
executables ``ros2 run`` would start, found through the ament index) on a
private ROS domain, follows ``/diagnostics``, ``sim/truth`` and ``imu/data``,
prints each phase change and a progress line, and ends with the final attitude
error against the simulator's truth.
"""
import argparse
import os
import signal
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
from ..nav.frames import ARCMIN, attitude_error, quat_to_dcm, quat_to_euler, yaw_to_heading
from ..sim.presets import SCENARIOS


def _executable(name):
    from ament_index_python.packages import get_package_prefix
    return os.path.join(get_package_prefix('sins_align_ros'), 'lib', 'sins_align_ros', name)


class _Watcher:
    def __init__(self, ctx):
        self.node = rclpy.create_node('demo_watcher', context=ctx)
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.truth = {}
        self.att = None
        self.status = None
        self.phases = []
        self.node.create_subscription(Odometry, 'sim/truth', self._on_truth, qos)
        self.node.create_subscription(Imu, 'imu/data', self._on_att, 50)
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 10)

    def _on_truth(self, m):
        q = m.pose.pose.orientation
        self.truth[stamp_to_ns(m.header.stamp)] = np.array([q.x, q.y, q.z, q.w])
        if len(self.truth) > 20000:
            self.truth.pop(next(iter(self.truth)))

    def _on_att(self, m):
        if m.orientation_covariance[0] >= 0.0:
            q = m.orientation
            self.att = (stamp_to_ns(m.header.stamp), np.array([q.x, q.y, q.z, q.w]),
                        np.array(m.orientation_covariance))

    def _on_diag(self, m):
        for st in m.status:
            if st.name.endswith(': alignment'):
                self.status = {kv.key: kv.value for kv in st.values}
                self.status['message'] = st.message
                ph = self.status.get('phase')
                if ph and (not self.phases or self.phases[-1] != ph):
                    self.phases.append(ph)
                    el = float(self.status.get('elapsed_s', 0))
                    print(f'  phase -> {ph:8s} (elapsed {el:7.1f} s)  {st.message}', flush=True)


def _report(w):
    if w.att is None:
        print('\nNo attitude was published on imu/data: the alignment node did not leave the '
              "'waiting' phase (no alignment filter in this build).")
        return 0
    t_ns, q, cov = w.att
    if not w.truth:
        print('\nNo truth received from the simulator.')
        return 1
    tt = min(w.truth, key=lambda k: abs(k - t_ns))
    err = attitude_error(quat_to_dcm(q), quat_to_dcm(w.truth[tt]))
    e = np.degrees(quat_to_euler(q))
    sig = np.degrees(np.sqrt(np.clip(np.diag(cov.reshape(3, 3)), 0, None)))
    print(f'\nFinal attitude (REP-103): roll {e[0]:.4f} deg, pitch {e[1]:.4f} deg, yaw {e[2]:.4f} '
          f'deg (heading {np.degrees(yaw_to_heading(np.radians(e[2]))):.3f} deg from north)')
    print(f'Error against truth (ENU axes): east {err[0] / ARCMIN:.3f}\', north '
          f'{err[1] / ARCMIN:.3f}\', up {err[2] / ARCMIN:.3f}\'  '
          f'(1-sigma reported: {sig[0] * 60:.3f}\', {sig[1] * 60:.3f}\', {sig[2] * 60:.3f}\')')
    return 0


def main(argv=None):
    """Run the demo; returns the process exit code."""
    ap = argparse.ArgumentParser(prog='sins_align_demo', description=__doc__.split('\n')[0])
    ap.add_argument('--scenario', default='static_navigation', choices=SCENARIOS)
    ap.add_argument('--duration', type=float, default=120.0, help='simulated seconds')
    ap.add_argument('--rate', type=float, default=10.0, help='real-time factor')
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
        procs.append(subprocess.Popen([_executable('alignment_node')], env=env))
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
                print(f"  t = {float(s.get('elapsed_s', 0)):7.1f} s  phase {s.get('phase')}  "
                      f"IMU {s.get('imu_count')}  rejected {s.get('imu_rejected_count')}",
                      flush=True)
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.1)
        return _report(watcher)
    except KeyboardInterrupt:
        return 130
    finally:
        for p in procs:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        ex.shutdown()
        ctx.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())

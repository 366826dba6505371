#!/usr/bin/env python3
"""The live alignment node at a 1 kHz IMU: CPU share and latency (issue 22, must-show 4 and 5).

Three processes on one machine, local discovery only, their own ``ROS_DOMAIN_ID``:

- a publisher (child process) plays ``ship_underway`` (marine IMU, 1 Hz GNSS position
  and velocity) in real time: IMU messages at ``--rate`` Hz stamped with the wall
  clock of their due time, each published when due;
- the alignment node, as ``ros2 run`` starts it (``python -m
  sins_align_ros.ros.alignment_node --ros-args --params-file P.yaml``; ``fine_filter``
  and the simulated sensors' parameters), in its own process;
- this process, subscribed to the node's ``imu/data``: the latency of each output is
  its arrival time minus its header stamp (the input's stamp: publication delay,
  transport both ways and the node's work; an upper bound of the node's share).

The node's CPU share is its user + system time (``/proc/PID/stat``) over the fine
phase's last ``--window`` seconds divided by that wall time. Cold start: from launching
the node to its first ``imu/data`` message (the IMU already flowing; the coarse phase
publishes from the first sample), with the ahead-of-time kernels (``_aot_kernels``,
built by setup) or, for a filter given as ``NAME/jit``, numba's just-in-time path
(``SINS_ALIGN_NO_AOT=1``): its first run with an empty numba cache, later ones with the
cache it filled.

``relay`` in ``--filters`` runs, in the node's place, the least a node can do with the same
traffic in rclpy: subscribe ``imu/data_raw`` and republish each message on ``imu/data``
with the node's QoS and executor (``runner.make_executor``); ``relay_raw`` the same with
the messages as serialized bytes (``raw=True``, as the node takes them): the floor of the
CPU share, what rclpy and the rmw cost for one message in and one out.

Usage: python bench/node_load.py [--rate 1000] [--seconds 150] [--window 60]
                                 [--filters asckf/jit,asckf,kf,relay,relay_raw]
                                 [--out FILE]
"""
import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', '87')

SCENARIO = 'ship_underway'

PUBLISHER = r'''
import sys, time
sys.path.insert(0, {root!r})
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy
from sensor_msgs.msg import Imu, NavSatFix
from geometry_msgs.msg import TwistWithCovarianceStamped
from sins_align_ros.eval.scenarios import named
from sins_align_ros.ros.conversions import ns_to_stamp
from sins_align_ros.ros.playback import gnss_msgs, imu_msg
from sins_align_ros.sim.faults import MessageStream
from sins_align_ros.sim.scenario import ScenarioStream
sc = named({scenario!r}, {seconds!r})
n = int({seconds!r} * {rate!r})
s = MessageStream(ScenarioStream(sc, seed=1, imu_rate_hz={rate!r}).next_block(n))
msgs = [(s.imu['t'][i], 0, imu_msg(s, i)) for i in range(n)]
for i in range(len(s.gnss['t'])):
    f, v = gnss_msgs(s, i)
    msgs.append((s.gnss['t'][i], 1, f))
    if v is not None:
        msgs.append((s.gnss['t'][i], 2, v))
msgs.sort(key=lambda m: (m[0], m[1]))
rclpy.init()
node = rclpy.create_node('load_publisher')
qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                 history=HistoryPolicy.KEEP_LAST)
pubs = [node.create_publisher(Imu, 'imu/data_raw', qos),
        node.create_publisher(NavSatFix, 'gnss/fix', 50),
        node.create_publisher(TwistWithCovarianceStamped, 'gnss/vel', 50)]
print('ready', flush=True)
sys.stdin.readline()                                 # go
t0 = time.time() + 0.5 - msgs[0][0]
for t, kind, m in msgs:                              # stamps: the wall clock when due
    ns = int(round((t + t0) * 1e9))
    m.header.stamp = ns_to_stamp(ns)
for t, kind, m in msgs:
    wait = t + t0 - time.time()
    if wait > 0:
        time.sleep(wait)
    pubs[kind].publish(m)
print('done', flush=True)
node.destroy_node()
rclpy.shutdown()
'''


RELAY = r'''
import sys
sys.path.insert(0, {root!r})
import rclpy
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu
from sins_align_ros.ros.runner import make_executor, run


def make_relay():
    node = rclpy.create_node('relay')
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                     history=HistoryPolicy.KEEP_LAST)
    pub = node.create_publisher(Imu, 'imu/data', qos)
    node.create_subscription(Imu, 'imu/data_raw', pub.publish, qos, raw={raw})
    return node


sys.exit(run(make_relay, 'relay', make_executor))       # spun as the node is
'''


def params_yaml(folder, fine_filter):
    """Write the node's parameter file (ROS layout); return its path."""
    from sins_align_ros.eval.scenarios import named
    from sins_align_ros.sim.presets import alignment_params
    p = alignment_params(named(SCENARIO), fine_filter)
    lines = ['alignment_node:', '  ros__parameters:']
    lines += [f'    {k}: {v!r}' if isinstance(v, str) else f'    {k}: {v}' for k, v in p.items()]
    path = Path(folder) / f'{fine_filter}.yaml'
    path.write_text('\n'.join(lines) + '\n')
    return path


def cpu_seconds(pid):
    """User + system CPU seconds of process ``pid`` so far."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


class Listener:
    """``imu/data`` subscriber in this process, spun in a thread; records latencies."""

    def __init__(self):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import Imu
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx)
        self.node = rclpy.create_node('load_listener', context=self.ctx)
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                         history=HistoryPolicy.KEEP_LAST)
        self.node.create_subscription(Imu, 'imu/data', self._on, qos)
        self.rows = []                       # (arrival wall time, stamp)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.stop = False
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _on(self, msg):
        st = msg.header.stamp
        self.rows.append((time.time(), st.sec + st.nanosec * 1e-9))

    def _spin(self):
        while not self.stop:
            self.ex.spin_once(timeout_sec=0.05)

    def close(self):
        """Stop spinning and shut the context down."""
        self.stop = True
        self.thread.join()
        self.node.destroy_node()
        self.ctx.try_shutdown()


def run_case(fine_filter, args, folder, cache_dir, jit=False):
    """Run one node under load (``jit``: numba's path); returns a dict of the measurements."""
    from sins_align_ros.ros.runner import stop_processes
    env = dict(os.environ, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS='1',
               NUMBA_CACHE_DIR=str(cache_dir))
    env.pop('SINS_ALIGN_NO_AOT', None)
    if jit:
        env['SINS_ALIGN_NO_AOT'] = '1'
    pub = subprocess.Popen([sys.executable, '-c', PUBLISHER.format(
        root=str(ROOT), scenario=SCENARIO, seconds=args.seconds, rate=float(args.rate))],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
    assert pub.stdout.readline().strip() == 'ready'
    listener = Listener()
    pub.stdin.write('go\n')
    pub.stdin.flush()
    t_go = time.time()
    time.sleep(2.0)                                   # the IMU is flowing
    t_launch = time.time()
    cmd = ([sys.executable, '-c', RELAY.format(root=str(ROOT), raw=fine_filter == 'relay_raw')]
           if fine_filter.startswith('relay')
           else [sys.executable, '-m', 'sins_align_ros.ros.alignment_node', '--ros-args',
                 '--params-file', str(params_yaml(folder, fine_filter))])
    node = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL,
                            stderr=open(Path(folder) / f'{fine_filter}.log', 'w'))
    while not listener.rows and time.time() - t_launch < 60.0:
        time.sleep(0.01)
    cold = listener.rows[0][0] - t_launch if listener.rows else float('nan')
    w0 = t_go + args.seconds - args.window
    time.sleep(max(0.0, w0 - time.time()))
    c0, t0 = cpu_seconds(node.pid), time.time()
    time.sleep(args.window - 1.0)
    c1, t1 = cpu_seconds(node.pid), time.time()
    pub.stdout.readline()                             # 'done'
    time.sleep(1.0)
    stop_processes([node, pub])
    listener.close()
    if not listener.rows:
        log = (Path(folder) / f'{fine_filter}.log').read_text()[-2000:]
        raise RuntimeError(f'{fine_filter}: no imu/data message arrived; its log:\n{log}')
    rows = np.array(listener.rows)
    late = rows[(rows[:, 0] >= t0) & (rows[:, 0] <= t1)]
    lat = (late[:, 0] - late[:, 1]) * 1e3
    return {'cpu': (c1 - c0) / (t1 - t0), 'p50': float(np.percentile(lat, 50)),
            'p99': float(np.percentile(lat, 99)), 'max': float(lat.max()),
            'rate': len(late) / (t1 - t0), 'cold': cold}


def main(argv=None):
    """Measure every filter asked for and write the table; returns the exit code."""
    from sins_align_ros.eval.markdown import machine_summary, write_markdown
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--rate', type=float, default=1000.0)
    ap.add_argument('--seconds', type=float, default=150.0)
    ap.add_argument('--window', type=float, default=60.0)
    ap.add_argument('--filters', default='asckf,kf')
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'node_load.md'))
    args = ap.parse_args(argv)
    results = {}
    with tempfile.TemporaryDirectory() as folder:
        cache = Path(folder) / 'numba'            # empty: the first JIT node compiles into it
        jit_runs = 0
        for f in args.filters.split(','):
            name, jit = f.split('/')[0], f.endswith('/jit')
            results[f] = run_case(name, args, folder, cache, jit)
            results[f]['cache'] = ('-' if name.startswith('relay') else
                                   'ahead of time' if not jit else
                                   'JIT, cache filled' if jit_runs else 'JIT, empty cache')
            jit_runs += jit
    lines = ['# The live node at a 1 kHz IMU (issue 22, must-show 4 and 5)', '',
             f'Command: `python bench/node_load.py --rate {args.rate:.0f} --seconds '
             f'{args.seconds:.0f} --window {args.window:.0f} --filters {args.filters}` on '
             f'{machine_summary()}.', '',
             f'`{SCENARIO}` played in real time at {args.rate:.0f} Hz (1 Hz GNSS) into the '
             'alignment node in its own process; CPU share of the node over the last '
             f'{args.window:.0f} s (fine phase); latency = arrival of `imu/data` in a '
             'listener process minus its header stamp (the input message\'s: publication, '
             'transport both ways and the node\'s work).', '',
             '| filter | node CPU (cores) | outputs / s | latency p50 ms | p99 ms | max ms | '
             'launch to first output s | kernels at launch |',
             '|---|---|---|---|---|---|---|---|']
    for f, r in results.items():
        lines.append(f'| {f} | {r["cpu"]:.3f} | {r["rate"]:.0f} | {r["p50"]:.2f} | '
                     f'{r["p99"]:.2f} | {r["max"]:.1f} | {r["cold"]:.2f} | {r["cache"]} |')
    print(write_markdown(args.out, lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())

"""Shared fixtures and helpers: an rclpy Context per test on its own DDS domain, data paths,
node processes (:func:`running`) and the simulator node's messages (:func:`run_simulator`).
"""
import contextlib
import importlib.util
import fcntl
import itertools
import os
import signal
import subprocess
import tempfile
import time
from pathlib import Path

import pytest

# Keep DDS discovery on this machine; each test also gets its own domain id.
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / 'shared' / 'data'
_domain_ids = itertools.count()


def load_bench(name):
    """Return ``bench/<name>.py`` loaded as a module (bench/ is not a package)."""
    spec = importlib.util.spec_from_file_location(f'bench_{name}', ROOT / 'bench' / f'{name}.py')
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _worker_index():
    """Index of this pytest-xdist worker (``gw0`` -> 0), 0 without xdist."""
    name = os.environ.get('PYTEST_XDIST_WORKER', 'gw0')
    return int(name[2:]) if name[2:].isdigit() else 0


def _lock_paths(config):
    """Turnstile and main lock files shared by this run's xdist workers, or None."""
    workerinput = getattr(config, 'workerinput', None)
    if workerinput is None:
        return None
    base = os.path.join(tempfile.gettempdir(), f"sins_align_tests_{workerinput['testrunuid']}")
    return base + '.turnstile', base + '.lock'


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """Under pytest-xdist, run the tests marked ``exclusive`` with no other test beside them.

    The wall-clock paced node tests (the demo at 10x, the simulator node feeding the
    alignment node) lose samples when another worker loads the second core; every other
    test holds the main lock shared, an ``exclusive`` one holds it alone. The turnstile
    keeps a waiting exclusive test from being starved by the other worker's next tests.
    Wrapping the whole protocol covers module fixtures built in the item's setup.
    """
    paths = _lock_paths(item.config)
    if paths is None:
        yield
        return
    mode = fcntl.LOCK_EX if item.get_closest_marker('exclusive') else fcntl.LOCK_SH
    with open(paths[0], 'a') as turnstile, open(paths[1], 'a') as main:
        fcntl.flock(turnstile, fcntl.LOCK_EX)
        fcntl.flock(main, mode)
        fcntl.flock(turnstile, fcntl.LOCK_UN)
        try:
            yield
        finally:
            fcntl.flock(main, fcntl.LOCK_UN)


def pytest_collection_modifyitems(config, items):
    """Run the modules marked ``first`` first: their shared fixture is the run's longest piece.

    (``scripts/test.sh`` hands whole files to two workers, ``--dist loadfile``; the quick
    evidence report keeps one worker busy for minutes, so it should not be left for the end.)
    """
    items.sort(key=lambda item: item.get_closest_marker('first') is None)


def pytest_unconfigure(config):
    """Remove this run's lock files (the last worker's removal wins; errors ignored)."""
    for path in _lock_paths(config) or ():
        try:
            os.unlink(path)
        except OSError:
            pass


def next_domain_id():
    """A domain id unlikely to be used by a concurrent test (1..149).

    Each xdist worker draws from its own block (``scripts/test.sh`` runs two), so two
    tests running at the same time never share a domain; within a block the pid spreads
    concurrent test runs of different checkouts. 150..199 are the demo's
    (:mod:`sins_align_ros.ros.demo`).
    """
    n_blocks = max(1, int(os.environ.get('PYTEST_XDIST_WORKER_COUNT', '1')))
    size = 149 // n_blocks
    block = _worker_index() % n_blocks
    return 1 + block * size + (os.getpid() * 7 + next(_domain_ids)) % size


@pytest.fixture
def domain_id():
    """A distinct ROS_DOMAIN_ID for this test."""
    return next_domain_id()


@pytest.fixture
def ros_context(domain_id):
    """An initialised rclpy Context on its own domain, shut down after the test."""
    rclpy = pytest.importorskip('rclpy')
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    try:
        yield ctx
    finally:
        ctx.try_shutdown()


def spin_until(executor, predicate, timeout_s):
    """Spin ``executor`` until ``predicate()`` is true or ``timeout_s`` of wall time pass."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if predicate():
            return True
        executor.spin_once(timeout_sec=0.05)
    return predicate()


def shared_data(name):
    """Path of a recording in ../shared/data, or skip the test with the reason."""
    p = SHARED_DATA / name
    if not p.exists():
        pytest.skip(f'{p} not present (../shared/data is not beside the checkout)')
    return p


def interrupt(proc, timeout=15.0):
    """Stop a node process as Ctrl-C does; return ``(exit code, stdout, stderr)``.

    A process still alive ``timeout`` seconds after the SIGINT is killed (the test then
    sees its negative exit code). Nothing is sent to a process that has exited already.
    """
    proc.send_signal(signal.SIGINT)
    try:
        out, err = proc.communicate(timeout=timeout)
    except Exception:
        proc.kill()
        out, err = proc.communicate()
    return proc.returncode, out, err


class NodeProcess(subprocess.Popen):
    """A process of :func:`running`; once stopped, ``out`` and ``err`` hold all it wrote."""

    out = err = None


@contextlib.contextmanager
def running(cmd, domain_id, source_tree=False, timeout=15.0):
    """Run node process ``cmd`` (argv) on ROS domain ``domain_id`` for a ``with`` block.

    Yields the :class:`NodeProcess` (text pipes; discovery on this machine, unbuffered
    output). Leaving the block, however it is left, stops the process as Ctrl-C does
    (:func:`interrupt`: SIGINT, killed ``timeout`` s later if still alive) and closes its
    pipes; after the block ``returncode``, ``out`` and ``err`` say how it ended. When
    the block raised, the node's stderr is printed (pytest shows it with the failure).
    ``source_tree``: this checkout first on PYTHONPATH, so that the node runs the code
    under test rather than the installed copy.
    """
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id), PYTHONUNBUFFERED='1',
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    if source_tree:
        env['PYTHONPATH'] = os.pathsep.join([str(ROOT), os.environ.get('PYTHONPATH', '')])
    with NodeProcess(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                     text=True) as proc:
        ok = False
        try:
            yield proc
            ok = True
        finally:
            _, proc.out, proc.err = interrupt(proc, timeout)
            if not ok:
                print(f'--- stderr of {" ".join(cmd)} (exit code {proc.returncode}) ---\n'
                      f'{proc.err}')


def run_simulator(ctx, **params):
    """Run a SimulatorNode in ``ctx`` as fast as possible to its end, every topic subscribed.

    ``params``: its parameter overrides (``real_time_factor`` 0 unless given). Returns
    ``(sc, got, publishers)``: its scenario, topic key (``TOPICS``) -> the messages
    received, and topic key -> the number of publishers seen on that topic at the end.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from sins_align_ros.io.sim_messages import TOPICS
    from sins_align_ros.ros.simulator_node import SimulatorNode, ros_message_class
    sim = SimulatorNode(context=ctx, parameter_overrides=[
        Parameter(k, value=v) for k, v in {'real_time_factor': 0.0, **params}.items()])
    sub = rclpy.create_node('sub', context=ctx)
    qos = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
    got = {k: [] for k in TOPICS}
    for k, (name, typ) in TOPICS.items():
        sub.create_subscription(ros_message_class(typ), name, got[k].append, qos)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(sim)
    ex.add_node(sub)
    try:
        n_imu = int(round(sim.sc.duration / sim.dt))
        assert spin_until(ex, lambda: sim.done and len(got['imu']) == n_imu, timeout_s=60.0)
        spin_until(ex, lambda: False, timeout_s=0.3)            # the last GNSS and truth
        publishers = {k: sub.count_publishers(name) for k, (name, _) in TOPICS.items()}
        return sim.sc, got, publishers
    finally:
        ex.shutdown()
        sim.destroy_node()
        sub.destroy_node()


@pytest.fixture(scope='module')
def posonly_robot():
    """bench/integrity.py's robot:posonly cell, plain MEMS, seed 1000 (400 s, 30 Hz IMU).

    The skid-steer robot (never still, 1 m/s, turning) with its vibration, and a
    position-only receiver at 2.5 Hz: 0.8 m white plus 1.5 m Gauss-Markov (60 s), reporting
    0.9 m. Returns ``(scenario, simulated data)``.
    """
    from sins_align_ros.eval.scenarios import simulate
    from sins_align_ros.sim.gnss import GnssSpec
    from sins_align_ros.sim.presets import SENSOR_GRADES, scenario
    sc = scenario('robot_skid', duration=400.0)
    vib = {k: v for k, v in vars(sc.imu).items() if k.startswith('vibration_')}
    sc.imu = SENSOR_GRADES['mems'].with_(**vib)
    sc.gnss = GnssSpec(rate_hz=2.5, pos_sigma_h=0.8, pos_sigma_v=1.6, pos_markov_sigma=1.5,
                       pos_markov_tau_s=60.0, vel_sigma=0.1, velocity=False,
                       reported_pos_sigma_h=0.9, reported_pos_sigma_v=1.8)
    return sc, simulate(sc, 1000)

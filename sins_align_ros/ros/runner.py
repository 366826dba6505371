"""Run loop of the executables, and the matching way to stop them as child processes.

``run``: spin, clean exit on Ctrl-C, one-line errors. ``stop_processes``: what the
demo, the tests and the benchmarks use to end the nodes they started.
"""
import os
import signal
import subprocess
import sys

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException


def run(make_node, name, make_executor=None, done=lambda node: False, args=None):
    """Create a node with ``make_node()``, spin it until shutdown or ``done(node)``.

    Invalid parameters (``ValueError`` from the node, rclpy's ``ParameterException`` for a
    value outside a declared range) end with one line on stderr
    and exit code 2; SIGINT ends with exit code 0. Returns the exit code.
    """
    rclpy.init(args=args)
    node = None
    try:
        node = make_node()
        if make_executor is None:
            from rclpy.executors import SingleThreadedExecutor
            executor = SingleThreadedExecutor()
        else:
            executor = make_executor()
        executor.add_node(node)
        while rclpy.ok() and not done(node):
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ValueError, ParameterException) as exc:
        # ParameterException: a start-up value outside a declared range (rclpy refuses it)
        print(f'{name}: {exc}', file=sys.stderr)
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


def stop_processes(procs, timeout=10.0):
    """Stop child processes as Ctrl-C would (SIGINT), killing any still alive after ``timeout``.

    ``None`` entries and processes that already ended are skipped; the SIGINTs go out
    together so the processes shut down in parallel.
    """
    procs = [p for p in procs if p is not None]
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    for p in procs:
        try:
            p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def make_executor():
    """Return the lightest executor available: rclpy's EventsExecutor (experimental).

    At 1000 Hz IMU input the default SingleThreadedExecutor alone costs about a
    third of a core in wait-set handling; set SINS_ALIGN_EXECUTOR=single to use it anyway.
    """
    if os.environ.get('SINS_ALIGN_EXECUTOR', 'events') == 'events':
        try:
            from rclpy.experimental import EventsExecutor
            return EventsExecutor()
        except ImportError:  # pragma: no cover - older rclpy
            pass
    from rclpy.executors import SingleThreadedExecutor
    return SingleThreadedExecutor()

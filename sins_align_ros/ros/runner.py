"""Run loop of the executables, and the matching way to stop them as child processes.

``run``: build the node, spin it (:func:`spin`), clean exit on Ctrl-C, one-line errors
for what construction refuses. ``spin``: the loop, where an exception raised in a callback
is handed to the node instead of ending the process. ``stop_processes``: what the demo,
the tests and the benchmarks use to end the nodes they started.
"""
import os
import signal
import subprocess
import sys
import traceback

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException


def run(make_node, name, make_executor=None, done=lambda node: False, args=None):
    """Create a node with ``make_node()``, spin it until shutdown or ``done(node)``.

    Invalid parameters at construction (``ValueError`` from the node, rclpy's
    ``ParameterException`` for a value outside a declared range) end with one line on
    stderr and exit code 2. Once the node is built, an exception in a callback does not
    end the process (:func:`spin`). SIGINT ends with exit code 0. Returns the exit code.
    """
    try:
        rclpy.init(args=args)
    except RuntimeError as exc:   # rcl refused the arguments: a params file missing or not YAML
        from .params import startup_error
        print(f'{name}: {startup_error(exc)}', file=sys.stderr)
        return 2
    node = None
    try:
        try:
            node = make_node()
        except (ValueError, ParameterException) as exc:
            # ParameterException: a start-up value outside a declared range (rclpy refuses it)
            print(f'{name}: {exc}', file=sys.stderr)
            return 2
        except Exception:                 # noqa: B902 - see below
            # Ctrl-C during construction shuts the context down under the node (its first
            # publication then fails): a clean stop, not an error
            if rclpy.ok():
                raise
            return 0
        if make_executor is None:
            from rclpy.executors import SingleThreadedExecutor
            executor = SingleThreadedExecutor()
        else:
            executor = make_executor()
        executor.add_node(node)
        spin(node, executor, done)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        _shutdown()
    return 0


def _shutdown():
    """Shut rclpy down unless a Ctrl-C already did.

    rclpy's ``try_shutdown`` checks ``ok()`` and then shuts down; its SIGINT handler shuts
    the context down on its own thread, and when it lands between the two the second
    shutdown raises "rcl_shutdown already called" (seen once in CI: exit code 1 and a
    traceback on a clean Ctrl-C). A context that is no longer ok is what we wanted.
    """
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    try:
        rclpy.try_shutdown()
    except _rclpy.RCLError:
        if rclpy.ok():
            raise


def spin(node, executor, done=lambda node: False, timeout_sec=0.1):
    """Spin ``executor`` while rclpy is ok and not ``done(node)``; no callback ends it.

    The executors re-raise an exception of a callback from ``spin_once`` (rclpy's
    EventsExecutor also logs it at FATAL first). It goes to ``node.on_callback_error(exc)``
    when the node has that hook (the alignment node logs it, counts it and restarts its
    alignment), else it is logged at ERROR with its traceback; either way spinning goes
    on. Ctrl-C and an external shutdown still end the loop (they propagate).
    """
    context = executor.context
    while context.ok() and not done(node):
        try:
            executor.spin_once(timeout_sec=timeout_sec)
        except (KeyboardInterrupt, ExternalShutdownException):
            raise
        except Exception as exc:          # noqa: B902 - a callback's error, whatever it is
            if not context.ok():
                break
            _hand_over(node, exc)


def _hand_over(node, exc):
    """Give a callback's exception to ``node.on_callback_error``, or log it."""
    hook = getattr(node, 'on_callback_error', None)
    try:
        if hook is not None:
            hook(exc)
            return
    except Exception as inner:            # noqa: B902 - the hook itself failed
        exc = inner
    text = ''.join(traceback.format_exception(exc))
    node.get_logger().error(f'exception in a callback (the node goes on):\n{text}')


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

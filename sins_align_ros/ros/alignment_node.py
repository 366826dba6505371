"""alignment_node: SINS initial alignment from sensor_msgs/Imu (and GNSS).

A thin shell: every message goes into an :class:`~sins_align_ros.align.session.
AlignmentSession` (the object the replay tool drives too, with the input checks and
restart rules); what the node shows it reads through the session's read-outs. The jobs
live in the modules named after them:

* :mod:`.inputs`: the subscriptions (``imu/data_raw``, ``gnss/fix``, ``gnss/vel``,
  ``heading/in``) with their QoS, messages into session calls, the IMU batch;
* :mod:`.outputs`: the publishers and the messages published per sample (``imu/data``,
  ``~/euler``, ``~/odom``);
* :mod:`.status`: the typed status (``~/phase``, ``~/reason``, ``~/*_ready``);
* :mod:`.diagnostics`: ``/diagnostics``, the rate-limited input-fault log (bad input is
  skipped or bridged, counted by reason, and raises the period's level), callback errors;
* :mod:`.alignment_params`: the parameters, checked when set; a change to an alignment
  parameter (``fine_filter`` included) restarts the alignment with it.

Service ``~/reset`` (std_srvs/Trigger) restarts the alignment in any phase. An exception
in a callback is handed to :meth:`AlignmentShell.on_callback_error` by the spin loop
(:func:`.runner.spin`): logged, counted, the alignment restarted; the node goes on.
:class:`AlignmentShell` is the body; :class:`AlignmentNode` starts it at construction,
the managed node of :mod:`.alignment_lifecycle_node` in its lifecycle transitions.
"""
import sys
import time
from collections import Counter

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from std_srvs.srv import Trigger

from ..align import AlignmentSession
from ..io.node_status import NO_IMU, imu_stopped, typed_state
from ..nav import kernels
from .alignment_params import PARAMS, AlignmentParams
from ..io.diagnostic_report import FAULT_SOURCES, PeriodReport
from .diagnostics import CallbackErrors, status_message
from .inputs import feed_imu, fix_args, heading_args, subscribe, velocity_args
from .outputs import RowPublisher, create_publishers
from .runner import make_executor, run
from .status import TypedStatus

__all__ = ['PARAMS', 'AlignmentShell', 'AlignmentNode', 'main']
#: how the input sources are named in log lines and diagnostics


class AlignmentShell:
    """The alignment node's body, a mixin for an rclpy ``Node``; see the module docstring.

    :class:`AlignmentNode` calls :meth:`_declare_params`, :meth:`_start_session`,
    :meth:`_subscribe`, :meth:`_create_outputs`; a managed node, its transitions.
    """

    #: the alignment session (None: a managed node that is not configured)
    session = None

    def _declare_params(self, check=True):
        """Declare the parameters (``check`` false: keep invalid values for a later check)."""
        self.params = AlignmentParams(self, check)
        self.p = self.params.p
        self.add_on_set_parameters_callback(self._check_pipeline_params)
        self.add_post_set_parameters_callback(self._apply_params)
        self.errors = CallbackErrors(self.get_logger())

    def _start_session(self):
        """Build the session from the parameters (``ValueError``: refused); start afresh."""
        self.session = AlignmentSession(self.params.align)   # ValueError: refused
        # compile the numeric kernels now, not at the coarse window's end amid the data
        self.get_logger().debug(f'numeric kernels ready in {kernels.warm_up():.2f} s')
        self.report = PeriodReport(self.get_logger())
        self._typed_phase = None
        #: IMU messages waiting for the batch (bytes); when the first came (wall, s)
        self._batch, self._batch_wall = [], 0.0
        #: samples the session accepted; messages received per topic (before any check)
        self.counts, self.received = {'imu': 0}, Counter()
        self._last_imu_wall = None

    def _subscribe(self):
        """Subscribe to the input topics (:mod:`.inputs`); return the subscriptions."""
        return subscribe(self, self._on_imu, self._on_fix, self._on_vel, self._on_heading)

    def _create_outputs(self, create_publisher):
        """Create the publishers (``pub_*``), ``~/reset``, the timers; return the last two."""
        self.pub_imu, self.pub_euler, self.pub_odom, self.pub_diag = \
            create_publishers(create_publisher)
        self.rows = RowPublisher(self.pub_imu, self.pub_euler, self.pub_odom, self.p)
        self.typed = TypedStatus(create_publisher)
        made = [self.create_service(Trigger, '~/reset', self._on_reset),
                self.create_timer(self.p['diagnostic_period'], self._publish_diagnostics)]
        if self.p['imu_batch_period'] > 0.0:
            made.append(self.create_timer(self.p['imu_batch_period'], self._on_batch_timer))
        return made

    def _log_start(self):
        self.get_logger().info(
            f"fine filter {self.p['fine_filter']}, coarse {self.p['coarse_method']} "
            f"{self.p['coarse_duration']:.0f} s; waiting for imu/data_raw")

    @property
    def pipeline(self):
        """Return the session's current pipeline for tests to inspect; None without a session."""
        return None if self.session is None else self.session.pipeline

    @property
    def odom(self):
        """Return the ``~/odom`` origin (:class:`~.odometry.OdometryFrame`)."""
        return self.rows.odom

    # -- parameters and restarts ------------------------------------------------------------
    def _check_pipeline_params(self, changes):
        return self.params.check(changes)

    def _apply_params(self, changes):
        names = self.params.apply(changes)
        if names and self.session is not None:     # a managed node not configured: stored
            self._flush_imu()
            self.session.restart(f'parameters changed: {", ".join(names)}',
                                 values=self.params.align)
            self._drain()

    def _on_reset(self, request, response):
        self._flush_imu()                           # what came before goes to the old run
        self.session.restart('~/reset service')
        self._drain()
        response.success = True
        response.message = 'alignment restarted; waiting for IMU data'
        return response

    def _drain(self):
        """Log the session's restarts, count its input notices, publish a new phase."""
        for level, text in self.session.pop_events():
            if level == 'warn':       # rclpy: one severity per call site
                self.get_logger().warn(text)
            else:
                self.get_logger().info(text)
            self.report.restarted(text)
            self.rows.restart()
        for source, key, text in self.session.notices():
            self.report.faults.add(FAULT_SOURCES[source], key, text)
        if self.session.phase != self._typed_phase or self.typed.last.get('reason') == NO_IMU:
            self._update_typed()

    def on_callback_error(self, exc):
        """Take an exception a callback raised (:func:`.runner.spin`): log, count, restart."""
        text = self.errors.add(exc)
        if self.session is not None:      # a managed node not configured: nothing to restart
            self._batch = []              # the messages it may have come from
            self.session.restart(f'exception in a callback ({text})', 'warn')
            self._drain()

    def _update_typed(self, s=None):
        """Publish what changed of the typed status (:mod:`.status`); return the state."""
        state = typed_state(self.session.status() if s is None else s,
                            imu_stopped(self._imu_age(), self.p['diagnostic_period']))
        self._typed_phase = self.session.phase
        if self._publishing():
            self.typed.update(state)
        return state

    def _publishing(self):
        """Tell whether the outputs publish (a managed node: while active)."""
        return True

    def _imu_age(self):
        """Return the seconds since the last IMU message (None before the first)."""
        return None if self._last_imu_wall is None else time.monotonic() - self._last_imu_wall

    # -- input -------------------------------------------------------------------------------
    def _on_fix(self, msg):
        self._take('gnss/fix', self.session.fix, fix_args(msg))

    def _on_vel(self, msg):
        self._take('gnss/vel', self.session.velocity, velocity_args(msg))

    def _on_heading(self, msg):
        """Take an external heading: the yaw of the orientation and its variance (REP-145)."""
        self._take('heading/in', self.session.heading, heading_args(msg))

    def _take(self, topic, entry, args):
        """Give a non-IMU message's ``args`` to the session's ``entry``, the IMU batch first."""
        self.received[topic] += 1
        self._flush_imu()
        entry(*args)
        self._drain()

    def _on_imu(self, raw):
        """Queue a serialized IMU message (``raw=True``: bytes) for the batch."""
        self.received['imu/data_raw'] += 1
        now = time.monotonic()
        self._last_imu_wall = now
        self.report.imu[0] += 1
        if not self._batch:
            self._batch_wall = now
        self._batch.append(raw)
        if now - self._batch_wall >= self.p['imu_batch_period']:
            self._flush_imu()

    def _on_batch_timer(self):
        """Flush a batch the input stopped filling (a pause, the end of a recording)."""
        if self._batch:
            self._flush_imu()

    def _flush_imu(self):
        """Run the waiting IMU messages through the session; publish a row per sample."""
        if not self._batch:
            return
        raws, self._batch = self._batch, []
        batch, out, usable, accepted = feed_imu(self.session, raws, self.p['imu_frame_id'])
        self.report.imu[1] += usable
        self.counts['imu'] += accepted
        if out is not None:
            self.rows.take(batch, self.session.C_s_v)
            if len(out.t):
                self.rows.publish(out, self.session.navigation)
        self._drain()

    # -- diagnostics -------------------------------------------------------------------------
    def _publish_diagnostics(self):
        s = self.session.status()
        state = self._update_typed(s)
        arr = DiagnosticArray()
        arr.status = [status_message(self.report.status(
            f'{self.get_fully_qualified_name()}: alignment', self.p['imu_frame_id'] or 'imu',
            self.session, s, state, self.p, self._imu_age(), self.errors, self.counts,
            self.rows.odom, self.params.noise_summary))]
        arr.header.stamp = self.get_clock().now().to_msg()
        self.pub_diag.publish(arr)


class AlignmentNode(AlignmentShell, Node):
    """Thin ROS shell around an alignment session, started at construction."""

    def __init__(self, **kwargs):
        super().__init__('alignment_node', **kwargs)
        self._declare_params()
        self._start_session()
        self._subscribe()
        self._create_outputs(self.create_publisher)
        self._update_typed()                # the typed status once at start
        self._log_start()


def main(args=None):
    """Entry point of ``ros2 run sins_align_ros alignment_node``."""
    return run(AlignmentNode, 'alignment_node', make_executor, args=args)


if __name__ == '__main__':
    sys.exit(main())

"""alignment_lifecycle_node: the alignment node as a managed (lifecycle) node.

The body of :mod:`.alignment_node` (:class:`~.alignment_node.AlignmentShell`) with the
same node name ``alignment_node``, parameters, topics and QoS, started and stopped
through the lifecycle services ``~/change_state`` and ``~/get_state`` (lifecycle_msgs):

* constructed, *unconfigured*: the parameters are declared, so they can be set before
  ``configure`` (overrides, a YAML file, set_parameters); a value outside its declared
  range is refused by rclpy at once, any other value the alignment refuses (an unknown
  ``fine_filter``, say) is kept until ``configure`` refuses it;
* ``configure``: builds the session from the parameters (refused: FAILURE with the reason
  logged, the node stays unconfigured), creates the lifecycle publishers (``imu/data``,
  ``~/euler``, ``/diagnostics``, ``~/odom``), the ``~/reset`` service and the timers:
  *inactive*;
* ``activate``: activates the publishers and subscribes ``imu/data_raw``, ``gnss/fix``,
  ``gnss/vel`` (the plain node's QoS): *active*, the plain node's behaviour;
* ``deactivate``: unsubscribes (input stops), publishes what the waiting IMU batch gives,
  deactivates the publishers: *inactive*. Nothing is published while inactive, diagnostics
  included: their timer skips its periods, and what happened meanwhile (a restart by
  ``~/reset`` or a parameter change) is in the first report after activation. The session
  keeps its state: activating again continues the alignment, the pause being a gap in the
  IMU stamps like any other (longer than ``max_gap``: a restart; ``~/reset`` starts afresh);
* ``cleanup``: destroys the publishers, the service and the timers and drops the session:
  *unconfigured*;
* ``shutdown`` (from any state), or an error in a transition: tears down whatever exists.

A transition the current state does not have (a second ``configure`` while inactive, an
unknown id or label) is refused: ``~/change_state`` answers ``success=false``, the reason
(the state and the transitions it has) is logged at WARN and the node keeps its state.
(rclpy's own handler would raise, which ended the process.)

The typed status (``~/phase``, ``~/reason``, ``~/tilt_ready``, ``~/heading_ready``) is
published again at each activation; inactive, nothing is published.

Parameter changes: while unconfigured they are stored (each value checked on its own);
while configured an alignment parameter restarts the session, as in the plain node.
"""
import sys
import time
from collections import Counter

from lifecycle_msgs.msg import Transition
from rcl_interfaces.msg import SetParametersResult
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rclpy.timer import Timer

from .alignment_node import AlignmentShell
from .runner import make_executor, run

SUCCESS = TransitionCallbackReturn.SUCCESS
FAILURE = TransitionCallbackReturn.FAILURE
#: lifecycle_msgs/Transition's ids by name, for the refusals
_TRANSITIONS = {v: k[len('TRANSITION_'):].lower() for k, v in vars(Transition).items()
                if k.startswith('TRANSITION_') and isinstance(v, int)}


class AlignmentLifecycleNode(AlignmentShell, LifecycleNode):
    """The alignment node as a managed node; see the module docstring."""

    def __init__(self, **kwargs):
        super().__init__('alignment_node', **kwargs)
        self._declare_params(check=False)
        self.pub_imu = self.pub_euler = self.pub_diag = self.pub_odom = None
        self._inputs = []       # subscriptions (active)
        self._outputs = []      # ~/reset and the timers (configured)
        self.counts = {'imu': 0}
        self.received = Counter()
        self.typed = None
        # refuse a transition the state does not have instead of raising (rclpy's handler)
        srv = self._service_change_state
        self._rclpy_change_state, srv.callback = srv.callback, self._on_change_state

    def _on_change_state(self, request, response):
        """``~/change_state``: refuse (``success=false``, reason logged) what the state lacks."""
        current = self._state_machine.current_state[1]
        possible = self._state_machine.available_transitions    # (id, label, ...) of the state
        t = request.transition
        if not any(t.label == p[1] if t.label else t.id == p[0] for p in possible):
            asked = f"'{t.label}'" if t.label else f'{_TRANSITIONS.get(t.id, "id")} ({t.id})'
            reason = (f"transition {asked} refused: not possible from state '{current}' "
                      f"(possible: {', '.join(f'{p[1]} ({p[0]})' for p in possible) or 'none'})")
        else:
            try:
                return self._rclpy_change_state(request, response)
            except _rclpy.RCLError as exc:    # the state machine refused it after all
                reason = f'transition refused in state {current!r}: {exc}'
        self.get_logger().warn(reason)
        response.success = False
        return response

    # -- transitions -------------------------------------------------------------------------
    def on_configure(self, state):
        """Build the session from the parameters; create the publishers, ~/reset, timers."""
        bad = self.params.refused()
        try:
            if bad:
                raise ValueError(bad)
            self._start_session()
        except ValueError as exc:
            self.session = None
            self.get_logger().error(f'configure refused: {exc}')
            return FAILURE
        self._outputs = self._create_outputs(self.create_lifecycle_publisher)
        self._log_start()
        return SUCCESS

    def on_activate(self, state):
        """Activate the publishers, subscribe to the input, publish the typed status."""
        ret = super().on_activate(state)          # the managed publishers
        if ret == SUCCESS:
            self._inputs = self._subscribe()
            self._last_imu_wall = time.monotonic()      # the input (re)starts now
            self.typed.forget()
            self._update_typed()
        return ret

    def on_deactivate(self, state):
        """Unsubscribe, publish what the waiting batch gives, deactivate the publishers."""
        self._unsubscribe()
        self._flush_imu()
        return super().on_deactivate(state)

    def on_cleanup(self, state):
        """Destroy the publishers, ~/reset and the timers; drop the session."""
        self._teardown()
        return SUCCESS

    def on_shutdown(self, state):
        """Tear down whatever exists, from any state."""
        self._teardown()
        return SUCCESS

    def on_error(self, state):
        """Tear down whatever exists; the node goes back to unconfigured."""
        self.get_logger().error(f'a transition from {state.label} failed; cleaning up')
        self._teardown()
        return SUCCESS

    def _unsubscribe(self):
        for sub in self._inputs:
            self.destroy_subscription(sub)
        self._inputs = []

    def _teardown(self):
        self._unsubscribe()
        for name in ('pub_imu', 'pub_euler', 'pub_diag', 'pub_odom'):
            pub = getattr(self, name)
            if pub is not None:
                self.destroy_lifecycle_publisher(pub)
                setattr(self, name, None)
        for pub in self.typed.publishers() if self.typed is not None else ():
            self.destroy_lifecycle_publisher(pub)
        self.typed = None
        for entity in self._outputs:
            if isinstance(entity, Timer):
                self.destroy_timer(entity)
            else:
                self.destroy_service(entity)
        self._outputs = []
        self.session = None

    # -- the shell's hooks -------------------------------------------------------------------
    def _check_pipeline_params(self, changes):
        if self.session is None:      # unconfigured: stored; configure checks them together
            return SetParametersResult(successful=True)
        return super()._check_pipeline_params(changes)

    def _publishing(self):
        return self.pub_diag is not None and self.pub_diag.is_activated

    def _publish_diagnostics(self):
        """Publish the diagnostics while active; inactive, keep the period for later."""
        if self._publishing():
            super()._publish_diagnostics()


def main(args=None):
    """Entry point of ``ros2 run sins_align_ros alignment_lifecycle_node``."""
    return run(AlignmentLifecycleNode, 'alignment_lifecycle_node', make_executor, args=args)


if __name__ == '__main__':
    sys.exit(main())

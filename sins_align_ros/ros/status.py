"""The alignment node's typed status: ``~/phase``, ``~/reason``, ``~/*_ready``.

A consumer subscribes to these instead of parsing ``/diagnostics`` strings. Each is
published once when the node's outputs start and then only when its value changes, with
QoS reliable, transient local, depth 1: a subscriber that comes later still gets the
current value.

* ``~/phase`` (std_msgs/String): ``waiting``, ``coarse``, ``fine`` or ``aligned`` (the
  four of the CSV contract). While no IMU message has come for ``max(2 s, 3 diagnostic
  periods)`` an ``aligned`` pipeline is published as ``fine``: the attitude is no longer
  being kept up.
* ``~/reason`` (std_msgs/String): why the phase is not ``aligned``, '' when it is:
  ``waiting for IMU data``, ``coarse alignment``, the pipeline's ``not_aligned_reason`` in
  ``fine``, and ``no IMU data`` while the input has stopped.
* ``~/tilt_ready``, ``~/heading_ready`` (std_msgs/Bool): the roll/pitch (heading)
  1-sigma within the ``aligned`` bounds (``aligned_max_*_sigma_deg``); false before fine
  alignment and while the input has stopped.

The values (:func:`~sins_align_ros.io.node_status.typed_state`) and what ``~/euler``
publishes (:func:`~sins_align_ros.io.node_status.known_euler`) are plain arithmetic in
:mod:`sins_align_ros.io.node_status`, which the replay's result bag shares.
"""
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, String

#: the typed topics' QoS: the last value kept for late subscribers
LATCHED = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
_TOPICS = (('phase', String), ('reason', String), ('tilt_ready', Bool),
           ('heading_ready', Bool))


class TypedStatus:
    """The four latched publishers; :meth:`update` publishes the values that changed."""

    def __init__(self, create_publisher):
        self.pubs = {name: (create_publisher(kind, f'~/{name}', LATCHED), kind)
                     for name, kind in _TOPICS}
        self.last = {}

    def forget(self):
        """Publish every value again at the next :meth:`update` (outputs (re)started)."""
        self.last = {}

    def update(self, values):
        """Publish each of ``values`` (``typed_state``) that differs from the last sent."""
        for name, value in values.items():
            if self.last.get(name) != value:
                pub, kind = self.pubs[name]
                pub.publish(kind(data=value))
                self.last[name] = value

    def publishers(self):
        """Return the four publishers: a managed node destroys them at cleanup."""
        return [pub for pub, _ in self.pubs.values()]

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

:func:`known_euler` is what ``~/euler`` publishes: the Euler angles with NaN for an angle
whose variance is that of an unknown angle.
"""
import numpy as np
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, String

from ..align import HEADING_UNKNOWN_VAR

#: the typed topics' QoS: the last value kept for late subscribers
LATCHED = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: a variance at least this is an unknown angle's (pi^2 / 3 rad^2, less round-off)
UNKNOWN_VAR = HEADING_UNKNOWN_VAR * (1.0 - 1e-9)
_TOPICS = (('phase', String), ('reason', String), ('tilt_ready', Bool),
           ('heading_ready', Bool))
_REASONS = {'waiting': 'waiting for IMU data', 'coarse': 'coarse alignment'}
#: the reason published while the IMU input has stopped
NO_IMU = 'no IMU data'


def imu_stopped(imu_age, period):
    """Tell whether ``imu_age`` s since the last IMU message (None: none yet) means stopped."""
    return imu_age is not None and imu_age > max(2.0, 3.0 * period)


def typed_state(s, stopped):
    """Return ``{'phase', 'reason', 'tilt_ready', 'heading_ready'}`` from pipeline status ``s``.

    ``stopped``: the IMU input has stopped (:func:`imu_stopped`).
    """
    phase = s['phase']
    reason = _REASONS.get(phase) or s.get('not_aligned_reason', '')
    tilt, heading = bool(s.get('tilt_ready', False)), bool(s.get('heading_ready', False))
    if stopped:
        phase = 'fine' if phase == 'aligned' else phase
        reason, tilt, heading = NO_IMU, False, False
    elif phase == 'aligned':
        reason = ''
    return {'phase': phase, 'reason': reason, 'tilt_ready': tilt, 'heading_ready': heading}


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
        """Publish each of ``values`` (:func:`typed_state`) that differs from the last sent."""
        for name, value in values.items():
            if self.last.get(name) != value:
                pub, kind = self.pubs[name]
                pub.publish(kind(data=value))
                self.last[name] = value

    def publishers(self):
        """Return the four publishers: a managed node destroys them at cleanup."""
        return [pub for pub, _ in self.pubs.values()]


def known_euler(out):
    """Return the Euler angles (N, 3) of output rows ``out`` with NaN where unknown.

    Yaw is NaN where the misalignment variance about up (``P_phi[2, 2]``) is the unknown
    angle's (:data:`~sins_align_ros.align.output.HEADING_UNKNOWN_VAR`, pi^2/3: a heading
    the sensors cannot observe); roll and pitch are NaN where the east or north one is
    (the IMU's attitude is not the vehicle's: an untold mounting).
    """
    euler = out.euler
    var = np.diagonal(out.P_phi, axis1=1, axis2=2)
    yaw = var[:, 2] >= UNKNOWN_VAR
    tilt = (var[:, :2] >= UNKNOWN_VAR).any(axis=1)
    if not (yaw.any() or tilt.any()):
        return euler
    euler = euler.copy()
    euler[yaw, 2] = np.nan
    euler[tilt, :2] = np.nan
    return euler

"""What the alignment node's typed status and ``~/euler`` say, as plain values (no rclpy).

The node (:mod:`sins_align_ros.ros.status`) publishes them; the replay's result bag
(:mod:`.result_bag`) writes the same values. The topics' meaning is
docs/alignment_node.md's:

* ``~/phase``: ``waiting``, ``coarse``, ``fine`` or ``aligned``; while the IMU input has
  stopped an ``aligned`` pipeline is said as ``fine``;
* ``~/reason``: why the phase is not ``aligned``, '' when it is;
* ``~/tilt_ready``, ``~/heading_ready``: the 1-sigma within the ``aligned`` bounds;
* ``~/euler``: the Euler angles with NaN for an angle the node does not know
  (:func:`known_euler`).
"""
import numpy as np

from ..align import HEADING_UNKNOWN_VAR

#: a variance at least this is an unknown angle's (pi^2 / 3 rad^2, less round-off)
UNKNOWN_VAR = HEADING_UNKNOWN_VAR * (1.0 - 1e-9)
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

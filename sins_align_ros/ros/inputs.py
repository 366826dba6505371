"""The alignment node's input: subscriptions with their QoS, messages into session calls.

* ``imu/data_raw`` (sensor_msgs/Imu): best effort with a deep queue (:data:`IMU_QOS`), so
  that it takes both best-effort and reliable publishers; taken as serialized bytes
  (``raw=True``) and
  decoded by the batch (:mod:`.imu_wire`). The node queues the messages and hands a batch
  to :func:`feed_imu` after ``imu_batch_period`` of waiting (at 1 kHz ten samples go
  through the input checks and the compiled filters at once, which took the node from
  0.39 to 0.22 cores with ``asckf``, bench/results/node_load.md); a GNSS message, a
  parameter change, a reset or the period's timer hands it over first.
* ``gnss/fix`` (sensor_msgs/NavSatFix), ``gnss/vel`` (geometry_msgs/
  TwistWithCovarianceStamped, ENU; used by the GNSS-aided filters) and ``heading/in``
  (sensor_msgs/Imu: an external heading, the yaw of its orientation and
  ``orientation_covariance[8]``; docs/installation.md): best effort, depth 50; each
  message becomes the arguments of the session's entry (:func:`fix_args`,
  :func:`velocity_args`, :func:`heading_args`).

Every check and restart rule is the session's (:class:`~sins_align_ros.align.session.
AlignmentSession`); here only what needs the message: bytes nothing decodes and a
``frame_id`` other than ``imu_frame_id`` are refused through the session, so that they
are counted with the rest.
"""
from geometry_msgs.msg import TwistWithCovarianceStamped
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, NavSatFix

from ..io import cdr
from ..nav.frames import quat_to_yaw
from .conversions import stamp_to_sec
from .imu_wire import ImuRows

#: 5 s of a 1 kHz IMU: the callback that ends a still base's coarse window runs the fine
#: filter over the stored window (0.7 s for 60 s at 1 kHz on the node,
#: bench/results/node_catch_up.md), and no sample may be dropped meanwhile
IMU_QOS = QoSProfile(depth=5000, reliability=ReliabilityPolicy.BEST_EFFORT,
                     history=HistoryPolicy.KEEP_LAST)
GNSS_QOS = QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT,
                      history=HistoryPolicy.KEEP_LAST)


def subscribe(node, on_imu, on_fix, on_vel, on_heading):
    """Subscribe ``node`` to the four input topics with these callbacks; return them."""
    return [node.create_subscription(Imu, 'imu/data_raw', on_imu, IMU_QOS, raw=True),
            node.create_subscription(NavSatFix, 'gnss/fix', on_fix, GNSS_QOS),
            node.create_subscription(TwistWithCovarianceStamped, 'gnss/vel', on_vel,
                                     GNSS_QOS),
            node.create_subscription(Imu, 'heading/in', on_heading, GNSS_QOS)]


def fix_args(msg):
    """Return ``AlignmentSession.fix``'s arguments from a NavSatFix (unknown covariance: None)."""
    c = msg.position_covariance
    pos_var = (None if msg.position_covariance_type == NavSatFix.COVARIANCE_TYPE_UNKNOWN
               else (c[0], c[4]))
    return (stamp_to_sec(msg.header.stamp), msg.status.status, msg.latitude, msg.longitude,
            msg.altitude, pos_var)


def velocity_args(msg):
    """Return ``AlignmentSession.velocity``'s arguments from a TwistWithCovarianceStamped."""
    v, c = msg.twist.twist.linear, msg.twist.covariance
    return stamp_to_sec(msg.header.stamp), (v.x, v.y, v.z), (c[0], c[7])


def heading_args(msg):
    """Return ``AlignmentSession.heading``'s arguments: the yaw and its variance (REP-145).

    A variance of zero is unknown (``heading_sigma_deg`` is used); ``orientation_covariance
    [0] = -1``: the message carries no orientation.
    """
    o, c = msg.orientation, msg.orientation_covariance
    var = None if c[8] == 0.0 else c[8]
    return (stamp_to_sec(msg.header.stamp), quat_to_yaw((o.x, o.y, o.z, o.w)), var,
            c[0] != -1.0)


def feed_imu(session, raws, frame_id):
    """Decode serialized Imu messages ``raws`` and run the usable ones through ``session``.

    ``frame_id``: the ``imu_frame_id`` every message must carry ('' any). Returns
    ``(batch, out, usable, accepted)``: the :class:`~.imu_wire.ImuRows` of the samples
    given to the session (those marked missing dropped), the session's output rows (None
    when nothing was given), the messages that passed the input checks and the samples
    the session accepted.
    """
    batch = ImuRows(raws)
    _refuse(session, batch, frame_id)
    if not len(batch):
        return batch, None, 0, 0
    missing = batch.missing
    rejected, accepted = session.imu_rejected, session.imu_accepted
    w_b, f_b = batch.body[:, cdr.IMU_RATE], batch.body[:, cdr.IMU_ACCELERATION]
    if len(batch) == 1 and not missing[0]:       # the one-sample path costs less
        out = session.imu(batch.t[0], w_b[0], f_b[0])
    else:
        out = session.imu_block(batch.t, w_b, f_b, missing if missing.any() else None)
    usable = len(batch) - (session.imu_rejected - rejected)
    if missing.any():
        batch.select(~missing)
    return batch, out, usable, session.imu_accepted - accepted


def _refuse(session, batch, frame_id):
    """Count and drop the messages of ``batch`` that cannot be used (bytes, frame)."""
    keep = ~batch.bad
    for _ in range(int(batch.bad.sum())):
        session.reject_imu('undecodable', 'message bytes not a decodable '
                                          'sensor_msgs/Imu: sample skipped')
    if frame_id:
        for i, fid in enumerate(batch.frame_ids()):
            if keep[i] and fid != frame_id:
                keep[i] = False
                session.reject_imu('wrong_frame', f"frame_id '{fid}' is not "
                                                  f"'{frame_id}': sample skipped")
    if not keep.all():
        batch.select(keep)

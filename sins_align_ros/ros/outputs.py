"""The alignment node's publishers and the messages it publishes at the IMU rate.

* ``imu/data`` (sensor_msgs/Imu): the input rates plus the orientation body -> ENU with
  ``orientation_covariance`` = the filter's misalignment covariance about the ENU axes
  (rad^2); until coarse alignment is done the orientation is marked unknown
  (``orientation_covariance[0] = -1``, REP-145). With ``imu_mounting_rpy_deg`` set, the
  body is the vehicle: rates, accelerations and their covariances are turned into its
  frame and the frame_id is ``base_frame_id``. Built from the input's bytes
  (:mod:`.imu_wire`, :func:`~sins_align_ros.io.cdr.echo_bodies`);
* ``~/euler`` (geometry_msgs/Vector3Stamped): REP-103 roll, pitch, yaw in rad; NaN for
  an angle the node does not know (yaw while the heading is unobservable,
  :func:`~sins_align_ros.io.node_status.known_euler`); built only while someone subscribes;
* ``~/odom`` (nav_msgs/Odometry) with the navigation filters (``kf``, ``vbakf``,
  ``mvbakf``, ``ukf``) and ``continue_navigation``: the GNSS/INS solution at every IMU
  sample from the start of fine alignment on, pose in ``odom_frame_id`` (ENU, origin
  where fine alignment started: ``odom_origin_*`` in the diagnostics), twist in the
  body's frame, the same as ``imu/data``'s (:mod:`~sins_align_ros.io.odometry`);
* ``/diagnostics`` (diagnostic_msgs/DiagnosticArray, :mod:`.diagnostics`) and the typed
  status (:mod:`.status`) have their own modules; :func:`create_publishers` makes the
  four plain publishers.

Each output row is published with the header of the received sample it refers to (with
pre-processing an earlier one than the batch's): :class:`RowPublisher` keeps the recent
samples for that.
"""
from collections import deque

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu

from ..io import cdr
from ..io.cdr import echo_bodies
from ..io.node_status import known_euler
from ..io.odometry import OdometryFrame, odometry_bodies
from .conversions import set_vector3
from .imu_wire import header_message


def create_publishers(create_publisher):
    """Return the publishers of ``imu/data``, ``~/euler``, ``~/odom`` and ``/diagnostics``.

    ``create_publisher``: the node's (``create_lifecycle_publisher`` for a managed node).
    """
    return (create_publisher(Imu, 'imu/data', 50),
            create_publisher(Vector3Stamped, '~/euler', 50),
            create_publisher(Odometry, '~/odom', 50),
            create_publisher(DiagnosticArray, '/diagnostics', 10))


class RowPublisher:
    """Publishes ``imu/data``, ``~/euler`` and ``~/odom`` for the session's output rows.

    ``p``: the node's parameter values (read at each use: ``base_frame_id``,
    ``odom_frame_id`` take effect at once).
    """

    def __init__(self, pub_imu, pub_euler, pub_odom, p):
        self.pub_imu, self.pub_euler, self.pub_odom, self.p = pub_imu, pub_euler, pub_odom, p
        #: recent (stamp, head, body): with pre-processing an output refers to an earlier
        #: sample, published with that sample's header
        self.recent = deque(maxlen=4 * 4096 + 64)
        #: the ``~/odom`` origin; a restart starts a new one (:meth:`restart`)
        self.odom = OdometryFrame()
        self._odom_heads = {}                 # (frame, Imu header's frame part): ~/odom's
        self._euler = Vector3Stamped()        # re-used: publish serialises at the call

    def restart(self):
        """Forget the ``~/odom`` origin: the alignment restarted."""
        self.odom = OdometryFrame()

    def take(self, batch, C_s_v):
        """Keep the samples of ``batch`` (:class:`~.imu_wire.ImuRows`) for the rows to come.

        ``C_s_v`` (3, 3) or None: the session's mounting rotation; with one the samples are
        turned into the vehicle frame, ``base_frame_id`` their frame.
        """
        if C_s_v is not None:
            batch.to_vehicle_frame(C_s_v, self.p['base_frame_id'])
        self.recent.extend(batch.rows())

    def publish(self, out, navigation):
        """Publish ``imu/data`` (and ``~/euler``, ``~/odom``) for each row of ``out``.

        Each row refers to the received sample with its stamp, whose header and rates it
        carries. ``navigation()``: the session's
        :class:`~sins_align_ros.align.session.NavReadout`, asked for when rows carry a
        navigation solution.
        """
        recent, srcs = self.recent, []
        for t_k in out.t.tolist():
            while len(recent) > 1 and recent[0][0] < t_k - 1e-9:
                recent.popleft()
            srcs.append(recent[0])
        bodies = echo_bodies([s[2] for s in srcs], out.q, out.P_phi)
        publish = self.pub_imu.publish
        for (_, head, _), body in zip(srcs, bodies):
            publish(head + body.tobytes())
        if self.pub_euler.get_subscription_count():     # none: not built
            euler = known_euler(out)
            for k, (_, head, _) in enumerate(srcs):
                if np.isfinite(out.q[k, 0]):
                    self._euler.header = header_message(head)
                    set_vector3(self._euler.vector, euler[k])
                    self.pub_euler.publish(self._euler)
        if out.nav is not None:
            self._publish_odom(srcs, bodies[:, cdr.IMU_RATE], out, navigation())

    def _publish_odom(self, srcs, w_b, out, nav):
        """Publish ``~/odom`` for the rows of ``out`` (``srcs`` their samples, rates ``w_b``).

        No GNSS update happens inside a batch (a GNSS message flushes it first), so the
        filter's covariance and bias at its end (``nav``) serve every row.
        """
        ok, odo = self.odom.samples(out, nav.P_nav, w_b, nav.gyro_bias, nav.rate_var)
        if odo is None:
            return
        publish, frame = self.pub_odom.publish, self.p['odom_frame_id']
        rows = iter(odometry_bodies(odo))
        for (_, head, _), k in zip(srcs, ok.tolist()):
            if k:
                publish(self._odom_head(head, frame) + next(rows).tobytes())

    def _odom_head(self, imu_head, frame_id):
        """Return ``~/odom``'s serialized start for the sample whose Imu starts ``imu_head``.

        Its stamp, ``frame_id`` and the sample's frame as the child frame; the part after
        the stamp is the same for every sample of a frame, so it is made once.
        """
        end = cdr.STAMP.stop
        key = (frame_id, imu_head[end:])
        rest = self._odom_heads.get(key)
        if rest is None:
            if len(self._odom_heads) > 64:           # frame ids that keep changing
                self._odom_heads.clear()
            child = cdr.header_fields(imu_head)[2]
            rest = self._odom_heads[key] = cdr.odometry_head(bytes(8), frame_id, child)[end:]
        return imu_head[:end] + rest

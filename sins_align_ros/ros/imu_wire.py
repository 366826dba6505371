"""The alignment node's IMU messages as serialized bytes: decoded by the batch, echoed.

The node subscribes ``imu/data_raw`` with ``raw=True``: rclpy hands over each message's
CDR bytes without building a Python message object, a batch of them is decoded with a
few numpy views (:func:`~sins_align_ros.io.cdr.imu_bodies`), and every ``imu/data``
message is the input's bytes with the orientation and its covariance written over
(published as bytes, serialized by nobody). At 1 kHz the two conversions between
messages and Python objects were most of what the node cost above the rmw's own work
(bench/results/node_load.md: a relay of Imu objects against one of bytes).

Messages the fixed layout does not fit (big-endian CDR) take rclpy's general
deserialiser; bytes that nothing decodes are refused with a reason, never a crash.
"""
import numpy as np
from builtin_interfaces.msg import Time
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu
from std_msgs.msg import Header

from ..io import cdr


class ImuRows:
    """A batch of serialized Imu messages, decoded.

    ``t`` (N,) stamps, s; ``body`` (N, 37) each message's doubles from ``orientation`` on
    (columns ``cdr.IMU_*``); ``head`` N bytes, each message's serialized start (its
    encapsulation, header and padding: ``head[i] + body[i].tobytes()`` is message ``i``);
    ``bad`` (N,) True for bytes nothing could decode (their rows are NaN).
    """

    def __init__(self, raws):
        self.t, self.body, a0, ok = cdr.imu_bodies(raws)
        self.head = [r[:4 + a] for r, a in zip(raws, a0.tolist())]
        self.bad = ~ok
        for i in np.flatnonzero(self.bad):          # big-endian or broken: the general way
            self._deserialize(i, raws[i])

    def _deserialize(self, i, raw):
        try:
            m = deserialize_message(raw, Imu)
        except Exception:                           # noqa: BLE001 - any bytes may arrive
            return
        s = m.header.stamp
        stamp = int(s.sec).to_bytes(4, 'little', signed=True) + int(s.nanosec).to_bytes(
            4, 'little')
        self.t[i] = s.sec + s.nanosec * 1e-9
        o, w, f = m.orientation, m.angular_velocity, m.linear_acceleration
        self.body[i] = np.r_[(o.x, o.y, o.z, o.w), m.orientation_covariance, (w.x, w.y, w.z),
                             m.angular_velocity_covariance, (f.x, f.y, f.z),
                             m.linear_acceleration_covariance]
        self.head[i] = cdr.header_bytes(stamp, m.header.frame_id)
        self.bad[i] = False

    def __len__(self):
        return len(self.t)

    @property
    def missing(self):
        """(N,) bool: rate or acceleration marked not provided (covariance[0] = -1, REP-145)."""
        return cdr.imu_missing(self.body)

    def frame_ids(self):
        """Return the N frame ids (str)."""
        return [cdr.header_fields(h)[2] for h in self.head]

    def select(self, keep):
        """Keep the rows where ``keep`` (N,) bool is True."""
        idx = np.flatnonzero(keep)
        self.t, self.body, self.bad = self.t[idx], self.body[idx], self.bad[idx]
        self.head = [self.head[i] for i in idx]

    def to_vehicle_frame(self, C_s_v, frame_id):
        """Turn rates, accelerations and their covariances by ``C_s_v`` (3, 3) IMU -> vehicle.

        ``frame_id`` (``base_frame_id``) replaces the IMU's in every header.
        """
        b = self.body
        for vec, cov in ((cdr.IMU_RATE, cdr.IMU_RATE_COV),
                         (cdr.IMU_ACCELERATION, cdr.IMU_ACCELERATION_COV)):
            b[:, vec] = b[:, vec] @ C_s_v.T
            P = b[:, cov].reshape(-1, 3, 3)
            b[:, cov] = (C_s_v @ P @ C_s_v.T).reshape(-1, 9)
        self.head = [cdr.header_bytes(h[cdr.STAMP], frame_id) for h in self.head]

    def rows(self):
        """Return ``[(t, head, body row)]``: what an output row refers back to."""
        return list(zip(self.t.tolist(), self.head, self.body))


def header_message(head):
    """Return the ``std_msgs/Header`` of a serialized message's start ``head``."""
    sec, nsec, frame_id = cdr.header_fields(head)
    return Header(stamp=Time(sec=sec, nanosec=nsec), frame_id=frame_id)

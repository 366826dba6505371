"""What reading a rosbag2 gives: :class:`BagEvent` and :class:`BagRecording`.

Their own module so that both readers, the general one (:mod:`.bag`, ``rosbags``) and the
sqlite3 fast path (:mod:`.bag_db3`), build them without importing each other.
"""
from dataclasses import dataclass

import numpy as np


@dataclass
class BagEvent:
    """One message in stamp order: ``kind`` is 'imu', 'fix', 'vel' or 'truth'; ``t`` its stamp (s).

    ``data``: imu ``(w, f, frame_id, missing)`` with ``missing`` true when the
    message marks its angular velocity or acceleration as not provided
    (covariance[0] = -1); fix ``(status, lat_deg, lon_deg, h, pos_var)``
    with ``pos_var`` (east, north) m^2 as reported, or None when the covariance type
    is unknown; vel ``(v_enu, vel_var)`` with ``vel_var`` (east, north) (m/s)^2 as
    reported (checked by :class:`~sins_align_ros.align.inputs.gnss_input.GnssInput`);
    truth ``(q_xyzw,)``.
    """

    kind: str
    t: float
    data: tuple


@dataclass
class BagRecording:
    """A bag read at once: the IMU as arrays, everything else as :class:`BagEvent`.

    ``t`` (N,), ``w`` (N, 3), ``f`` (N, 3) and ``missing`` (N,) are the IMU messages in
    recording order (as :func:`~.bag.iter_bag`'s imu events; ``frame_id`` is not kept);
    ``events`` the fix, velocity and truth messages in recording order and
    ``imu_before`` (len(events),) how many IMU messages came before each, so that the
    two interleave exactly as recorded. ``error``: why reading stopped early (a
    truncated or corrupt bag: what came before is kept), else None.
    """

    t: np.ndarray
    w: np.ndarray
    f: np.ndarray
    missing: np.ndarray
    events: list
    imu_before: np.ndarray
    error: str = None

"""Bulk decoding of serialized ``sensor_msgs/msg/Imu`` (CDR, as rosbag2 stores it).

An Imu message has a fixed layout once its ``header.frame_id`` length is known, so a
whole recording is decoded with a few numpy views instead of one Python object per
message (``rosbags`` deserialises about 40,000 messages a second; this, millions).

Layout (OMG CDR, little endian, after the 4-byte encapsulation header; offsets relative
to the end of that header, doubles aligned to 8 there)::

    0   int32   header.stamp.sec
    4   uint32  header.stamp.nanosec
    8   uint32  len(frame_id) + 1, then the characters and a NUL
    a0  = align8(12 + that length)
    a0 +   0  orientation (4 doubles)          a0 +  32  orientation_covariance (9)
    a0 + 104  angular_velocity (3)             a0 + 128  angular_velocity_covariance (9)
    a0 + 200  linear_acceleration (3)          a0 + 224  linear_acceleration_covariance (9)
    a0 + 296  end

Messages that do not fit (big-endian CDR, a length that disagrees with the layout) are
left to the caller's general decoder: :func:`decode_imu` says which.
"""
import numpy as np

#: encapsulation header of little-endian plain CDR
CDR_LE = (0x00, 0x01)
#: bytes of the message body after the aligned start of ``orientation``
_BODY = 296


def decode_imu(raws):
    """Decode a list of serialized Imu messages (bytes, in order).

    Returns ``(t, w, f, missing, ok)``: stamp (N,) s, angular velocity (N, 3) rad/s,
    linear acceleration (N, 3) m/s^2, ``missing`` (N,) True where the message marks its
    angular velocity or acceleration as not provided (covariance[0] = -1), and ``ok``
    (N,) False for messages not decoded here (their rows are NaN; decode them with the
    general deserialiser). ``frame_id`` is not returned.
    """
    n = len(raws)
    t = np.full(n, np.nan)
    w = np.full((n, 3), np.nan)
    f = np.full((n, 3), np.nan)
    missing = np.zeros(n, dtype=bool)
    ok = np.zeros(n, dtype=bool)
    lens = np.fromiter(map(len, raws), dtype=np.int64, count=n)
    for size in np.unique(lens):
        a0 = int(size) - 4 - _BODY
        if a0 < 16:
            continue
        idx = np.flatnonzero(lens == size)
        buf = np.frombuffer(b''.join([raws[k] for k in idx]), dtype=np.uint8)
        buf = buf.reshape(len(idx), int(size))
        n_id = buf[:, 12:16].copy().view('<u4')[:, 0].astype(np.int64)
        fits = ((buf[:, 0] == CDR_LE[0]) & (buf[:, 1] == CDR_LE[1])
                & (((12 + n_id + 7) & ~7) == a0))
        idx, buf = idx[fits], buf[fits]
        sec = buf[:, 4:8].copy().view('<i4')[:, 0]
        nsec = buf[:, 8:12].copy().view('<u4')[:, 0]
        t[idx] = sec.astype(float) + nsec.astype(float) * 1e-9
        body = buf[:, 4 + a0:].copy().view('<f8')                    # 37 doubles per row
        w[idx] = body[:, 13:16]
        f[idx] = body[:, 25:28]
        missing[idx] = (body[:, 16] == -1.0) | (body[:, 28] == -1.0)
        ok[idx] = True
    return t, w, f, missing, ok

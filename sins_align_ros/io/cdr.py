"""Bulk decoding of serialized Imu, NavSatFix, TwistWithCovarianceStamped and Odometry.

The messages are CDR as rosbag2 stores them. The same layouts serve the other way for
the node's ``imu/data`` and ``~/odom`` (:func:`echo_bodies`, :func:`header_bytes`,
:func:`odometry_head`), which the replay's result bag writes too.

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
left to the caller's general decoder: each decoder says which.

Every decoder (:func:`decode_imu`, :func:`decode_fix`, :func:`decode_twist`,
:func:`decode_odometry_q`) groups the messages by length and reads each row's fields at
offsets computed from its own string lengths (``_Rows``): a frame id of any length, and a
serializer's trailing padding of up to 3 bytes, are taken.
"""
import numpy as np

#: encapsulation header of little-endian plain CDR
CDR_LE = (0x00, 0x01)
#: bytes of the message body after the aligned start of ``orientation``
_BODY = 296
#: the bytes of ``header.stamp`` (sec, nanosec) in a serialized message; what follows
#: depends only on the frame id (and, for Odometry, the child frame id)
STAMP = slice(4, 12)

#: columns of :func:`imu_bodies`' rows: orientation (x, y, z, w), its covariance (9),
#: angular velocity (3), its covariance, linear acceleration (3), its covariance
IMU_ORIENTATION, IMU_ORIENTATION_COV = slice(0, 4), slice(4, 13)
IMU_RATE, IMU_RATE_COV = slice(13, 16), slice(16, 25)
IMU_ACCELERATION, IMU_ACCELERATION_COV = slice(25, 28), slice(28, 37)
#: doubles in an Imu body (from ``orientation`` on)
IMU_DOUBLES = _BODY // 8


def decode_imu(raws):
    """Decode a list of serialized Imu messages (bytes, in order).

    Returns ``(t, w, f, missing, ok)``: stamp (N,) s, angular velocity (N, 3) rad/s,
    linear acceleration (N, 3) m/s^2, ``missing`` (N,) True where the message marks its
    angular velocity or acceleration as not provided (covariance[0] = -1), and ``ok``
    (N,) False for messages not decoded here (their rows are NaN; decode them with the
    general deserialiser). ``frame_id`` is not returned.
    """
    t, body, _, ok = imu_bodies(raws)
    missing = ok & imu_missing(body)
    return t, body[:, IMU_RATE], body[:, IMU_ACCELERATION], missing, ok


def imu_missing(body):
    """(N,) True where a body (N, 37) marks its rate or acceleration not provided (REP-145)."""
    return (body[:, IMU_RATE_COV.start] == -1.0) | (body[:, IMU_ACCELERATION_COV.start] == -1.0)


def imu_bodies(raws):
    """Decode serialized Imu messages (list of bytes) into their fixed-layout bodies.

    Returns ``(t, body, a0, ok)``: stamp (N,) s; ``body`` (N, 37) the doubles from
    ``orientation`` on (:data:`IMU_ORIENTATION` ... :data:`IMU_ACCELERATION_COV`
    slices); ``a0`` (N,) int, the body offset where they start (the bytes before
    ``4 + a0`` are the encapsulation, the header and its padding); ``ok`` as in
    :func:`decode_imu` (rows not decoded are NaN, ``a0`` 0).
    """
    one = _one_layout(raws)
    if one is not None:
        return one
    n = len(raws)
    t, body = np.full(n, np.nan), np.full((n, IMU_DOUBLES), np.nan)
    a0, ok = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=bool)
    for g in _groups(raws):
        a = _align(g.string_end(np.full(len(g.idx), 8)), 8)
        rows = g.f8(a, IMU_DOUBLES)
        g.ends_at(a + _BODY)
        i, k = g.idx[g.ok], g.ok
        t[i], body[i], a0[i], ok[i] = g.stamp()[k], rows[k], a[k], True
    return t, body, a0, ok


def _one_layout(raws):
    """:func:`imu_bodies` of messages that share one layout (one sensor's stream), or None.

    All of the same length, with the first's encapsulation and ``frame_id`` length: the
    general path's answer from a few slices (a live node's batch is ten messages, where
    the general path's per-group work was most of the decoding).
    """
    first = raws[0] if raws else b''
    size = len(first)
    if type(first) is not bytes or size < 16 or first[:2] != bytes(CDR_LE):
        return None
    a = _align(12 + int.from_bytes(first[12:16], 'little'), 8)
    if not 0 <= size - 4 - (a + _BODY) <= 3:
        return None
    n = len(raws)
    if set(map(len, raws)) != {size}:
        return None
    # one fixed-width bytes array: a copy into fresh memory as b''.join makes, at a third
    # of its time for 120,000 messages (10 against 27 ms)
    rows = np.frombuffer(np.array(raws, dtype=f'S{size}'), dtype=np.uint8).reshape(n, size)
    if not (rows[:, :2] == rows[0, :2]).all() or not (rows[:, 12:16] == rows[0, 12:16]).all():
        return None
    stamp = rows[:, STAMP].copy().view('<u4')
    t = stamp[:, 0].view('<i4').astype(float) + stamp[:, 1] * 1e-9
    body = rows[:, 4 + a:4 + a + _BODY].copy().view('<f8')
    return t, body, np.full(n, a, dtype=np.int64), np.ones(n, dtype=bool)


def echo_bodies(src_bodies, q, P_phi):
    """Return the ``imu/data`` bodies: the inputs' (K, 37) with the attitude written over.

    ``q`` (K, 4) orientation (x, y, z, w), NaN while unknown: then identity with
    ``orientation_covariance[0] = -1`` (REP-145); ``P_phi`` (K, 3, 3) its covariance.
    """
    out = np.array(src_bodies, dtype=float).reshape(-1, IMU_DOUBLES)
    known = np.isfinite(q[:, 0])
    out[:, IMU_ORIENTATION] = np.where(known[:, None], q, (0.0, 0.0, 0.0, 1.0))
    unknown_cov = np.zeros(9)
    unknown_cov[0] = -1.0
    out[:, IMU_ORIENTATION_COV] = np.where(known[:, None], P_phi.reshape(-1, 9), unknown_cov)
    return out


def header_bytes(stamp, frame_id):
    """Serialize a message's start: encapsulation, ``std_msgs/Header``, padding to 8.

    ``stamp``: the 8 bytes of ``sec`` and ``nanosec`` as serialized (little endian);
    ``frame_id`` str. The result followed by a message body whose first field is a
    double (an Imu's ``orientation``) is the whole serialized message.
    """
    body = stamp + _string(frame_id)
    return bytes(CDR_LE) + b'\0\0' + body + bytes(-len(body) % 8)


def odometry_head(stamp, frame_id, child_frame_id):
    """Serialize a ``nav_msgs/Odometry``'s start: encapsulation, header, ``child_frame_id``.

    Padded to 8: followed by the 85 doubles of the pose and twist with their
    covariances it is the whole message (the layout :func:`decode_odometry_q` reads).
    """
    body = stamp + _string(frame_id)
    body += bytes(-len(body) % 4) + _string(child_frame_id)
    return bytes(CDR_LE) + b'\0\0' + body + bytes(-len(body) % 8)


def _string(text):
    """Return a CDR string: its length with the NUL (uint32), the UTF-8 characters, a NUL."""
    raw = text.encode() + b'\0'
    return len(raw).to_bytes(4, 'little') + raw


def header_fields(head):
    """Return ``(sec, nanosec, frame_id)`` of a serialized little-endian message's header."""
    sec = int.from_bytes(head[STAMP][:4], 'little', signed=True)
    nsec = int.from_bytes(head[STAMP][4:], 'little')
    size = int.from_bytes(head[12:16], 'little')
    return sec, nsec, head[16:15 + size].decode(errors='replace')


def _align(x, n):
    return (x + n - 1) & ~(n - 1)


class _Rows:
    """Messages of one byte length as a (N, size) array, with per-row field reads.

    Offsets are relative to the CDR body (after the 4-byte encapsulation header), one
    per row (N,); reads past a row's end give ``ok`` False for that row.
    """

    def __init__(self, raws, idx, size):
        self.idx = idx
        self.size = size
        self.buf = np.frombuffer(b''.join([raws[k] for k in idx]), dtype=np.uint8)
        self.buf = self.buf.reshape(len(idx), size)
        self.ok = (self.buf[:, 0] == CDR_LE[0]) & (self.buf[:, 1] == CDR_LE[1])
        self._r = np.arange(len(idx))[:, None]

    def _bytes(self, off, nbytes):
        """(N, nbytes) uint8 at per-row body offsets ``off`` (N,)."""
        if len(off) and (off == off[0]).all():          # one layout (the usual case): a slice
            if off[0] + 4 + nbytes <= self.size:
                return self.buf[:, off[0] + 4:off[0] + 4 + nbytes]
            self.ok[:] = False
            return np.zeros((len(off), nbytes), np.uint8)
        cols = off[:, None] + 4 + np.arange(nbytes)
        inside = cols[:, -1] < self.size
        self.ok &= inside
        return self.buf[self._r, np.where(inside[:, None], cols, 0)]

    def u32(self, off):
        return self._bytes(off, 4).copy().view('<u4')[:, 0].astype(np.int64)

    def f8(self, off, n):
        return self._bytes(off, 8 * n).copy().view('<f8')

    def u8(self, off):
        return self._bytes(off, 1)[:, 0].astype(np.int64)

    def string_end(self, off):
        """Body offset after a CDR string whose length field is at ``off`` (aligned 4)."""
        off = _align(off, 4)
        return off + 4 + self.u32(off)

    def ends_at(self, end):
        """Rows whose message ends at body offset ``end`` (N,), up to 3 bytes of padding."""
        pad = self.size - 4 - end
        self.ok &= (pad >= 0) & (pad <= 3)

    def stamp(self):
        sec = self._bytes(np.zeros(len(self.idx), dtype=np.int64), 4).copy().view('<i4')[:, 0]
        nsec = self.u32(np.full(len(self.idx), 4))
        return sec.astype(float) + nsec.astype(float) * 1e-9


def _groups(raws):
    """Yield a :class:`_Rows` per distinct message length (at least a header long)."""
    lens = np.fromiter(map(len, raws), dtype=np.int64, count=len(raws))
    for size in np.unique(lens):
        if size >= 16:
            yield _Rows(raws, np.flatnonzero(lens == size), int(size))


def decode_fix(raws):
    """Decode serialized ``sensor_msgs/msg/NavSatFix`` messages (list of bytes).

    Returns ``(t, status, llh, cov, cov_type, ok)``: stamp (N,) s, ``status.status``
    (N,) int, latitude/longitude (deg) and altitude (N, 3), ``position_covariance``
    (N, 9), its type (N,) int, and ``ok`` (N,) False where not decoded (big-endian or
    a length that disagrees with the layout: use the general deserialiser).

    Layout after the header: ``status.status`` int8, ``status.service`` uint16
    (aligned 2), latitude, longitude, altitude, 9 covariance doubles (aligned 8),
    ``position_covariance_type`` uint8.
    """
    n = len(raws)
    t, status, cov_type = np.full(n, np.nan), np.zeros(n, dtype=int), np.zeros(n, dtype=int)
    llh, cov, ok = np.full((n, 3), np.nan), np.full((n, 9), np.nan), np.zeros(n, dtype=bool)
    for g in _groups(raws):
        e0 = g.string_end(np.full(len(g.idx), 8))
        st = g.u8(e0)
        lat = _align(_align(e0 + 1, 2) + 2, 8)
        vals = g.f8(lat, 12)
        ct = g.u8(lat + 96)
        g.ends_at(lat + 97)
        i, k = g.idx[g.ok], g.ok
        t[i], llh[i], cov[i] = g.stamp()[k], vals[k, :3], vals[k, 3:]
        status[i] = np.where(st[k] > 127, st[k] - 256, st[k])
        cov_type[i], ok[i] = ct[k], True
    return t, status, llh, cov, cov_type, ok


def decode_twist(raws):
    """Decode serialized ``geometry_msgs/msg/TwistWithCovarianceStamped`` messages.

    Returns ``(t, v, cov, ok)``: stamp (N,) s, ``twist.twist.linear`` (N, 3), the
    twist covariance (N, 36), ``ok`` (N,) as :func:`decode_fix`. Layout after the
    header: linear (3), angular (3), covariance (36) doubles, aligned 8.
    """
    n = len(raws)
    t, v = np.full(n, np.nan), np.full((n, 3), np.nan)
    cov, ok = np.full((n, 36), np.nan), np.zeros(n, dtype=bool)
    for g in _groups(raws):
        a = _align(g.string_end(np.full(len(g.idx), 8)), 8)
        vals = g.f8(a, 42)
        g.ends_at(a + 336)
        i, k = g.idx[g.ok], g.ok
        t[i], v[i], cov[i], ok[i] = g.stamp()[k], vals[k, :3], vals[k, 6:], True
    return t, v, cov, ok


def decode_odometry_q(raws):
    """Decode the stamp and ``pose.pose.orientation`` of serialized ``nav_msgs/msg/Odometry``.

    Returns ``(t, q_xyzw, ok)``: (N,), (N, 4), (N,) as :func:`decode_fix`. Layout after
    the header: ``child_frame_id`` (string), then position (3), orientation (4), pose
    covariance (36), linear and angular velocity (6) and twist covariance (36) doubles.
    """
    n = len(raws)
    t, q, ok = np.full(n, np.nan), np.full((n, 4), np.nan), np.zeros(n, dtype=bool)
    for g in _groups(raws):
        e1 = g.string_end(g.string_end(np.full(len(g.idx), 8)))
        a = _align(e1, 8)
        vals = g.f8(a + 24, 4)
        g.ends_at(a + 680)
        i, k = g.idx[g.ok], g.ok
        t[i], q[i], ok[i] = g.stamp()[k], vals[k], True
    return t, q, ok

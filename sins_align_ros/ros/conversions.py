"""Conversions between ROS messages and the numpy types of the lower layers."""
from builtin_interfaces.msg import Time


def stamp_to_ns(stamp):
    """Integer nanoseconds of a ``builtin_interfaces/Time``."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def stamp_to_sec(stamp):
    """Seconds (float) of a ``builtin_interfaces/Time``: ``sec + nanosec * 1e-9``."""
    return stamp.sec + stamp.nanosec * 1e-9


def ns_to_stamp(ns):
    """``builtin_interfaces/Time`` from integer nanoseconds."""
    ns = int(ns)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def sec_to_ns(t):
    """Nanoseconds (int) of a time in seconds, rounded to the nearest ns."""
    return int(round(t * 1e9))


def set_vector3(v, xyz):
    """Fill a geometry_msgs Vector3 (or Point) from a length-3 sequence."""
    v.x, v.y, v.z = (float(xyz[0]), float(xyz[1]), float(xyz[2]))
    return v


def set_quaternion(q, xyzw):
    """Fill a geometry_msgs Quaternion from ``(x, y, z, w)``."""
    q.x, q.y, q.z, q.w = (float(c) for c in xyzw)
    return q


def diag_cov(n, diag):
    """Row-major n x n covariance list with ``diag`` on the diagonal."""
    out = [0.0] * (n * n)
    for i, d in enumerate(diag):
        out[i * n + i] = float(d)
    return out

"""The alignment node's serialized IMU path (ros/imu_wire.py) against rclpy's own serializer.

The node takes ``imu/data_raw`` as bytes and publishes ``imu/data`` as bytes; each
conversion here is checked against ``rclpy.serialization`` on messages of every shape
the wire may carry: frame ids of every length mod 8, marked-missing fields, big-endian
CDR (the general deserialiser's path) and bytes that are no Imu at all.
"""
import struct

import numpy as np
import pytest

pytest.importorskip('rclpy')

from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from sensor_msgs.msg import Imu  # noqa: E402

from sins_align_ros.nav.frames import euler_to_dcm  # noqa: E402
from sins_align_ros.io.cdr import echo_bodies  # noqa: E402
from sins_align_ros.ros.imu_wire import ImuRows, header_message  # noqa: E402
from tolerance import assert_roundoff  # noqa: E402

RNG = np.random.default_rng(7)


def _imu(k, frame_id):
    m = Imu()
    m.header.stamp.sec, m.header.stamp.nanosec = 1_700_000_000 + k, 1000 * k + 1
    m.header.frame_id = frame_id
    v = RNG.normal(size=37)
    m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = v[:4]
    m.orientation_covariance = v[4:13]
    m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = v[13:16]
    m.angular_velocity_covariance = v[16:25]
    m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = v[25:28]
    m.linear_acceleration_covariance = v[28:37]
    return m, v


def _big_endian(m, v):
    """``m`` serialized as big-endian CDR (rclpy writes little endian only)."""
    text = m.header.frame_id.encode() + b'\0'
    h = struct.pack('>iIi', m.header.stamp.sec, m.header.stamp.nanosec, len(text)) + text
    return b'\x00\x00\x00\x00' + h + bytes(-len(h) % 8) + struct.pack('>37d', *v)


def _fields(m):
    return np.r_[(m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w),
                 m.orientation_covariance, (m.angular_velocity.x, m.angular_velocity.y,
                                            m.angular_velocity.z),
                 m.angular_velocity_covariance, (m.linear_acceleration.x,
                                                 m.linear_acceleration.y,
                                                 m.linear_acceleration.z),
                 m.linear_acceleration_covariance]


def _batch():
    frames = ['', 'a', 'imu', 'imu_lin', 'imu_link', 'imu_link_1', 'x' * 21, 'imu_link']
    made = [_imu(k, f) for k, f in enumerate(frames)]
    made[3][0].angular_velocity_covariance[0] = -1.0            # REP-145: not provided
    made[3][1][16] = -1.0
    raws = [serialize_message(m) for m, _ in made]
    raws[5] = _big_endian(*made[5])
    raws.insert(2, b'\x00\x01\x00\x00no imu here')
    return made, raws


def test_rows_decode_every_layout_as_rclpy_does_and_refuse_what_is_no_imu():
    made, raws = _batch()
    rows = ImuRows(raws)
    assert rows.bad.tolist() == [k == 2 for k in range(len(raws))]
    assert rows.missing.tolist() == [k == 4 for k in range(len(raws))]
    good = [k for k in range(len(raws)) if k != 2]
    frames = rows.frame_ids()
    for k, (m, v) in zip(good, made):
        assert rows.t[k] == m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
        assert np.array_equal(rows.body[k], v)
        assert frames[k] == m.header.frame_id
        assert header_message(rows.head[k]) == m.header
        # the head and body are the whole message: rclpy reads back the same one
        again = deserialize_message(rows.head[k] + rows.body[k].tobytes(), Imu)
        assert again.header == m.header and np.array_equal(_fields(again), v)
    rows.select(~rows.bad)
    assert len(rows) == len(good) and len(rows.head) == len(good)
    assert rows.frame_ids() == [m.header.frame_id for m, _ in made]


def test_echo_writes_the_attitude_over_the_input_and_marks_it_unknown_per_rep145():
    made, raws = _batch()
    rows = ImuRows([r for k, r in enumerate(raws) if k != 2])
    q = RNG.normal(size=(len(rows), 4))
    q[1] = np.nan                                           # no attitude yet
    P = RNG.normal(size=(len(rows), 3, 3))
    for k, body in enumerate(echo_bodies(list(rows.body), q, P)):
        out = deserialize_message(rows.head[k] + body.tobytes(), Imu)
        m, v = made[k]
        assert out.header == m.header and np.array_equal(_fields(out)[13:], v[13:])
        o = out.orientation
        if k == 1:
            assert (o.x, o.y, o.z, o.w) == (0.0, 0.0, 0.0, 1.0)
            assert list(out.orientation_covariance) == [-1.0] + [0.0] * 8
        else:
            assert np.array_equal((o.x, o.y, o.z, o.w), q[k])
            assert np.array_equal(out.orientation_covariance, P[k].ravel())


def test_vehicle_frame_turns_vectors_and_covariances_and_renames_the_frame():
    made, raws = _batch()
    rows = ImuRows([r for k, r in enumerate(raws) if k != 2])
    C_s_v = euler_to_dcm(np.radians([10.0, -20.0, 135.0]))
    rows.to_vehicle_frame(C_s_v, 'base_link')
    for k, (m, v) in enumerate(made):
        out = deserialize_message(rows.head[k] + rows.body[k].tobytes(), Imu)
        assert out.header.frame_id == 'base_link' and out.header.stamp == m.header.stamp
        w = out.angular_velocity
        # a 3-term dot product (5 operations) on the vector's size, in another order
        assert_roundoff((w.x, w.y, w.z), C_s_v @ v[13:16], 5, np.abs(v[13:16]).max())
        f = out.linear_acceleration
        assert_roundoff((f.x, f.y, f.z), C_s_v @ v[25:28], 5, np.abs(v[25:28]).max())
        P = v[28:37].reshape(3, 3)
        # C P C^T: two 3-term dot products deep (10) on P's size
        assert_roundoff(np.reshape(out.linear_acceleration_covariance, (3, 3)),
                        C_s_v @ P @ C_s_v.T, 10, np.abs(P).max())


def test_odometry_bytes_are_the_message_rclpy_reads():
    from nav_msgs.msg import Odometry as OdometryMsg

    from sins_align_ros.io.cdr import odometry_head
    from sins_align_ros.io.odometry import Odometry, odometry_bodies
    k = 3
    odo = Odometry(RNG.normal(size=(k, 3)), RNG.normal(size=(k, 4)),
                   RNG.normal(size=(k, 6, 6)), RNG.normal(size=(k, 3)),
                   RNG.normal(size=(k, 3)), RNG.normal(size=(k, 6, 6)))
    for frame, child in (('odom', 'imu_link'), ('', 'a'), ('map_frame', ''), ('ab', 'cdefg')):
        stamp = (1_700_000_123).to_bytes(4, 'little') + (456).to_bytes(4, 'little')
        for i, body in enumerate(odometry_bodies(odo)):
            m = deserialize_message(odometry_head(stamp, frame, child) + body.tobytes(),
                                    OdometryMsg)
            assert (m.header.stamp.sec, m.header.stamp.nanosec) == (1_700_000_123, 456)
            assert (m.header.frame_id, m.child_frame_id) == (frame, child)
            p, o, t = m.pose.pose.position, m.pose.pose.orientation, m.twist.twist
            assert np.array_equal((p.x, p.y, p.z), odo.position[i])
            assert np.array_equal((o.x, o.y, o.z, o.w), odo.q[i])
            assert np.array_equal(m.pose.covariance, odo.pose_cov[i].ravel())
            assert np.array_equal((t.linear.x, t.linear.y, t.linear.z), odo.v_b[i])
            assert np.array_equal((t.angular.x, t.angular.y, t.angular.z), odo.w_b[i])
            assert np.array_equal(m.twist.covariance, odo.twist_cov[i].ravel())


def test_one_layout_shortcut_decodes_as_the_general_path(monkeypatch):
    from sins_align_ros.io import cdr
    for frame in ('', 'a', 'imu_link', 'x' * 13):
        raws = [serialize_message(_imu(k, frame)[0]) for k in range(10)]
        assert cdr._one_layout(raws) is not None
        fast = cdr.imu_bodies(raws)
        with monkeypatch.context() as m:
            m.setattr(cdr, '_one_layout', lambda raws: None)
            general = cdr.imu_bodies(raws)
        for a, b in zip(fast, general):
            assert np.array_equal(a, b)
        other = serialize_message(_imu(11, frame + 'z')[0])   # another frame id length
        assert cdr._one_layout(raws + [other]) is None
        assert cdr._one_layout(raws[:3] + [raws[3][:-8]]) is None     # one cut short
        views = [bytearray(r) for r in raws]                        # bytes-like, not bytes
        assert cdr._one_layout(views) is None
        for a, b in zip(cdr.imu_bodies(views), general):
            assert np.array_equal(a, b)

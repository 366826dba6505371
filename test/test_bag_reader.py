"""The bulk CDR decoders and the sqlite3 fast path of read_bag against rosbags' reader."""
import numpy as np
import pytest

from sins_align_ros.io import bag_db3
from sins_align_ros.io.bag import (FIX_TYPE, IMU_TYPE, ODOM_TYPE, VEL_TYPE, _topics,
                                   _typestore, iter_bag, read_bag)
from sins_align_ros.io.cdr import decode_fix, decode_odometry_q, decode_twist

START_NS = 1_700_000_000 * 10 ** 9


@pytest.fixture(scope='module')
def ts():
    return _typestore()


def _header(T, k, frame):
    return T['std_msgs/msg/Header'](
        stamp=T['builtin_interfaces/msg/Time'](sec=1_700_000_000 + k, nanosec=7919 * k),
        frame_id=frame)


def _fix(T, k, rng):
    cov = rng.normal(size=9)
    return T[FIX_TYPE](header=_header(T, k, 'g' * (k % 11)),
                       status=T['sensor_msgs/msg/NavSatStatus'](status=(-1, 0, 1, 2)[k % 4],
                                                                service=k % 16),
                       latitude=float(rng.uniform(-90, 90)),
                       longitude=float(rng.uniform(-180, 180)),
                       altitude=float(rng.normal(50, 30)), position_covariance=cov,
                       position_covariance_type=k % 4)


def _twist(T, k, rng):
    V3 = T['geometry_msgs/msg/Vector3']
    return T[VEL_TYPE](header=_header(T, k, 'v' * (k % 9)),
                       twist=T['geometry_msgs/msg/TwistWithCovariance'](
                           twist=T['geometry_msgs/msg/Twist'](linear=V3(*rng.normal(size=3)),
                                                              angular=V3(*rng.normal(size=3))),
                           covariance=rng.normal(size=36)))


def _odom(T, k, rng):
    V3, Q = T['geometry_msgs/msg/Vector3'], T['geometry_msgs/msg/Quaternion']
    q = rng.normal(size=4)
    return T[ODOM_TYPE](
        header=_header(T, k, 'o' * (k % 5)), child_frame_id='c' * (k % 7),
        pose=T['geometry_msgs/msg/PoseWithCovariance'](
            pose=T['geometry_msgs/msg/Pose'](
                position=T['geometry_msgs/msg/Point'](*rng.normal(size=3)), orientation=Q(*q)),
            covariance=rng.normal(size=36)),
        twist=T['geometry_msgs/msg/TwistWithCovariance'](
            twist=T['geometry_msgs/msg/Twist'](linear=V3(0.0, 0.0, 0.0),
                                               angular=V3(0.0, 0.0, 0.0)),
            covariance=np.zeros(36)))


def _serialize(ts, msgs, msgtype):
    """Every message as little-endian CDR but #5 big-endian, #6 padded by 2 bytes, #7 cut."""
    raws = [bytes(ts.serialize_cdr(m, msgtype, little_endian=k != 5))
            for k, m in enumerate(msgs)]
    raws[6] += b'\x00\x00'
    raws[7] = raws[7][:-3]
    return raws


def test_bulk_gnss_and_truth_decoders_equal_the_general_deserialiser(ts):
    """Frame ids of every padding, all status and covariance types; odd messages left over."""
    T, rng = ts.types, np.random.default_rng(11)
    fixes = [_fix(T, k, rng) for k in range(30)]
    t, status, llh, cov, cov_type, ok = decode_fix(_serialize(ts, fixes, FIX_TYPE))
    assert list(np.flatnonzero(~ok)) == [5, 7] and np.isnan(t[5])
    for k in np.flatnonzero(ok):
        m = fixes[k]
        assert t[k] == m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
        assert status[k] == m.status.status and cov_type[k] == m.position_covariance_type
        assert tuple(llh[k]) == (m.latitude, m.longitude, m.altitude)
        assert np.array_equal(cov[k], m.position_covariance)
    twists = [_twist(T, k, rng) for k in range(30)]
    t, v, cov, ok = decode_twist(_serialize(ts, twists, VEL_TYPE))
    assert list(np.flatnonzero(~ok)) == [5, 7]
    for k in np.flatnonzero(ok):
        lin = twists[k].twist.twist.linear
        assert tuple(v[k]) == (lin.x, lin.y, lin.z)
        assert np.array_equal(cov[k], twists[k].twist.covariance)
    odoms = [_odom(T, k, rng) for k in range(30)]
    t, q, ok = decode_odometry_q(_serialize(ts, odoms, ODOM_TYPE))
    assert list(np.flatnonzero(~ok)) == [5, 7]
    for k in np.flatnonzero(ok):
        o = odoms[k].pose.pose.orientation
        assert tuple(q[k]) == (o.x, o.y, o.z, o.w)


def _write(path, ts, messages):
    """A rosbag2 (sqlite3) of ``(topic, msgtype, receive_ns, raw)`` in the given order."""
    from rosbags.rosbag2 import Writer
    with Writer(path, version=8) as w:
        conns = {}
        for topic, msgtype, ns, raw in messages:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=ts)
            w.write(conns[topic], ns, raw)
    return path


def _imu(ts, k, rng, frame='imu_link'):
    T = ts.types
    V3 = T['geometry_msgs/msg/Vector3']
    return T[IMU_TYPE](header=_header(T, k, frame),
                       orientation=T['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0),
                       orientation_covariance=np.zeros(9),
                       angular_velocity=V3(*rng.normal(size=3)),
                       angular_velocity_covariance=np.zeros(9),
                       linear_acceleration=V3(*rng.normal(size=3)),
                       linear_acceleration_covariance=np.zeros(9))


def _mixed(ts, rng, n=200):
    """IMU at every ns step, GNSS and truth every 10th, some stamps tied, written shuffled."""
    T, out = ts.types, []
    for k in range(n):
        ns = START_NS + (k // 2) * 10_000_000          # pairs of IMU messages share a stamp
        out.append(('/ns/imu/data_raw', IMU_TYPE, ns,
                    bytes(ts.serialize_cdr(_imu(ts, k, rng), IMU_TYPE))))
        if k % 10 == 3:
            for topic, msgtype, make in (('/ns/gnss/fix', FIX_TYPE, _fix),
                                         ('/ns/gnss/vel', VEL_TYPE, _twist),
                                         ('/ns/sim/truth', ODOM_TYPE, _odom)):
                out.append((topic, msgtype, ns,
                            bytes(ts.serialize_cdr(make(T, k, rng), msgtype))))
    return out


def _same(a, b):
    for k in ('t', 'w', 'f', 'missing', 'imu_before'):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    assert [(e.kind, e.t, e.data) for e in a.events] == [(e.kind, e.t, e.data) for e in b.events]
    assert a.error == b.error


def test_db3_fast_path_equals_the_general_reader_in_recording_order(tmp_path, ts, monkeypatch):
    """Rows written out of stamp order and stamps tied across topics: the same recording."""
    rng = np.random.default_rng(3)
    msgs = _mixed(ts, rng)
    order = np.random.default_rng(4).permutation(len(msgs))
    bag = _write(tmp_path / 'bag', ts, [msgs[k] for k in order])
    fast = bag_db3.read_db3(bag_db3.db3_file(bag), lambda topics: _topics(
        topics, 'imu/data_raw', 'gnss/fix', 'sim/truth', 'gnss/vel'))
    assert fast is not None
    _same(fast, read_bag(bag))
    assert len(fast.t) == 200 and {e.kind for e in fast.events} == {'fix', 'vel', 'truth'}
    monkeypatch.setattr(bag_db3, 'read_db3', lambda *a: None)
    _same(fast, read_bag(bag))
    imu = [e for e in iter_bag(bag) if e.kind == 'imu']
    assert np.array_equal(fast.t, [e.t for e in imu])


def test_db3_fast_path_leaves_what_it_cannot_decode_to_the_general_reader(tmp_path, ts):
    """A big-endian GNSS message in the bag: read_db3 declines, read_bag still reads it all."""
    rng = np.random.default_rng(5)
    msgs = _mixed(ts, rng)
    j = next(k for k, m in enumerate(msgs) if m[1] == FIX_TYPE)
    m = _fix(ts.types, 3, rng)
    msgs[j] = msgs[j][:3] + (bytes(ts.serialize_cdr(m, FIX_TYPE, little_endian=False)),)
    bag = _write(tmp_path / 'bag', ts, msgs)
    db = bag_db3.db3_file(bag)
    assert bag_db3.read_db3(db, lambda topics: (topics, [], [], [])) is None
    rec = read_bag(bag)
    fix = [e for e in rec.events if e.kind == 'fix'][0]
    assert fix.data[1:4] == (m.latitude, m.longitude, m.altitude)


def test_db3_file_only_for_a_single_uncompressed_storage_file(tmp_path, ts):
    rng = np.random.default_rng(6)
    bag = _write(tmp_path / 'bag', ts, _mixed(ts, rng, n=20))
    db = bag_db3.db3_file(bag)
    assert db is not None and bag_db3.db3_file(db) == db
    meta = bag / 'metadata.yaml'
    meta.write_text(meta.read_text().replace("compression_format: ''",
                                             'compression_format: zstd'))
    assert bag_db3.db3_file(bag) is None
    (bag / 'metadata.yaml').write_text('')
    (bag / 'bag_1.db3').write_bytes(b'')
    assert bag_db3.db3_file(bag) is None
    assert bag_db3.db3_file(tmp_path / 'missing') is None

"""rosbag2 input (and output, for simulated recordings) with the ``rosbags`` library.

No ROS graph and no rclpy: messages are read and written as CDR with the
ROS 2 Jazzy type store. Topics are matched by name or by name suffix, so
namespaced recordings (``/ship/imu/data_raw``) work without options.
"""
import difflib
from pathlib import Path

import numpy as np

from ..nav import earth
from ..nav.frames import euler_to_quat
from .bag_data import BagEvent, BagRecording
from .bag_db3 import db3_file, read_db3
from .cdr import decode_imu

IMU_TYPE = 'sensor_msgs/msg/Imu'
FIX_TYPE = 'sensor_msgs/msg/NavSatFix'
VEL_TYPE = 'geometry_msgs/msg/TwistWithCovarianceStamped'
ODOM_TYPE = 'nav_msgs/msg/Odometry'


class BagError(ValueError):
    """The bag cannot be replayed; the message says why in one line."""


def _stamp(header):
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def _typestore():
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def _match(connections, name, msgtype, required):
    found = [c for c in connections if c.topic == name or c.topic == '/' + name
             or c.topic.endswith('/' + name)]
    if not found:
        if required:
            listed = sorted({c.topic for c in connections})
            near = difflib.get_close_matches('/' + name.lstrip('/'), listed, n=1, cutoff=0.6)
            raise BagError(f'no topic {name!r} in the bag'
                           + (f' (did you mean {near[0]!r}?)' if near else '')
                           + f'; its topics: {", ".join(listed) or "none"}')
        return []
    for c in found:
        if c.msgtype != msgtype:
            raise BagError(f'topic {c.topic!r} has type {c.msgtype}, expected {msgtype}')
    return found


def _open(path):
    """Return an opened rosbags ``AnyReader`` on ``path``; :class:`BagError` if it cannot be."""
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:   # pragma: no cover - depends on the installation
        raise BagError('the rosbags library is not installed (pip install rosbags)') from None
    p = Path(path)
    if not p.exists():
        raise BagError(f'{path}: no such file or directory')
    try:
        reader = AnyReader([p], default_typestore=_typestore())
        reader.open()
    except Exception as exc:          # rosbags raises several types for bad input
        raise BagError(f'{path}: not a readable rosbag2: {exc}') from None
    return reader


def _topics(connections, imu_topic, fix_topic, truth_topic, vel_topic, required=()):
    """Return the connections ``(imu, fix, truth, vel)``; truth and vel None: not read.

    The IMU topic must be in the bag, and so must those of ``required`` ('fix', 'vel',
    'truth': topics the user named): :class:`BagError` listing the bag's topics.
    """
    c = connections
    return (_match(c, imu_topic, IMU_TYPE, True),
            _match(c, fix_topic, FIX_TYPE, 'fix' in required),
            _match(c, truth_topic, ODOM_TYPE, 'truth' in required) if truth_topic else [],
            _match(c, vel_topic, VEL_TYPE, 'vel' in required) if vel_topic else [])


def iter_bag(path, imu_topic='imu/data_raw', fix_topic='gnss/fix', truth_topic='sim/truth',
             vel_topic='gnss/vel', required=()):
    """Yield :class:`BagEvent` in recording order from a rosbag2 folder or .mcap file.

    Raises :class:`BagError` for a missing IMU topic (or a missing one of ``required``,
    see :func:`_topics`), a wrong message type or an unreadable bag (also part-way
    through: the caller keeps what came before).
    """
    reader = _open(path)
    try:
        imu, fix, truth, vel = _topics(reader.connections, imu_topic, fix_topic, truth_topic,
                                       vel_topic, required)
        try:
            for conn, _, raw in reader.messages(connections=imu + fix + truth + vel):
                yield _event(reader, conn, raw)
        except Exception as exc:
            raise BagError(f'{path}: bag is truncated or corrupt: {exc}') from None
    finally:
        reader.close()


def imu_frame_id(path, imu_topic='imu/data_raw'):
    """Return the ``frame_id`` of the first message on the bag's IMU topic ('' if none)."""
    reader = _open(path)
    try:
        imu = _match(reader.connections, imu_topic, IMU_TYPE, True)
        for conn, _, raw in reader.messages(connections=imu):
            return reader.deserialize(raw, conn.msgtype).header.frame_id
        return ''
    finally:
        reader.close()


def raw_messages(path):
    """Yield ``(topic, msgtype, msgdef, rihs01, log time ns, raw CDR)`` of every message.

    In recording order, for copying a bag's messages as they are (the result bag's
    ``--copy-input``); ``msgdef`` is the message definition text the bag stored.
    """
    reader = _open(path)
    try:
        for conn, t_ns, raw in reader.messages():
            yield conn.topic, conn.msgtype, conn.msgdef.data, conn.digest, t_ns, raw
    finally:
        reader.close()


def read_bag(path, imu_topic='imu/data_raw', fix_topic='gnss/fix', truth_topic='sim/truth',
             vel_topic='gnss/vel', required=()):
    """Read a rosbag2 folder or .mcap file at once into a :class:`BagRecording`.

    The fast path of :func:`iter_bag` for replaying a whole recording: a single
    uncompressed ``.db3`` is read with sqlite3 and decoded in bulk (:mod:`.bag_db3`);
    otherwise the raw messages are read with rosbags without deserialising, the IMU
    decoded in bulk (:mod:`.cdr`), the few GNSS and truth messages one by one with
    rosbags (as are IMU messages the bulk decoder does not take). ``truth_topic``
    None: truth not read; ``required``: as :func:`iter_bag`'s. The same :class:`BagError`
    rules as :func:`iter_bag`,
    except that a fault part-way through is returned in ``error`` with what was read
    before it.
    """
    db = db3_file(path)
    if db is not None:
        rec = read_db3(db, lambda topics: _topics(topics, imu_topic, fix_topic, truth_topic,
                                                  vel_topic, required))
        if rec is not None:
            return rec
    reader = _open(path)
    raws, events, before, error = [], [], [], None
    try:
        imu, fix, truth, vel = _topics(reader.connections, imu_topic, fix_topic, truth_topic,
                                       vel_topic, required)
        imu_ids = {c.id for c in imu}
        try:
            for conn, _, raw in reader.messages(connections=imu + fix + truth + vel):
                if conn.id in imu_ids:
                    raws.append(raw)
                else:
                    events.append((conn, raw))
                    before.append(len(raws))
        except Exception as exc:
            error = f'{path}: bag is truncated or corrupt: {exc}'
        t, w, f, missing, ok = decode_imu(raws)
        before = np.asarray(before, dtype=int)
        n_imu, n_ev = len(raws), len(events)
        for k in np.flatnonzero(~ok):               # what the bulk decoder left
            try:
                msg = reader.deserialize(raws[k], IMU_TYPE)
            except Exception as exc:
                error = f'{path}: bag is truncated or corrupt: {exc}'
                n_imu, n_ev = int(k), int(np.searchsorted(before, k, side='right'))
                break
            t[k] = _stamp(msg.header)
            w[k], f[k], missing[k] = _imu_fields(msg)[:3]
        decoded = []
        for j, (conn, raw) in enumerate(events[:n_ev]):
            try:
                decoded.append(_event(reader, conn, raw))
            except Exception as exc:
                error = f'{path}: bag is truncated or corrupt: {exc}'
                n_imu = min(n_imu, int(before[j]))
                break
    finally:
        reader.close()
    return BagRecording(t[:n_imu], w[:n_imu], f[:n_imu], missing[:n_imu], decoded,
                        before[:len(decoded)], error)


def _imu_fields(msg):
    """``(w, f, missing, frame_id)`` of a deserialised Imu message."""
    w, a = msg.angular_velocity, msg.linear_acceleration
    missing = bool(msg.angular_velocity_covariance[0] == -1.0
                   or msg.linear_acceleration_covariance[0] == -1.0)
    return (w.x, w.y, w.z), (a.x, a.y, a.z), missing, msg.header.frame_id


def _event(reader, conn, raw):
    """Return the :class:`BagEvent` of one deserialised message."""
    msg = reader.deserialize(raw, conn.msgtype)
    t = _stamp(msg.header)
    if conn.msgtype == IMU_TYPE:
        w, f, missing, frame = _imu_fields(msg)
        return BagEvent('imu', t, (w, f, frame, missing))
    if conn.msgtype == FIX_TYPE:
        c = msg.position_covariance
        pos_var = None if msg.position_covariance_type == 0 else (float(c[0]), float(c[4]))
        return BagEvent('fix', t, (int(msg.status.status), msg.latitude, msg.longitude,
                                   msg.altitude, pos_var))
    if conn.msgtype == VEL_TYPE:
        v, c = msg.twist.twist.linear, msg.twist.covariance
        return BagEvent('vel', t, ((v.x, v.y, v.z), (float(c[0]), float(c[7]))))
    q = msg.pose.pose.orientation
    return BagEvent('truth', t, ((q.x, q.y, q.z, q.w),))


def write_scenario_bag(path, sc, seed=0, duration=None, start_time=1_700_000_000.0,
                       truth_rate_hz=10.0):
    """Record a simulated scenario into a rosbag2 (sqlite3) like simulator_node publishes it.

    Topics: imu/data_raw, gnss/fix, gnss/vel, sim/truth (relative names, no namespace).
    Returns the path.
    """
    from rosbags.rosbag2 import Writer

    from ..sim.scenario import ScenarioStream
    ts = _typestore()
    T = ts.types
    st = ScenarioStream(sc, seed=seed)
    dur = duration or sc.duration
    n_total = int(round(dur / st.dt))
    every = max(1, int(round(1.0 / (truth_rate_hz * st.dt))))

    def header(t, frame):
        ns = int(round((start_time + t) * 1e9))
        return T['std_msgs/msg/Header'](
            stamp=T['builtin_interfaces/msg/Time'](sec=ns // 10 ** 9, nanosec=ns % 10 ** 9),
            frame_id=frame)

    V3, Q = T['geometry_msgs/msg/Vector3'], T['geometry_msgs/msg/Quaternion']
    zeros9 = np.zeros(9)
    with Writer(path, version=8) as w:
        c_imu = w.add_connection('/imu/data_raw', IMU_TYPE, typestore=ts)
        c_fix = w.add_connection('/gnss/fix', FIX_TYPE, typestore=ts)
        c_truth = w.add_connection('/sim/truth', ODOM_TYPE, typestore=ts)
        c_vel = w.add_connection('/gnss/vel', VEL_TYPE, typestore=ts)
        k = 0
        while k < n_total:
            n = min(int(round(1.0 / st.dt)), n_total - k)
            b = st.next_block(n)
            events = []
            for i in range(n):
                t = b.imu.t[i]
                ocov = zeros9.copy()
                ocov[0] = -1.0
                m = T[IMU_TYPE](header=header(t, 'imu_link'),
                                orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0),
                                orientation_covariance=ocov,
                                angular_velocity=V3(*(b.imu.dtheta[i] / st.dt)),
                                angular_velocity_covariance=zeros9,
                                linear_acceleration=V3(*(b.imu.dv[i] / st.dt)),
                                linear_acceleration_covariance=zeros9)
                events.append((t, 0, c_imu, ts.serialize_cdr(m, IMU_TYPE)))
                if (k + i + 1) % every == 0:
                    q = euler_to_quat(b.imu.euler[i])
                    off = earth.local_offset_m(*sc.trajectory.initial_position, *b.imu.pos[i])
                    pose = T['geometry_msgs/msg/PoseWithCovariance'](
                        pose=T['geometry_msgs/msg/Pose'](
                            position=T['geometry_msgs/msg/Point'](*off), orientation=Q(*q)),
                        covariance=np.zeros(36))
                    tw = T['geometry_msgs/msg/TwistWithCovariance'](
                        twist=T['geometry_msgs/msg/Twist'](linear=V3(0.0, 0.0, 0.0),
                                                           angular=V3(0.0, 0.0, 0.0)),
                        covariance=np.zeros(36))
                    od = T[ODOM_TYPE](header=header(t, 'enu'), child_frame_id='imu_link',
                                      pose=pose, twist=tw)
                    events.append((t, 1, c_truth, ts.serialize_cdr(od, ODOM_TYPE)))
            if b.gnss is not None:
                g = b.gnss
                for j in range(len(g.t)):
                    st_msg = T['sensor_msgs/msg/NavSatStatus'](status=0 if g.fix[j] else -1,
                                                               service=1)
                    cov = np.zeros(9)
                    cov[[0, 4, 8]] = g.pos_cov
                    fx = T[FIX_TYPE](header=header(g.t[j], 'gnss_link'), status=st_msg,
                                     latitude=float(np.degrees(g.lat[j])),
                                     longitude=float(np.degrees(g.lon[j])),
                                     altitude=float(g.h[j]), position_covariance=cov,
                                     position_covariance_type=2)
                    events.append((g.t[j], 2, c_fix, ts.serialize_cdr(fx, FIX_TYPE)))
                    if g.fix[j] and g.v_n is not None:      # None: a position-only receiver
                        tcov = np.zeros(36)
                        tcov[[0, 7, 14]] = g.vel_cov
                        tcov[[21, 28, 35]] = 1e6
                        vm = T[VEL_TYPE](
                            header=header(g.t[j], 'gnss_link'),
                            twist=T['geometry_msgs/msg/TwistWithCovariance'](
                                twist=T['geometry_msgs/msg/Twist'](linear=V3(*g.v_n[j]),
                                                                   angular=V3(0.0, 0.0, 0.0)),
                                covariance=tcov))
                        events.append((g.t[j], 3, c_vel, ts.serialize_cdr(vm, VEL_TYPE)))
            for t, _, conn, data in sorted(events, key=lambda e: (e[0], e[1])):
                w.write(conn, int(round((start_time + t) * 1e9)), data)
            k += n
    return path

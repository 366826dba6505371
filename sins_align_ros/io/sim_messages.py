"""The simulator's messages, built once for simulator_node and for the scenario recorder.

:class:`SimulatedMessages` turns a scenario into the messages of the simulator's four
topics (:data:`TOPICS`), in stamp order, a second of data at a time (each message built
when it is sent). It imports no ROS
package: the message classes come from ``types``, a lookup from a type name
(``'sensor_msgs/msg/Imu'``) to a class. ``simulator_node`` passes the ROS message
packages' classes and publishes what it gets; :func:`write_simulated_bag` (behind
``sins_align_record``) passes the ``rosbags`` type store's and writes CDR into a rosbag2.
Both kinds of class take every field by keyword, and every field is given, so the two
carry the same contents.

What the messages hold is documented in :mod:`sins_align_ros.ros.simulator_node`. A
position-only receiver (``GnssSpec.velocity`` False) has no ``gnss/vel``: :func:`topics`
leaves it out, and neither the node nor the recorder creates it.
"""
import math

import numpy as np

from ..nav import earth
from ..nav.frames import euler_rates_to_w_nb_b, euler_to_dcm, euler_to_quat
from ..sim.presets import SENSOR_GRADES, scenario
from ..sim.scenario import ScenarioStream
from ..units import DPSH, UG

IMU_TYPE = 'sensor_msgs/msg/Imu'
FIX_TYPE = 'sensor_msgs/msg/NavSatFix'
VEL_TYPE = 'geometry_msgs/msg/TwistWithCovarianceStamped'
ODOM_TYPE = 'nav_msgs/msg/Odometry'
#: key -> (relative topic name, message type); the keys are those of :meth:`next_block`
TOPICS = {'imu': ('imu/data_raw', IMU_TYPE), 'fix': ('gnss/fix', FIX_TYPE),
          'vel': ('gnss/vel', VEL_TYPE), 'truth': ('sim/truth', ODOM_TYPE)}
#: frame ids: (IMU, GNSS receiver, the truth's local ENU frame)
FRAMES = ('imu_link', 'gnss_link', 'enu')

# sensor_msgs constants (NavSatStatus, NavSatFix)
_STATUS_NO_FIX, _STATUS_FIX, _SERVICE_GPS = -1, 0, 1
_COV_UNKNOWN, _COV_DIAGONAL_KNOWN = 0, 2
_ORDER = {'imu': 0, 'truth': 1, 'fix': 2, 'vel': 3}   # same stamp: this order
_BLOCK_S = 1.0   # seconds of data per block


def topics(sc):
    """Return the :data:`TOPICS` of scenario ``sc``: no ``vel`` without a receiver velocity."""
    vel = sc.gnss is None or sc.gnss.velocity
    return {k: v for k, v in TOPICS.items() if vel or k != 'vel'}


def simulated_scenario(name, grade='', duration=0.0):
    """Build the named scenario preset with the IMU of sensor grade ``grade`` (empty: its own).

    ``duration`` > 0 replaces the scenario's. An unknown name or grade raises
    ``ValueError`` naming the known ones.
    """
    if grade and grade not in SENSOR_GRADES:
        raise ValueError(f'unknown sensor grade {grade!r} (known: '
                         f'{", ".join(SENSOR_GRADES)}; empty for the scenario\'s own)')
    sc = scenario(name, **({'duration': float(duration)} if duration > 0 else {}))
    if grade and sc.imu is not SENSOR_GRADES[grade]:
        sc.imu = SENSOR_GRADES[grade]
        sc.description += f'; IMU grade {grade} instead of the scenario\'s'
    return sc


def _diag(n, values):
    """Row-major n x n covariance (a float64 array) with ``values`` on the diagonal."""
    c = np.zeros(n * n)
    c[::n + 1][:len(values)] = values
    return c


class SimulatedMessages:
    """A scenario as the messages of :data:`TOPICS`, in stamp order.

    Parameters
    ----------
    sc : Scenario
    types : callable
        Type name -> message class (see the module docstring).
    seed : int
    imu_rate_hz, gnss_rate_hz : float or None
        Override the scenario's rates.
    truth_rate_hz : float
        Rate of ``sim/truth`` (capped at the IMU rate).
    frames : (imu, gnss, world) frame ids
    start_ns : int
        Stamp of t = 0, ns.
    """

    def __init__(self, sc, types, seed=0, imu_rate_hz=None, gnss_rate_hz=None,
                 truth_rate_hz=10.0, frames=FRAMES, start_ns=0):
        self.sc = sc
        self.stream = ScenarioStream(sc, seed=seed, imu_rate_hz=imu_rate_hz,
                                     gnss_rate_hz=gnss_rate_hz)
        self.dt = self.stream.dt
        #: IMU samples in the whole run
        self.n_total = int(round(sc.duration / self.dt))
        self.truth_every = max(1, int(round(1.0 / (truth_rate_hz * self.dt))))
        self.frames = tuple(frames)
        self.start_ns = int(start_ns)
        self.origin = sc.trajectory.initial_position
        spec = sc.imu
        self.gyro_cov = _diag(3, [(spec.gyro_arw_dpsh * DPSH) ** 2 / self.dt] * 3)
        self.accel_cov = _diag(3, [(spec.accel_vrw_ug_rthz * UG) ** 2 / self.dt] * 3)
        self._orientation_cov = _diag(3, [-1.0])     # REP-145: orientation not provided
        self._t = {k: types(k) for k in (
            IMU_TYPE, FIX_TYPE, VEL_TYPE, ODOM_TYPE, 'std_msgs/msg/Header',
            'builtin_interfaces/msg/Time', 'sensor_msgs/msg/NavSatStatus',
            'geometry_msgs/msg/Vector3', 'geometry_msgs/msg/Point',
            'geometry_msgs/msg/Quaternion', 'geometry_msgs/msg/Pose',
            'geometry_msgs/msg/PoseWithCovariance', 'geometry_msgs/msg/Twist',
            'geometry_msgs/msg/TwistWithCovariance')}
        self._build = {'imu': self._imu, 'truth': self._truth, 'fix': self._fix,
                       'vel': self._vel}

    def stamp_ns(self, t):
        """Stamp (ns) of simulation time ``t`` (s)."""
        return self.start_ns + int(round(t * 1e9))

    def next_block(self):
        """Simulate the next second of data: ``(t, key, args)`` in stamp order, [] at the end.

        ``t`` is the simulation time (s), ``key`` one of :data:`TOPICS`, ``build(key, args)``
        the message (built when it is sent, as a live publisher would); IMU, then truth,
        then fix, then vel at equal stamps.
        """
        n = min(int(round(_BLOCK_S / self.dt)), self.n_total - self.stream.imu.k)
        if n <= 0:
            return []
        b = self.stream.next_block(n)
        imu = b.imu
        k0 = self.stream.imu.k - n
        kin = self.sc.trajectory.kinematics(imu.t)
        w_nb_b = euler_rates_to_w_nb_b(kin.euler, kin.euler_rate)
        items = []
        for i in range(n):
            t = imu.t[i]
            items.append((t, 'imu', (t, imu.dtheta[i], imu.dv[i])))
            if (k0 + i + 1) % self.truth_every == 0:
                items.append((t, 'truth', (t, imu.euler[i], imu.v_n[i], imu.pos[i], w_nb_b[i])))
        if b.gnss is not None:
            g = b.gnss
            for j in range(len(g.t)):
                t = g.t[j]
                items.append((t, 'fix', (t, g.lat[j], g.lon[j], g.h[j], g.fix[j], g.pos_cov)))
                if g.fix[j] and g.v_n is not None:
                    items.append((t, 'vel', (t, g.v_n[j], g.vel_cov)))
        items.sort(key=lambda it: (it[0], _ORDER[it[1]]))
        return items

    def build(self, key, args):
        """Return the message of one item of :meth:`next_block`."""
        return self._build[key](*args)

    # -- one message each ------------------------------------------------------------
    def _header(self, t, frame):
        ns = self.stamp_ns(t)
        stamp = self._t['builtin_interfaces/msg/Time'](sec=ns // 1_000_000_000,
                                                       nanosec=ns % 1_000_000_000)
        return self._t['std_msgs/msg/Header'](stamp=stamp, frame_id=frame)

    def _vec(self, xyz, kind='geometry_msgs/msg/Vector3'):
        return self._t[kind](x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))

    def _quat(self, xyzw):
        x, y, z, w = (float(c) for c in xyzw)
        return self._t['geometry_msgs/msg/Quaternion'](x=x, y=y, z=z, w=w)

    def _twist(self, linear, angular, cov):
        T = self._t
        return T['geometry_msgs/msg/TwistWithCovariance'](
            twist=T['geometry_msgs/msg/Twist'](linear=self._vec(linear),
                                               angular=self._vec(angular)),
            covariance=cov)

    def _imu(self, t, dtheta, dv):
        return self._t[IMU_TYPE](
            header=self._header(t, self.frames[0]), orientation=self._quat((0, 0, 0, 1)),
            orientation_covariance=self._orientation_cov,
            angular_velocity=self._vec(dtheta / self.dt),
            angular_velocity_covariance=self.gyro_cov,
            linear_acceleration=self._vec(dv / self.dt),
            linear_acceleration_covariance=self.accel_cov)

    def _truth(self, t, euler, v_n, pos, w_nb_b):
        T = self._t
        off = earth.local_offset_m(self.origin[0], self.origin[1], self.origin[2], *pos)
        pose = T['geometry_msgs/msg/PoseWithCovariance'](
            pose=T['geometry_msgs/msg/Pose'](position=self._vec(off, 'geometry_msgs/msg/Point'),
                                             orientation=self._quat(euler_to_quat(euler))),
            covariance=np.zeros(36))
        return T[ODOM_TYPE](header=self._header(t, self.frames[2]),
                            child_frame_id=self.frames[0], pose=pose,
                            twist=self._twist(euler_to_dcm(euler).T @ v_n, w_nb_b,
                                              np.zeros(36)))

    def _fix(self, t, lat, lon, h, fix, pos_cov):
        if fix:
            status, cov_type = _STATUS_FIX, _COV_DIAGONAL_KNOWN
            lla, cov = (math.degrees(lat), math.degrees(lon), float(h)), _diag(3, pos_cov)
        else:
            status, cov_type = _STATUS_NO_FIX, _COV_UNKNOWN
            lla, cov = (math.nan,) * 3, np.zeros(9)
        return self._t[FIX_TYPE](
            header=self._header(t, self.frames[1]),
            status=self._t['sensor_msgs/msg/NavSatStatus'](status=status, service=_SERVICE_GPS),
            latitude=lla[0], longitude=lla[1], altitude=lla[2], position_covariance=cov,
            position_covariance_type=cov_type)

    def _vel(self, t, v_n, vel_cov):
        return self._t[VEL_TYPE](header=self._header(t, self.frames[1]), twist=self._twist(
            v_n, (0.0, 0.0, 0.0), _diag(6, list(vel_cov) + [1e6] * 3)))


def write_simulated_bag(path, sc, **kwargs):
    """Record scenario ``sc`` into a rosbag2 (sqlite3) at ``path``, as simulator_node publishes it.

    ``kwargs`` are those of :class:`SimulatedMessages` (seed, rates, frames, ``start_ns``);
    the topics are :func:`topics` of ``sc`` with a leading slash (no ``gnss/vel`` from a
    position-only receiver), each message's receive time its stamp. Needs the ``rosbags``
    library. Returns the number of messages per topic key.
    """
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    messages = SimulatedMessages(sc, ts.types.__getitem__, **kwargs)
    counts = dict.fromkeys(topics(sc), 0)
    with Writer(path, version=8) as w:
        conns = {k: w.add_connection('/' + name, typ, typestore=ts)
                 for k, (name, typ) in topics(sc).items()}
        while True:
            items = messages.next_block()
            if not items:
                break
            for t, key, args in items:
                w.write(conns[key], messages.stamp_ns(t),
                        ts.serialize_cdr(messages.build(key, args), TOPICS[key][1]))
                counts[key] += 1
    return counts

"""Sensor-grade and scenario presets.

Sensor grades (datasheet units; docs/simulator_node.md "Sensor grade presets" mirrors this
table and a test keeps the two equal):

============  ========  =========  =========  =========  =========  ==============
grade         gyro bias  gyro ARW   gyro GM    acc bias   acc VRW    source
              deg/h      deg/rt-h   deg/h,tau  micro-g    ug/rt-Hz
============  ========  =========  =========  =========  =========  ==============
navigation    0.01       0.001      -          100        10         seed 002 sec. 4
marine        0.003      0.0005     -          30         5          seed 000 sec. 4.1
tactical      1.0        0.05       0.5, 300   300        50         typical FOG/RLG tactical
mems          200        3.0        50, 300    5000       350        ADXRS610 / MMA7260 (seed 003)
usv_high      0.02       0.002      -          50         10         seed 004 "high"
usv_medium    5          0.1        2, 100     500        80         seed 004 "medium"
usv_low       50         0.5        10, 100    2000       200        seed 004 "low"
mems_ahrs     400        0.42       10, 300    7000       120        raw AHRS triads
============  ========  =========  =========  =========  =========  ==============

Seed 000 gives its gyro noise as 0.0005 deg/h and accelerometer noise as 5e-6 g
without a bandwidth; we read them as 0.0005 deg/sqrt(h) and 5 ug/sqrt(Hz).
Seed 004's Table 2 values are not in the text we have; the usv_* grades are our
choice of the three classes it describes and are documented as such.

``mems_ahrs``: the raw gyro and accelerometer triads of an industrial MEMS AHRS, read
without the AHRS's factory calibration (issue 44). Its turn-on errors are drawn per run
(``random_bias``) as N(0, sigma^2): gyro bias 400 deg/h, gyro scale factor 2 % per axis,
accelerometer bias 7 mg, accelerometer scale factor 0.4 %, and an axis misalignment of
0.5 % on each of the six off-diagonal entries of both triads (the sizes issue 44 reports
for such triads). Its noise is that of the Xsens MTi-1 series datasheet: gyro noise
density 0.007 deg/s/sqrt(Hz) (0.42 deg/sqrt(h)), in-run bias stability 10 deg/h (our
Markov sigma, tau 300 s), accelerometer noise density 120 ug/sqrt(Hz) and zero-offset
instability 0.03 mg (Markov, tau 300 s).

Scenarios: :func:`scenario` builds a named :class:`Scenario` (trajectory, IMU
spec, GNSS spec, duration and the initial misalignment the seed applies to the
fine filter); ``SCENARIOS`` lists the names.
"""
from dataclasses import dataclass, field, replace

import numpy as np

from ..units import DEG, G0, KNOT
from .gnss import GnssSpec
from .imu import ImuSpec
from .trajectory import Segment, Sway, Trajectory

SENSOR_GRADES = {
    'navigation': ImuSpec(gyro_bias_dph=0.01, gyro_arw_dpsh=0.001,
                          accel_bias_ug=100.0, accel_vrw_ug_rthz=10.0),
    'marine': ImuSpec(gyro_bias_dph=0.003, gyro_arw_dpsh=0.0005,
                      accel_bias_ug=30.0, accel_vrw_ug_rthz=5.0),
    'tactical': ImuSpec(gyro_bias_dph=1.0, gyro_arw_dpsh=0.05, gyro_markov_dph=0.5,
                        gyro_markov_tau_s=300.0, accel_bias_ug=300.0,
                        accel_vrw_ug_rthz=50.0),
    'mems': ImuSpec(gyro_bias_dph=200.0, gyro_arw_dpsh=3.0, gyro_markov_dph=50.0,
                    gyro_markov_tau_s=300.0, accel_bias_ug=5000.0,
                    accel_vrw_ug_rthz=350.0),
    'usv_high': ImuSpec(gyro_bias_dph=0.02, gyro_arw_dpsh=0.002,
                        accel_bias_ug=50.0, accel_vrw_ug_rthz=10.0),
    'usv_medium': ImuSpec(gyro_bias_dph=5.0, gyro_arw_dpsh=0.1, gyro_markov_dph=2.0,
                          gyro_markov_tau_s=100.0, accel_bias_ug=500.0,
                          accel_vrw_ug_rthz=80.0),
    'usv_low': ImuSpec(gyro_bias_dph=50.0, gyro_arw_dpsh=0.5, gyro_markov_dph=10.0,
                       gyro_markov_tau_s=100.0, accel_bias_ug=2000.0,
                       accel_vrw_ug_rthz=200.0),
    # uncalibrated raw triads of an industrial MEMS AHRS (module docstring): turn-on
    # errors drawn per run, noise of the Xsens MTi-1 series datasheet
    'mems_ahrs': ImuSpec(gyro_bias_dph=400.0, gyro_arw_dpsh=0.42, gyro_markov_dph=10.0,
                         gyro_markov_tau_s=300.0, gyro_scale_ppm=20000.0,
                         gyro_misalign_ppm=5000.0, accel_bias_ug=7000.0,
                         accel_vrw_ug_rthz=120.0, accel_markov_ug=30.0,
                         accel_markov_tau_s=300.0, accel_scale_ppm=4000.0,
                         accel_misalign_ppm=5000.0, random_bias=True),
}

#: seed 000 sec. 4.1 sway: 2 deg / 3 s, 4 deg / 5 s, 3 deg / 7 s (pitch, roll, heading)
SEED000_SWAY = Sway(pitch_amp=2.0, pitch_period=3.0, roll_amp=4.0, roll_period=5.0,
                    yaw_amp=3.0, yaw_period=7.0)
#: severe sea for a small USV (seed 004 Table 1 is not in our text; sea state 6-7 values)
SEVERE_SEA = Sway(roll_amp=15.0, roll_period=6.0, pitch_amp=8.0, pitch_period=5.0,
                  pitch_phase=0.7, yaw_amp=6.0, yaw_period=9.0, yaw_phase=1.9,
                  heave_amp=1.5, heave_period=7.0, surge_amp=0.8, surge_period=8.0,
                  sway_amp=0.8, sway_period=10.0)


@dataclass
class Scenario:
    """Everything needed to simulate one run.

    Attributes
    ----------
    name, description : str
    trajectory : Trajectory
    imu : ImuSpec
    gnss : GnssSpec or None
        None: no receiver (stationary alignment uses the initial_* position).
    duration : float
        s.
    imu_rate_hz : float
    misalignment_deg : (3,)
        Initial attitude error the seed applies to the fine filter, ENU axes
        (east, north, up), deg.
    gnss_lever_arm_m : (3,)
        The GNSS antenna's position relative to the IMU, vehicle frame (FLU), m: the
        receiver measures the antenna's position and velocity.
    imu_mounting_rpy_deg : (3,)
        Rotation vehicle frame -> IMU frame (REP-103 roll, pitch, yaw, deg): the IMU
        outputs its samples in its own axes (the sensor errors are drawn in the
        vehicle's, which changes nothing for errors alike on every axis).
    """

    name: str
    description: str
    trajectory: Trajectory
    imu: ImuSpec
    gnss: GnssSpec = None
    duration: float = 600.0
    imu_rate_hz: float = 100.0
    misalignment_deg: tuple = (0.0, 0.0, 0.0)
    extra: dict = field(default_factory=dict)
    gnss_lever_arm_m: tuple = (0.0, 0.0, 0.0)
    imu_mounting_rpy_deg: tuple = (0.0, 0.0, 0.0)


def _seed002(mis):
    return Scenario(
        name=f'seed002_{mis}deg',
        description=f'seed 002 sec. 4: still, level, heading north at (34 N, 75 E, 100 m), '
                    f'navigation grade, 10 min, initial misalignment {mis} deg on each axis',
        trajectory=Trajectory(34.0, 75.0, 100.0, heading_deg=0.0, name='static'),
        imu=SENSOR_GRADES['navigation'], gnss=None, duration=600.0,
        misalignment_deg=(mis, mis, mis))


def noise_window(t0, t1, factor, end):
    """GNSS noise multiplier profile (``Scenario.extra['gnss_noise_profile']``).

    ``factor`` from ``t0`` to ``t1`` s, 1 elsewhere up to ``end`` s; the receiver's
    reported covariance stays nominal (the filter is not told).
    """
    return ((0.0, 1.0), (t0, 1.0), (t0 + 0.01, factor), (t1, factor), (t1 + 0.01, 1.0),
            (end, 1.0))


def seed000_profile():
    """Our acceleration profile for seed 000's "accelerating ship".

    Seed 000 states 0.1 g from 5 kn for 0.4 h, which would end near 1400 m/s.
    We keep its start speed and heading and use 0.1 g only as a short burst,
    then ship-like accelerations: 60 s at 5 kn; 5 s at 0.1 g (+4.9 m/s, ~14.5 kn);
    400 s at 0.01 m/s^2 (+4 m/s, ~22 kn); cruise; 300 s at -0.01 m/s^2; cruise.
    """
    return [Segment(60.0), Segment(5.0, accel=0.1 * G0, ramp=1.0),
            Segment(200.0), Segment(400.0, accel=0.01), Segment(300.0),
            Segment(300.0, accel=-0.01), Segment(175.0)]


def _seed000(case):
    mis = {1: (0.03, 0.03, 0.35), 2: (0.06, 0.06, 0.95)}[case]
    return Scenario(
        name=f'seed000_case{case}',
        description=f'seed 000 sec. 4: ship at (45.7796 N, 126.6705 E) heading 45 deg, '
                    f'sway 2deg/3s, 4deg/5s, 3deg/7s, accelerating from 5 kn, marine grade, '
                    f'0.4 h, GNSS position, initial misalignment {mis} deg',
        trajectory=Trajectory(45.7796, 126.6705, 0.0, heading_deg=45.0, speed=5.0 * KNOT,
                              segments=seed000_profile(), sway=SEED000_SWAY,
                              name='ship_accelerating'),
        imu=SENSOR_GRADES['marine'],
        gnss=GnssSpec(rate_hz=1.0, pos_sigma_h=0.2, pos_sigma_v=0.4, vel_sigma=0.05),
        duration=1440.0, misalignment_deg=mis)


def _flight():
    segs = [Segment(120.0), Segment(30.0, accel=2.0), Segment(200.0),
            Segment(60.0, climb_rate=0.1, ramp=5.0), Segment(240.0),
            Segment(60.0, climb_rate=-0.1, ramp=5.0), Segment(300.0),
            Segment(45.0, turn_rate=2.0, ramp=5.0), Segment(300.0),
            Segment(60.0, climb_rate=-0.1, ramp=5.0), Segment(200.0),
            Segment(60.0, climb_rate=0.1, ramp=5.0), Segment(300.0),
            Segment(90.0, turn_rate=-2.0, ramp=5.0), Segment(300.0),
            Segment(30.0, accel=-2.0), Segment(300.0),
            Segment(45.0, turn_rate=2.0, ramp=5.0), Segment(855.0)]
    return Scenario(
        name='seed001_flight',
        description='seed 001 sec. 3: 3600 s flight at 34 N with acceleration, deceleration, '
                    'climb, dive and coordinated turns; tactical grade; GNSS 1 Hz with an '
                    'abrupt and a slow change of its noise',
        trajectory=Trajectory(34.0, 108.0, 3000.0, heading_deg=45.0, speed=150.0,
                              segments=segs, coordinated_bank=True, name='flight'),
        imu=SENSOR_GRADES['tactical'],
        gnss=GnssSpec(rate_hz=1.0, pos_sigma_h=5.0, pos_sigma_v=8.0, vel_sigma=0.1),
        duration=3600.0, misalignment_deg=(0.05, 0.05, 0.2),
        # noise multiplier, linearly interpolated: abrupt x4 at 1200-1500 s, slow ramp
        # to x3 over 2400-3000 s (the filter is not told; receiver covariance stays nominal)
        extra={'gnss_noise_profile': ((0.0, 1.0), (1200.0, 1.0), (1200.01, 4.0),
                                      (1500.0, 4.0), (1500.01, 1.0), (2400.0, 1.0),
                                      (3000.0, 3.0), (3600.0, 3.0))})


def _car():
    segs = [Segment(30.0), Segment(10.0, accel=1.5), Segment(60.0),
            Segment(15.0, turn_rate=6.0), Segment(60.0), Segment(8.0, accel=-1.0),
            Segment(20.0, turn_rate=-9.0), Segment(40.0), Segment(10.0, accel=1.0),
            Segment(60.0, turn_rate=1.5), Segment(80.0), Segment(15.0, accel=-1.5),
            Segment(30.0), Segment(12.0, accel=1.2), Segment(100.0),
            Segment(30.0, turn_rate=-3.0), Segment(120.0)]
    return Scenario(
        name='seed003_car',
        description='seed 003 sec. 4: car with a MEMS IMU (ADXRS610 gyros, MMA7260 '
                    'accelerometers) and a receiver with 10 m horizontal, 5 m vertical, '
                    '0.1 m/s errors; IMU 100 Hz, GNSS 1 Hz',
        trajectory=Trajectory(30.5, 114.3, 30.0, heading_deg=20.0, speed=0.0,
                              segments=segs, name='car'),
        imu=SENSOR_GRADES['mems'],
        gnss=GnssSpec(rate_hz=1.0, pos_sigma_h=10.0, pos_sigma_v=5.0, vel_sigma=0.1),
        duration=700.0, misalignment_deg=(1.0, 1.0, 10.0))


def _severe_sea(grade):
    return Scenario(
        name=f'seed004_{grade}',
        description=f'seed 004 sec. 4: USV in severe sea, {grade} IMU, 300 s, initial '
                    f'misalignment 10/10/30 deg, GNSS with Bernoulli outliers (eq. 25)',
        trajectory=Trajectory(22.0, 113.5, 0.0, heading_deg=120.0, speed=1.0,
                              sway=SEVERE_SEA, name='usv_severe_sea'),
        imu=SENSOR_GRADES[f'usv_{grade}'],
        gnss=GnssSpec(rate_hz=1.0, pos_sigma_h=1.0, pos_sigma_v=2.0, vel_sigma=0.05,
                      outlier_prob=0.05, outlier_scale=20.0),
        duration=300.0, misalignment_deg=(10.0, 10.0, 30.0))


def _static(grade, lat=34.0, heading=30.0):
    return Scenario(
        name=f'static_{grade}', description=f'still, level IMU of {grade} grade at {lat} N',
        trajectory=Trajectory(lat, 108.0, 50.0, heading_deg=heading, name='static'),
        imu=SENSOR_GRADES[grade], gnss=GnssSpec(pos_sigma_h=1.0), duration=600.0,
        misalignment_deg=(0.5, 0.5, 2.0))


def _ship_sway():
    return Scenario(
        name='ship_sway', description='moored ship swaying (seed 000 sway) with heave, '
                                      'marine grade, 600 s',
        trajectory=Trajectory(45.7796, 126.6705, 0.0, heading_deg=45.0,
                              sway=Sway(**{**SEED000_SWAY.__dict__, 'heave_amp': 0.5,
                                           'heave_period': 6.0}),
                              name='ship_sway'),
        imu=SENSOR_GRADES['marine'], gnss=GnssSpec(pos_sigma_h=0.5), duration=600.0,
        misalignment_deg=(0.1, 0.1, 1.0))


def _ship_underway():
    segs = [Segment(60.0), Segment(120.0, accel=0.05), Segment(60.0),
            Segment(90.0, turn_rate=1.0, ramp=10.0), Segment(120.0),
            Segment(60.0, turn_rate=-1.5, ramp=10.0), Segment(90.0)]
    return Scenario(
        name='ship_underway', description='ship underway: accelerates from 5 kn, turns 90 deg '
                                          'and back, with seed 000 sway; marine grade',
        trajectory=Trajectory(45.7796, 126.6705, 0.0, heading_deg=45.0, speed=5.0 * KNOT,
                              segments=segs, sway=SEED000_SWAY, name='ship_underway'),
        imu=SENSOR_GRADES['marine'], gnss=GnssSpec(pos_sigma_h=0.5), duration=600.0,
        misalignment_deg=(0.1, 0.1, 1.0))


def _robot(still_s=90.0):
    """Build a small ground robot: MEMS IMU, still ``still_s``, then about 1 m/s, turning often.

    The turns (their sizes, rates and the straight legs between them) are drawn once from
    a fixed generator, so the trajectory is the same in every run; the sensor noise
    varies with the run's seed.
    """
    rng = np.random.default_rng(4343)
    segs = [Segment(still_s), Segment(2.5, accel=0.5, ramp=0.5)]
    for _ in range(40):
        angle = rng.uniform(20.0, 180.0) * rng.choice((-1.0, 1.0))
        rate = rng.uniform(15.0, 45.0)
        turn = abs(angle) / rate
        segs += [Segment(float(rng.uniform(3.0, 12.0))),
                 Segment(turn + 1.0, turn_rate=float(np.sign(angle) * rate), ramp=0.5)]
    return Scenario(
        name='robot_lot', description=f'small ground robot on a parking lot: MEMS IMU, still '
                                      f'for {still_s:.0f} s, then about 1 m/s with frequent '
                                      'turns of random size; consumer GNSS at 5 Hz',
        trajectory=Trajectory(48.1, 11.6, 520.0, heading_deg=70.0, speed=0.0,
                              segments=segs, name='robot_lot'),
        imu=SENSOR_GRADES['mems'],
        gnss=GnssSpec(rate_hz=5.0, pos_sigma_h=1.5, pos_sigma_v=3.0, vel_sigma=0.1),
        duration=400.0, misalignment_deg=(1.0, 1.0, 10.0))


def starting_still(sc, still_s, accel=0.05):
    """Scenario ``sc`` with the vehicle still for ``still_s`` seconds before its manoeuvres.

    A vehicle that starts under way first accelerates from rest to its initial speed at
    ``accel`` m/s^2 (a ship: 0.05 m/s^2, 5 kn in 51 s). The name gets ``_still<N>``.
    """
    tr = sc.trajectory
    lead = [Segment(float(still_s))]
    if tr.speed > 0.0:
        # a plateau of D - ramp at full acceleration: the speed gained is accel (D - ramp)
        lead.append(Segment(tr.speed / accel + 1.0, accel=accel, ramp=1.0))
    sc.trajectory = replace(tr, speed=0.0, segments=lead + list(tr.segments))
    sc.duration += sum(s.duration for s in lead)
    sc.name = f'{sc.name}_still{still_s:.0f}'
    sc.description = f'{sc.description}; still for the first {still_s:.0f} s'
    return sc


#: a skid-steer robot's vibration on asphalt (sample RMS at the IMU rate, full from 0.5 m/s)
ROBOT_VIBRATION = dict(vibration_gyro_dps=3.0, vibration_accel_mps2=1.5, vibration_tau_s=0.05,
                       vibration_full_speed_mps=0.5)


def _robot_skid():
    """Build robot_lot's robot never still: under way at 1 m/s from t = 0, same turns.

    Raw MEMS AHRS triads (``mems_ahrs``) at 30 Hz on a vibrating skid-steer chassis; a
    consumer receiver with positions only at 2.5 Hz, 0.8 m white + 1.5 m Gauss-Markov
    over 60 s, reporting 0.9 m (the issue 44 robot's receiver).
    """
    base = _robot()
    tr = base.trajectory
    # robot_lot's first two segments are its rest and its start (to 1 m/s): drop them
    return Scenario(
        name='robot_skid',
        description='skid-steer robot on a parking lot, never still: about 1 m/s from the '
                    'start with frequent turns of random size (robot_lot\'s), raw MEMS AHRS '
                    'triads at 30 Hz with vibration, consumer GNSS positions only at 2.5 Hz '
                    '(0.8 m white + 1.5 m over 60 s, reporting 0.9 m), no gnss/vel',
        trajectory=replace(tr, speed=1.0, segments=list(tr.segments[2:]), name='robot_skid'),
        imu=SENSOR_GRADES['mems_ahrs'].with_(**ROBOT_VIBRATION),
        gnss=GnssSpec(rate_hz=2.5, pos_sigma_h=0.8, pos_sigma_v=1.6, pos_markov_sigma=1.5,
                      pos_markov_tau_s=60.0, vel_sigma=0.1, velocity=False,
                      reported_pos_sigma_h=0.9, reported_pos_sigma_v=1.8),
        duration=400.0, imu_rate_hz=30.0, misalignment_deg=(1.0, 1.0, 10.0))


def urban_route(duration, v0=10.0, seed=4444):
    """Segments of a car in town, under way at ``v0`` m/s: ``duration`` s or a little more.

    Drawn once from the fixed generator ``seed`` (the same route in every run): legs of
    8-25 s at 8-14 m/s between events: a junction turn (slow to 5 m/s, turn 60-100 deg
    at 12-20 deg/s, speed up), a stop (brake at about 1.5 m/s^2, stand 5-20 s, pull away
    at about 1.5 m/s^2) or a bend (10-40 deg at 2-5 deg/s, at speed).
    """
    rng = np.random.default_rng(seed)
    segs, v, total = [], float(v0), 0.0

    def change(dv, a):              # a speed change of dv at about |a| (or gentler), ramp 1 s
        d = max(abs(dv) / a + 1.0, 3.0)
        return Segment(d, accel=dv / (d - 1.0), ramp=1.0)

    while total < duration:
        new = [Segment(float(rng.uniform(8.0, 25.0)))]
        kind = rng.choice(('turn', 'stop', 'bend'), p=(0.4, 0.3, 0.3))
        target = float(rng.uniform(8.0, 14.0))
        if kind == 'turn':
            angle = float(rng.uniform(60.0, 100.0) * rng.choice((-1.0, 1.0)))
            rate = float(rng.uniform(12.0, 20.0))
            new += [change(5.0 - v, 2.0),
                    Segment(abs(angle) / rate + 1.0, turn_rate=np.sign(angle) * rate, ramp=0.5),
                    change(target - 5.0, 1.5)]
        elif kind == 'stop':
            new += [change(-v, 1.5), Segment(float(rng.uniform(5.0, 20.0))),
                    change(target, 1.5)]
        else:
            angle = float(rng.uniform(10.0, 40.0) * rng.choice((-1.0, 1.0)))
            rate = float(rng.uniform(2.0, 5.0))
            new += [Segment(abs(angle) / rate + 2.0, turn_rate=np.sign(angle) * rate, ramp=1.0),
                    change(target - v, 1.0)]
        segs += new
        total += sum(sg.duration for sg in new)
        v = target
    return segs


def _urban_car(name, description, imu, gnss, duration):
    return Scenario(
        name=name, description=description,
        trajectory=Trajectory(52.52, 13.40, 40.0, heading_deg=35.0, speed=10.0,
                              segments=urban_route(duration), name='urban_car'),
        imu=imu, gnss=gnss, duration=duration, misalignment_deg=(1.0, 1.0, 10.0))


def _car_consumer():
    return _urban_car(
        'car_consumer', 'car in town, under way from the start (10 m/s; junction turns, '
        'stops, bends): raw MEMS AHRS triads, consumer GNSS at 5 Hz (position 1 m white + '
        '1.5 m over 60 s, reporting 1 m; Doppler velocity 0.08 m/s)',
        SENSOR_GRADES['mems_ahrs'],
        GnssSpec(rate_hz=5.0, pos_sigma_h=1.0, pos_sigma_v=2.0, pos_markov_sigma=1.5,
                 pos_markov_tau_s=60.0, vel_sigma=0.08, reported_pos_sigma_h=1.0,
                 reported_pos_sigma_v=2.0),
        480.0)


def _car_rtk():
    sc = starting_still(_urban_car(
        'car_rtk', 'car in town (junction turns, stops, bends): MEMS IMU, RTK GNSS at 5 Hz '
        '(2 cm, 4 cm vertical, 0.02 m/s)', SENSOR_GRADES['mems'],
        GnssSpec(rate_hz=5.0, pos_sigma_h=0.02, pos_sigma_v=0.04, vel_sigma=0.02), 480.0),
        30.0, accel=1.5)
    sc.name = 'car_rtk'
    return sc


#: a mast-top GNSS antenna: 10 m aft of the IMU, 2 m to port, 18 m up (FLU)
MAST_LEVER_ARM_M = (-10.0, 2.0, 18.0)
#: robot_localization's test robot: its IMU turned +90 deg about x and -90 deg about z
ROBOT_IMU_MOUNTING_RPY_DEG = (90.0, 0.0, -90.0)


def _installed(factory, name, description, **fields):
    """Scenario of ``factory`` renamed, with installation ``fields`` set."""
    sc = factory()
    sc.name, sc.description = name, f'{sc.description}; {description}'
    for k, v in fields.items():
        setattr(sc, k, v)
    return sc


_FACTORIES = {
    'static_navigation': lambda: _static('navigation'),
    'static_tactical': lambda: _static('tactical'),
    'static_mems': lambda: _static('mems'),
    'seed002_1deg': lambda: _seed002(1),
    'seed002_5deg': lambda: _seed002(5),
    'seed002_10deg': lambda: _seed002(10),
    'seed000_case1': lambda: _seed000(1),
    'seed000_case2': lambda: _seed000(2),
    'seed001_flight': _flight,
    'seed003_car': _car,
    'seed004_high': lambda: _severe_sea('high'),
    'seed004_medium': lambda: _severe_sea('medium'),
    'seed004_low': lambda: _severe_sea('low'),
    'ship_sway': _ship_sway,
    'ship_underway': _ship_underway,
    'robot_lot': _robot,
    'robot_skid': _robot_skid,
    'car_consumer': _car_consumer,
    'car_rtk': _car_rtk,
    'ship_sway_mast': lambda: _installed(
        _ship_sway, 'ship_sway_mast', 'GNSS antenna at the masthead (18 m up)',
        gnss_lever_arm_m=MAST_LEVER_ARM_M),
    'ship_underway_mast': lambda: _installed(
        _ship_underway, 'ship_underway_mast', 'GNSS antenna at the masthead (18 m up)',
        gnss_lever_arm_m=MAST_LEVER_ARM_M),
    'seed003_car_rotated': lambda: _installed(
        _car, 'seed003_car_rotated', 'IMU mounted turned as robot_localization\'s test robot '
        '(+90 deg about x, -90 deg about z)', imu_mounting_rpy_deg=ROBOT_IMU_MOUNTING_RPY_DEG),
    'robot_skid_rotated': lambda: _installed(
        _robot_skid, 'robot_skid_rotated', 'IMU mounted turned as robot_localization\'s test '
        'robot (+90 deg about x, -90 deg about z)',
        imu_mounting_rpy_deg=ROBOT_IMU_MOUNTING_RPY_DEG),
}
#: names accepted by :func:`scenario`
SCENARIOS = tuple(_FACTORIES)


def scenario(name, **overrides):
    """Build the named scenario; keyword overrides replace its fields (e.g. ``duration``)."""
    try:
        sc = _FACTORIES[name]()
    except KeyError:
        raise ValueError(f'unknown scenario {name!r}; known: {", ".join(SCENARIOS)}') from None
    for k, v in overrides.items():
        if not hasattr(sc, k):
            raise ValueError(f'scenario has no field {k!r}')
        setattr(sc, k, v)
    return sc


def misalignment_rad(sc):
    """Return the scenario's initial misalignment in rad, (3,)."""
    return np.asarray(sc.misalignment_deg, dtype=float) * DEG


def translates(sc, min_speed=0.2):
    """Tell whether the scenario's vehicle moves horizontally faster than ``min_speed`` m/s.

    A moored, swaying ship does not translate (its zero-mean sway and heave keep
    the still-base models usable); a ship underway, a car or a USV does.
    """
    t = np.linspace(0.0, sc.duration, 401)
    v_n = sc.trajectory.kinematics(t).v_n
    return bool(np.max(np.hypot(v_n[:, 0], v_n[:, 1])) > min_speed)


def alignment_params(sc, fine_filter, **overrides):
    """Alignment parameters (``align.params`` names) that describe scenario ``sc`` honestly.

    The filter is told the simulated sensor grade: the constant gyro bias and its
    Gauss-Markov part (``gyro_bias_instability_dph``, ``gyro_bias_tau_s``), the
    accelerometer's constant and Gauss-Markov bias combined into one 1-sigma bias
    (no filter models a varying accelerometer bias), the white noises, the GNSS noise
    (with its Gauss-Markov position error where the receiver has one) and the
    scenario's position as the initial one; the installation (lever arm,
    mounting) when the scenario has one; the gyro and accelerometer scale factors and
    misalignment where the IMU has them (the accelerometer misalignment's part under
    gravity, a constant horizontal error, joins the accelerometer bias as well:
    :mod:`~sins_align_ros.align.engines.force_error`).
    ``sc.extra['alignment']`` adds scenario-specific settings; keyword overrides win.
    """
    s = sc.imu
    gyro_bias = float(np.max(np.abs(s.gyro_bias_dph)))
    # the accelerometer misalignment turns gravity into a constant horizontal error, a bias
    # to the filters (1e-6 g per ppm; align/engines/force_error.py models the rest of it)
    accel_bias = float(np.hypot(np.hypot(np.max(np.abs(s.accel_bias_ug)), s.accel_markov_ug),
                                np.max(np.abs(s.accel_misalign_ppm))))
    out = {'fine_filter': fine_filter, 'initial_latitude_deg': float(sc.trajectory.lat_deg),
           'initial_longitude_deg': float(sc.trajectory.lon_deg),
           'initial_height_m': float(sc.trajectory.h),
           'gyro_bias_dph': gyro_bias, 'gyro_arw_dpsh': float(s.gyro_arw_dpsh),
           'gyro_bias_instability_dph': float(s.gyro_markov_dph),
           'gyro_bias_tau_s': float(s.gyro_markov_tau_s),
           'accel_bias_ug': accel_bias, 'accel_vrw_ug_rthz': float(s.accel_vrw_ug_rthz)}
    # the triads' scale factors and misalignment (issue 44), where the IMU has them
    for name, value in (('gyro_scale_factor_ppm', s.gyro_scale_ppm),
                        ('gyro_misalignment_ppm', s.gyro_misalign_ppm),
                        ('accel_scale_factor_ppm', s.accel_scale_ppm),
                        ('accel_misalignment_ppm', s.accel_misalign_ppm)):
        if np.any(value):
            out[name] = float(np.max(np.abs(value)))
    if np.any(sc.gnss_lever_arm_m):
        out['gnss_lever_arm_m'] = tuple(float(v) for v in sc.gnss_lever_arm_m)
    if np.any(sc.imu_mounting_rpy_deg):
        out['imu_mounting_rpy_deg'] = tuple(float(v) for v in sc.imu_mounting_rpy_deg)
    if sc.gnss is not None:
        out['gnss_pos_sigma_m'] = float(sc.gnss.pos_sigma_h)
        out['gnss_vel_sigma_mps'] = float(sc.gnss.vel_sigma)
        out['gnss_height_sigma_m'] = float(sc.gnss.pos_sigma_v)
        if sc.gnss.pos_markov_sigma > 0.0:        # a receiver's time-correlated error
            out['gnss_position_markov_sigma_m'] = float(sc.gnss.pos_markov_sigma)
            out['gnss_position_markov_tau_s'] = float(sc.gnss.pos_markov_tau_s)
    out.update(sc.extra.get('alignment', {}))
    out.update(overrides)
    return out

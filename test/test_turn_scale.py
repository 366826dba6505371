"""The up gyro's scale factor measured from turns against the GNSS course (issue 44).

``car_consumer``'s town drive (junction turns of 60-100 deg between straight legs) with a
position-only receiver (2.5 Hz, 0.8 m white + 1.5 m over 60 s, reporting 0.9 m): the
self-check presumes 2 % for a MEMS triad's scale factors, which as noise put about 1.7
deg of heading sigma into every junction turn (bench/results/integrity_ground.md,
session 50: the car's heading sigma at the end 2.1-2.4 deg). The turns measure it.
"""
import math

import numpy as np
import pytest

from sins_align_ros.align.engines.registry import engine_class
from sins_align_ros.align.engines.rotation_error import COHERENCE_FACTOR, coherent_variance
from sins_align_ros.align.stages import turn_scale as ts
from sins_align_ros.eval.integrity import run_integrity
from sins_align_ros.eval.run import run_pipeline
from sins_align_ros.eval.scenarios import simulate
from sins_align_ros.nav import earth
from sins_align_ros.sim.gnss import GnssSpec
from sins_align_ros.sim.presets import SENSOR_GRADES, scenario
from sins_align_ros.sim.scenario import ScenarioStream

POSITION_ONLY = GnssSpec(rate_hz=2.5, pos_sigma_h=0.8, pos_sigma_v=1.6, pos_markov_sigma=1.5,
                         pos_markov_tau_s=60.0, vel_sigma=0.1, velocity=False,
                         reported_pos_sigma_h=0.9, reported_pos_sigma_v=1.8)


def _car(grade):
    sc = scenario('car_consumer')
    vib = {k: v for k, v in vars(sc.imu).items() if k.startswith('vibration_')}
    sc.imu = SENSOR_GRADES[grade].with_(**vib)
    sc.gnss = POSITION_ONLY
    return sc


def _defaults(sc, ff, **extra):
    tr = sc.trajectory
    return {'fine_filter': ff, 'initial_latitude_deg': tr.lat_deg,
            'initial_longitude_deg': tr.lon_deg, 'initial_height_m': tr.h, **extra}


@pytest.mark.slow
@pytest.mark.parametrize('grade, seed', [('mems_ahrs', 1003), ('mems_ahrs', 1006),
                                         ('mems', 1001)])
def test_the_turns_measure_the_scale_factor_and_the_heading_stops_paying_for_it(grade, seed):
    """kf with node defaults: the up scale factor measured from the turns lies within 3 of
    its sigmas of the simulated one (the AHRS's drawn 2 % class, or none for the plain
    MEMS grade), its sigma under half the presumed 2 % (7 turns of 60-100 deg, about 1
    deg of course noise each: 0.6-0.7 %); the heading ends inside 3
    sigma under 1.5 deg (the 2-deg bound of a car with a consumer receiver); without the
    measurement the heading sigma at the end is above that."""
    sc = _car(grade)
    s_true = ScenarioStream(sc, seed=seed).imu.errors.gyro_sm[2, 2]
    data = simulate(sc, seed)
    on = run_pipeline(_defaults(sc, 'kf'), data)
    off = run_pipeline(_defaults(sc, 'kf', turn_scale=False), data)
    st = on.pipeline.fine.monitor_status()
    s, sigma = st['turn_scale_ppm'] * 1e-6, st['turn_scale_sigma_ppm'] * 1e-6
    assert st['turn_scale_turns'] >= 5 and st['turn_scale_on'], st
    assert abs(s - s_true) <= 3.0 * sigma and sigma < 0.02 / 2.0, (s, sigma, s_true)
    r = run_integrity(on, sc.imu_rate_hz)
    assert not r['silent'], r['why']
    assert r['end_inside']
    assert r['end_sigma'][2] < math.radians(1.5)
    assert run_integrity(off, sc.imu_rate_hz)['end_sigma'][2] > r['end_sigma'][2]
    # the engine compensates what was measured; turned off, nothing
    assert on.pipeline.engine.sf[2] == pytest.approx(s, rel=1e-9)
    assert not np.any(off.pipeline.engine.sf)


class _Mech:
    lat = math.radians(45.0)
    h = 0.0

    def __init__(self):
        self.v_n = np.array([10.0, 0.0, 0.0])


class _Engine:
    """The two calls of the engine contract the measurement makes, and its ``mech``: the
    rotation it returns is compensated by the scale factor it was given."""

    def __init__(self):
        self.mech = _Mech()
        self.turn = 0.0
        self.given = []
        self.sf = 0.0

    def take_turn(self):
        A, self.turn = self.turn, 0.0
        return A / (1.0 + self.sf), 0.0, 0.0, 0.0, 0.0, 0.02 ** 2

    def set_turn_scale(self, s, sigma):
        self.given.append((s, sigma))
        self.sf = s if sigma is not None else 0.0
        return True


class _Fix:
    def __init__(self, lat, lon):
        self.lat, self.lon, self.h = lat, lon, 0.0
        self.pos_var = None
        self.v_n = None
        self.vel_var = None


def _drive(meas, eng, scale, crab_deg, legs=8, turn_deg=90.0, rate_hz=2.5, rng=None,
           alternate=False):
    """Straight 20-s legs at 10 m/s joined by turns of ``turn_deg`` at 15 deg/s (left and
    right in turn with ``alternate``); the gyro reads the turns with scale factor ``scale``,
    and the navigation frame's rate (Earth, and the transport rate of the engine's 10 m/s
    east); the leg's course is off its heading by ``crab_deg[i]``. Positions exact (``rng``
    None) or with 0.5 m of white noise."""
    lat0, lon0 = _Mech.lat, 0.0
    R_M, R_N = earth.radii(lat0)
    t, e, n, yaw = 0.0, 0.0, 0.0, 0.0
    dt = 1.0 / rate_hz
    w_up = earth.OMEGA_IE * math.sin(lat0) + 10.0 * math.tan(lat0) / R_N
    for i in range(legs):
        course = yaw + math.radians(crab_deg[i])
        for _ in range(int(20.0 * rate_hz)):
            t += dt
            e += 10.0 * math.cos(course) * dt
            n += 10.0 * math.sin(course) * dt
            eng.turn += w_up * dt
            pe, pn = (e, n) if rng is None else (e, n) + 0.5 * rng.standard_normal(2)
            meas.add(t, eng, _Fix(lat0 + pn / R_M, lon0 + pe / (R_N * math.cos(lat0))))
        rate = math.radians(15.0) * (-1.0 if alternate and i % 2 else 1.0)
        for _ in range(int(turn_deg / 15.0 * rate_hz)):
            t += dt
            yaw += rate * dt
            eng.turn += (1.0 + scale) * rate * dt + w_up * dt
            meas.add(t, eng, _Fix(lat0 + n / R_M, lon0 + e / (R_N * math.cos(lat0))))


def test_the_gyro_heading_holds_still_on_a_straight_drive():
    """No turn: the rotation the engine gives is the navigation frame's own (Earth and
    transport rate), which the gyro heading takes off; it stays at zero."""
    meas, eng = ts.TurnScale(sideslip_deg=0.5, pos_sigma=0.5), _Engine()
    _drive(meas, eng, 0.0, [0.0] * 4, legs=4, turn_deg=0.0)
    assert abs(meas.psi) < 1e-12 and meas.n_legs >= 2 and meas.n_turns == 0


@pytest.mark.parametrize('alternate', [False, True])
def test_a_scale_factor_is_found_from_the_turns(alternate):
    """A 1.5 % scale factor, 0.5 m position noise, no sideslip; 90-deg turns all one way or
    left and right in turn: found to within 3 of its sigmas, the sigma under a quarter of
    the told 2 % and shrinking turn after turn, every leg used."""
    meas, eng = ts.TurnScale(sideslip_deg=0.5, pos_sigma=0.5), _Engine()
    _drive(meas, eng, 0.015, [0.0] * 8, rng=np.random.default_rng(5), alternate=alternate)
    s, sigma = meas.estimate
    assert meas.n_turns == 7 and meas.n_rejected == 0
    assert abs(s - 0.015) < 3.0 * sigma and sigma < 0.005
    sigmas = [g[1] for g in eng.given]
    assert sigmas == sorted(sigmas, reverse=True)


def test_a_kf_engine_gives_its_turn_and_compensates_the_measured_scale_factor():
    """The navigation engine's side: the rotation about up of its increments; the measured
    scale factor divides its z increments and its sigma replaces the told one about z in
    the turn noise; once GNSS velocity and a known heading make the scale factors states,
    it takes no more (returns False, gives no turn)."""
    P0, Qc = np.eye(15) * 1e-4, np.zeros(15)
    eng = engine_class('kf')(np.eye(3), np.zeros(3), 0.9, 0.2, 40.0, P0, Qc, np.eye(6))
    eng.set_rotation_error(0.02, 0.005)
    eng.take_turn()
    for _ in range(10):
        eng.step_imu(np.array([0.0, 0.0, 0.01]), np.array([0.0, 0.0, 0.098]), 0.01)
    A, eps_applied, eps, var_eps, q_eps, prior_var = eng.take_turn()
    assert A == pytest.approx(0.1, rel=1e-12) and prior_var == pytest.approx(0.02 ** 2)
    assert eng.set_turn_scale(0.01, 0.002)
    assert eng._correct_imu(np.array([0.0, 0.0, 0.0101]), np.zeros(3), 0.01)[0][2] == (
        pytest.approx(0.0101 / 1.01, rel=1e-12))
    rot = COHERENCE_FACTOR * np.array([0.02, 0.02, 0.002])
    assert np.allclose(coherent_variance([0.0, 0.0, 1.0], rot, 0.01),
                       coherent_variance([0.0, 0.0, 1.0], COHERENCE_FACTOR * 0.002, 0.01))
    eng._rot_A, eng._rot = np.zeros(3), np.zeros(3)
    eng.step_imu(np.array([0.0, 0.0, 0.5]), np.zeros(3), 0.01)
    E = eng._rotation_noise(0.01)
    k = np.arange(15)[eng.i_phi][2]
    # the heading rows take the told 1x: (sigma x the compensated rotation)^2
    assert E[k, k] == pytest.approx((0.002 * 0.5 / 1.01) ** 2, rel=1e-6)
    eng.velocity_measured = True
    eng._interval_ended(1.0)
    assert eng.i_sf is not None and eng._turn_scale_sigma is None
    assert not eng.set_turn_scale(0.01, 0.002) and eng.take_turn() is None


def test_courses_that_jump_from_leg_to_leg_turn_the_measurement_off():
    """A vehicle crabbing by 30 deg, one way on a leg, the other on the next (far beyond a
    0.5-deg sideslip, and than the told 2 % of 1-3 turns): three legs in a row refused,
    the engine gets its told model back (sigma None) and a WARN says why; nothing more is
    measured."""
    meas, eng = ts.TurnScale(sideslip_deg=0.5, pos_sigma=0.5), _Engine()
    _drive(meas, eng, 0.0, [0.0] + [30.0 * (-1) ** i for i in range(7)])
    assert meas.off and meas.n_rejected == ts.MAX_REJECTED
    assert eng.given[-1] == (0.0, None)
    assert any('no longer measured from turns' in w for w in meas.take_findings())
    assert not meas.take_findings()            # said once
    n = len(eng.given)
    _drive(meas, eng, 0.0, [0.0] * 4, legs=4)
    assert len(eng.given) == n

"""The installation: a rotated IMU and a GNSS antenna on a lever arm, against truth."""
import numpy as np
import pytest

from sins_align_ros.align import params as prm
from sins_align_ros.align.param_text import parse_value
from sins_align_ros.align.inputs.gnss_fix import GnssFix
from sins_align_ros.align.inputs.installation import Installation
from sins_align_ros.eval.run import run_pipeline, run_scenario
from sins_align_ros.eval.scenarios import named, simulate
from sins_align_ros.nav import coarse, earth
from sins_align_ros.nav.frames import euler_rates_to_w_nb_b, euler_to_dcm
from sins_align_ros.sim.presets import (MAST_LEVER_ARM_M, ROBOT_IMU_MOUNTING_RPY_DEG,
                                        alignment_params, scenario)
from sins_align_ros.sim.scenario import antenna_truth
from sins_align_ros.units import ARCMIN, DEG


def test_array_parameters_read_from_yaml_text_and_are_checked():
    assert parse_value('gnss_lever_arm_m', '[-12.0, 3, 18]') == (-12.0, 3.0, 18.0)
    with pytest.raises(ValueError, match='array of 3 numbers'):
        parse_value('gnss_lever_arm_m', '[1, 2]')
    with pytest.raises(ValueError, match='array of 3 numbers'):
        parse_value('imu_mounting_rpy_deg', 'abc')
    assert prm.validate({'imu_mounting_rpy_deg': [90, 0, -90]}) == {
        'imu_mounting_rpy_deg': (90.0, 0.0, -90.0)}
    with pytest.raises(ValueError, match='outside'):
        prm.validate({'gnss_lever_arm_m': [0.0, 0.0, 1e4]})
    with pytest.raises(ValueError, match='non-finite'):
        prm.validate({'gnss_lever_arm_m': [0.0, float('nan'), 0.0]})


def test_mounting_rotation_is_undone_exactly():
    """robot_localization's rotated IMU: the same increments, hence the same attitude."""
    sc = scenario('static_tactical', duration=90.0)
    rot = scenario('static_tactical', duration=90.0,
                   imu_mounting_rpy_deg=ROBOT_IMU_MOUNTING_RPY_DEG)
    a, b = simulate(sc, 3), simulate(rot, 3)
    assert np.max(np.abs(a.imu.dv - b.imu.dv)) > 0.05         # the IMU axes really differ
    ra = run_pipeline(alignment_params(sc, 'auto'), a)
    rb = run_pipeline(alignment_params(rot, 'auto'), b)
    assert rb.pipeline.configured['imu_mounting_rpy_deg'] == (90.0, 0.0, -90.0)
    ok = np.isfinite(ra.out.q[:, 0])
    assert ok.sum() > 1000 and np.array_equal(ok, np.isfinite(rb.out.q[:, 0]))
    assert np.max(np.abs(ra.out.euler[ok] - rb.out.euler[ok])) < 1e-9
    assert np.max(np.abs(ra.out.sigma[ok] - rb.out.sigma[ok])) < 1e-9
    assert not rb.pipeline.check.mounting_doubt
    assert rb.pipeline.check.figures['vehicle_tilt_deg'] < 1.0
    # told nothing, the pipeline finds the IMU's attitude, 90 deg away, and says so: the
    # self-check's mounting check publishes it as unknown, never aligned
    rc = run_pipeline(alignment_params(sc, 'auto'), b)
    assert abs(rc.out.euler[-1, 0] - ra.out.euler[-1, 0]) > 80 * DEG
    p = rc.pipeline
    assert p.check.figures['vehicle_tilt_deg'] == pytest.approx(90.0, abs=1.0)
    assert any('imu_mounting_rpy_deg' in w and 'never aligned' in w for w in p.warnings)
    assert 'aligned' not in set(rc.out.phase)
    fine_rows = rc.out.phase == 'fine'
    assert fine_rows.sum() > 1000 and np.all(rc.out.sigma[fine_rows] > 100 * DEG)
    why = p.status()['not_aligned_reason']
    assert 'imu_mounting_rpy_deg untold' in why or 'imu_mounting_rpy_deg:' in why, why
    e = p.expectation()
    assert e.t_aligned == np.inf and 'imu_mounting_rpy_deg' in e.note


@pytest.mark.parametrize('roll_deg, doubt', [(30.0, False), (-60.0, True), (180.0, True)])
def test_the_mounting_check_takes_a_heeled_vehicle_for_one_and_a_side_mount_for_a_mounting(
        roll_deg, doubt):
    """A vehicle frame rolled 30 deg (a heeling sailing boat) is a vehicle; 60 deg, or
    upside down, is an IMU mounted rotated and left untold (mounting_check_max_tilt_deg
    45)."""
    rot = scenario('static_tactical', duration=75.0, imu_mounting_rpy_deg=(roll_deg, 0.0, 0.0))
    run = run_pipeline(alignment_params(scenario('static_tactical', duration=75.0), 'auto'),
                       simulate(rot, 4))
    p = run.pipeline
    assert p.check.figures['vehicle_tilt_deg'] == pytest.approx(abs(roll_deg), abs=1.0)
    assert bool(p.check.mounting_doubt) == doubt
    assert (p.fine.attitude_cov()[0, 0] > 1.0) == doubt
    if doubt and abs(roll_deg) < 90.0:
        assert f'about [{roll_deg:.0f}, 0]' in p.check.mounting_doubt


def test_the_robot_car_with_its_imu_turned_and_untold_is_never_aligned_and_says_why():
    """seed003_car_rotated told no mounting: before the check, 51/79 deg of tilt error
    (RMS of 10 runs) under a 37'/39' sigma, aligned in 1 run of 10
    (bench/results/installation.md)."""
    run = run_scenario('seed003_car_rotated', 1000, 'auto', duration=150.0,
                       imu_mounting_rpy_deg=(0.0, 0.0, 0.0))
    p = run.pipeline
    assert p.check.mounting_doubt and p.phase != 'aligned'
    assert 'aligned' not in set(run.out.phase)
    f = run.final
    assert np.all(np.abs(f.euler) <= 3.0 * f.sigma)


def test_fix_to_imu_recovers_the_imu_truth_from_the_antenna():
    """The antenna of a swaying ship, moved back with the true attitude and rate."""
    sc = scenario('ship_underway_mast')
    traj = sc.trajectory
    t = np.array([100.0, 250.5, 333.3])
    pos = np.column_stack([np.full(3, traj.lat_deg * DEG), np.full(3, traj.lon_deg * DEG),
                           np.zeros(3)])
    ant, v_ant = antenna_truth(traj, t, pos, MAST_LEVER_ARM_M)
    kin = traj.kinematics(t)
    inst = Installation(MAST_LEVER_ARM_M)
    for k in range(3):
        C = euler_to_dcm(kin.euler[k])
        w = euler_rates_to_w_nb_b(kin.euler[k], kin.euler_rate[k])
        fix = inst.fix_to_imu(GnssFix(t[k], *ant[k], v_n=v_ant[k]), C, w, np.zeros((3, 3)))
        d = earth.local_offset_m(pos[k, 0], pos[k, 1], pos[k, 2], np.array([fix.lat]),
                                 np.array([fix.lon]), np.array([fix.h]))[0]
        assert np.all(np.abs(d) < 1e-3)                           # m
        assert np.all(np.abs(fix.v_n - kin.v_n[k]) < 1e-4)        # m/s (transport rate)
        assert np.linalg.norm(v_ant[k] - kin.v_n[k]) > 0.05       # the arm mattered


def test_arm_variance_is_the_attitude_error_seen_through_the_arm():
    """Arm straight up, L m: tilts move the antenna by L phi; heading does not."""
    inst = Installation((0.0, 0.0, 20.0))
    P = np.diag([1e-4, 4e-4, 9e-2])
    fix = inst.fix_to_imu(GnssFix(0.0, 0.6, 2.0, 10.0, v_n=np.zeros(3)), np.eye(3),
                          np.array([0.1, 0.0, 0.0]), P, rate_var=1e-6)
    assert np.allclose(fix.arm_var[:3], [400 * 4e-4, 400 * 1e-4, 0.0])
    # velocity (w x l) = (0, -2, 0) m/s: heading and east tilt errors turn it
    assert np.allclose(fix.arm_var[3:], np.array([4 * 9e-2, 0.0, 4 * 1e-4]) + 400e-6)
    assert Installation().fix_to_imu(fix, np.eye(3), np.zeros(3), P) is fix


def test_coarse_fit_takes_the_arm_velocity_from_the_gyros():
    """Inertial-frame coarse alignment with the antenna's velocity: the arm term restores it."""
    sc = scenario('ship_underway_mast', duration=60.0)
    data = simulate(sc, 2)
    imu = data.imu
    n = len(imu.t)
    dt = np.full(n, imu.t[1] - imu.t[0])
    pos = imu.pos
    _, v_ant = antenna_truth(sc.trajectory, imu.t, pos, MAST_LEVER_ARM_M)
    lat, h = pos[0, 0], pos[0, 2]
    C_true = euler_to_dcm(imu.euler[-1])

    def heading_error(dv_n, arm):
        C = coarse.inertial_frame(imu.dtheta, imu.dv, dt, lat, h, dv_n=dv_n, arm_b=arm)
        return abs(np.degrees(np.arctan2((C @ C_true.T)[1, 0], (C @ C_true.T)[0, 0])))

    imu_err = heading_error(imu.v_n - imu.v_n[0], None)
    assert heading_error(v_ant - v_ant[0], np.array(MAST_LEVER_ARM_M)) < imu_err + 0.05
    assert heading_error(v_ant - v_ant[0], None) > 5 * imu_err + 0.5


@pytest.mark.parametrize('flt, seed', [('kf', 1001), ('ukf', 1001), ('ckf', 1001),
                                       ('asckf', 1002)])
def test_mast_antenna_aligns_as_well_as_a_co_located_one(flt, seed):
    """(asckf on seed 1002: its Sage-Husa R once took the arm's lent variance for the
    receiver's and ended 20' off under a 2.8' sigma; filters/adaptive.py.)"""
    run = run_scenario('ship_underway_mast', seed, flt)
    base = run_scenario('ship_underway', seed, flt)
    f, g = run.final, base.final
    assert run.pipeline.phase == 'aligned'
    assert np.all(np.abs(f.euler) <= 3.0 * f.sigma + 1e-9)
    assert abs(f.euler[2]) < abs(g.euler[2]) + 1.0 * ARCMIN
    # the arm's coupling with the attitude is taken as noise (align/inputs/installation.py): a
    # little wider, never narrower than the error
    assert f.sigma[2] < 2.0 * g.sigma[2]


def test_ignoring_the_mast_costs_the_heading():
    """Told no arm and the self-check off, the sway of an 18 m mast reads as velocity noise
    and costs the heading: off by more than 3' or, where the filter's consistency checks
    see it, a sigma ten times the told arm's. (Seed 1000 with a 60-s window: 4.6' off told
    no arm, 1.4' told the arm; with the 20-s window of a base moving from the start, since
    session 52: 1.5' off under a 57' sigma.)"""
    run = run_scenario('ship_underway_mast', 1000, 'kf', gnss_lever_arm_m=(0.0, 0.0, 0.0),
                       sensor_self_check=False)
    told = run_scenario('ship_underway_mast', 1000, 'kf')
    assert (abs(run.final.euler[2]) > 3.0 * ARCMIN
            or run.final.sigma[2] > 10.0 * told.final.sigma[2])


def test_the_self_check_finds_an_untold_mast_and_uses_it():
    """Told no arm, the coarse window's velocities show the mast (align/stages/arm_check.py):
    its arm replaces the configured one and the attitude is as good as told it. (Without
    the fit: heading 4.7' off, tilt 0.86' under a 0.05' sigma, 17 sigma.)"""
    told = run_scenario('ship_underway_mast', 1000, 'kf')
    run = run_scenario('ship_underway_mast', 1000, 'kf', gnss_lever_arm_m=(0.0, 0.0, 0.0))
    p = run.pipeline
    np.testing.assert_allclose(p.cfg['gnss_lever_arm_m'], MAST_LEVER_ARM_M, atol=0.5)
    assert p.install.l_v == pytest.approx(p.cfg['gnss_lever_arm_m'])
    assert any('gnss_lever_arm_m set to the fit' in w for w in p.warnings)
    s = p.status()                                       # what /diagnostics shows
    assert 'gnss_lever_arm_m=[' in s['self_check_widened']
    assert s['self_check_gnss_lever_arm_chi2'] > 1000.0
    f = run.final
    assert p.phase == 'aligned'
    assert np.all(np.abs(f.euler) <= 3.0 * f.sigma)
    assert np.all(np.abs(f.euler[:2]) < 0.1 * ARCMIN)
    assert abs(f.euler[2]) < abs(told.final.euler[2]) + 0.5 * ARCMIN


@pytest.mark.parametrize('name, seed, arm', [
    ('ship_underway', 1001, (0.0, 0.0, 0.0)), ('ship_underway_mast', 1001, MAST_LEVER_ARM_M),
    ('seed003_car', 1000, (0.0, 0.0, 0.0)), ('seed004_medium', 1005, (0.0, 0.0, 0.0))])
def test_a_right_arm_is_left_alone(name, seed, arm):
    """No antenna offset, or the right one told: the fit finds nothing (a chi-square of a
    few against the 50 that replaces the arm), on a ship, a car and a USV in severe sea
    with GNSS outliers."""
    run = run_scenario(name, seed, 'kf', duration=70.0, gnss_lever_arm_m=arm)
    p = run.pipeline
    assert p.cfg['gnss_lever_arm_m'] == tuple(arm)
    assert p.check.figures['gnss_lever_arm_chi2'] < 10.0


def test_a_mast_straight_up_takes_the_antenna_above_the_imu():
    """An arm along the mast alone: the horizontal velocities cannot tell +18 m from -18 m
    (with the heading half a turn away), nor the vertical ones (a vertical arm moves the
    antenna sideways): the fit takes the antenna above the IMU."""
    sc = named('ship_underway_mast', 70.0)
    sc.gnss_lever_arm_m = (0.0, 0.0, 18.0)
    run = run_scenario(sc, 1000, 'kf', gnss_lever_arm_m=(0.0, 0.0, 0.0))
    p = run.pipeline
    np.testing.assert_allclose(p.cfg['gnss_lever_arm_m'], (0.0, 0.0, 18.0), atol=0.5)
    assert any('antenna above the IMU' in w for w in p.warnings)


def test_a_moored_ship_with_a_mast_antenna_is_not_taken_for_moving():
    """The antenna sways at about a metre per second; the IMU does not translate."""
    run = run_scenario('ship_sway_mast', 1, 'auto', duration=150.0)
    p = run.pipeline
    assert p.n_restarts == 0
    assert p.cfg['fine_filter'] == p.configured['auto_still_filter']


def test_the_sideslip_check_judges_the_velocity_in_the_vehicle_frame():
    """Forward (with a 20 deg crab) is a vehicle; 90 deg is an IMU turned about the vertical."""
    from sins_align_ros.align.stages.sideslip import MIN_EPOCHS, SideslipCheck
    C = euler_to_dcm([0.0, 0.0, 0.3])                       # yaw 0.3 rad (REP-103, from east)

    def velocity(angle_deg, speed=3.0):
        return C @ (speed * np.array([np.cos(np.radians(angle_deg)),
                                      np.sin(np.radians(angle_deg)), 0.0]))

    crab = SideslipCheck(45.0)
    assert not any(crab.add(velocity(20.0), C, 1e-4) for _ in range(100))
    turned = SideslipCheck(45.0)
    found = [turned.add(velocity(-90.0), C, 1e-4) for _ in range(MIN_EPOCHS)]
    assert not any(found[:-1]) and 'about 90 deg' in found[-1]
    # not judged: too slow, the heading not known, or the check off
    for check, v, var in ((SideslipCheck(45.0), velocity(-90.0, 0.5), 1e-4),
                          (SideslipCheck(45.0), velocity(-90.0), np.radians(20.0) ** 2),
                          (SideslipCheck(180.0), velocity(-90.0), 1e-4)):
        assert not any(check.add(v, C, var) for _ in range(100))


def test_the_sideslip_check_judges_old_epochs_in_the_heading_known_now():
    """A heading that starts as the GNSS course and is corrected by 80 deg: the old epochs move.

    Session 47: with stale angles the median stayed under the bound for 20 more epochs and
    the ship under way was aligned before the mounting check saw its turned IMU.
    """
    from sins_align_ros.align.stages.sideslip import MIN_EPOCHS, SideslipCheck
    v_n = np.array([0.0, 5.0, 0.0])                           # northwards
    course = euler_to_dcm([0.0, 0.0, np.pi / 2])              # heading taken from the course
    check = SideslipCheck(45.0)
    assert not any(check.add(v_n, course, 1e-4) for _ in range(MIN_EPOCHS))
    stale = SideslipCheck(45.0)
    for _ in range(MIN_EPOCHS):
        stale.add(v_n, course, 1e-4)
    # the filter turns the heading 80 deg (yaw +80: C_after = Rz(80) C_before, phi_up = -80)
    for _ in range(8):
        check.correct(np.radians(-10.0))
    turned = euler_to_dcm([0.0, 0.0, np.pi / 2 + np.radians(80.0)])
    found = check.add(v_n, turned, 1e-4)
    assert 'lies 80 deg' in found and 'about 80 deg' in found
    # without the corrections the old epochs keep the median at zero
    assert not stale.add(v_n, turned, 1e-4)


@pytest.mark.parametrize('name', ['ship_underway', 'seed003_car'])
def test_an_imu_turned_about_the_vertical_and_untold_is_found_under_way(name):
    """A yaw mounting leaves gravity alone: the GNSS velocity shows it (align/stages/sideslip.py).
    Before: the ship published 91 deg off (its IMU's heading) under a 0.09 deg sigma,
    aligned; the car 123 deg off under 5.5 deg."""
    sc = named(name, 300.0)
    sc.imu_mounting_rpy_deg = (0.0, 0.0, 90.0)
    run = run_scenario(sc, 1000, 'auto', imu_mounting_rpy_deg=(0.0, 0.0, 0.0))
    p = run.pipeline
    # the mounting check (sideslip.py), or the slow-error monitor first (slow_monitor.py: the
    # heading off the course on straight legs, the same evidence): either names the mounting
    # (on the ship the monitor fires first and opens the heading, so the mounting check, which
    # judges only a heading known within 10 deg, never reaches its verdict)
    found = p.fine.mounting_doubt or (p.fine.slow.finding if p.fine.slow else '')
    assert 'turned about the vertical' in found
    assert 'aligned' not in set(run.out.phase)
    f = run.final
    assert np.all(np.abs(f.euler) <= 3.0 * f.sigma)
    why = p.status()['not_aligned_reason']
    assert 'imu_mounting_rpy_deg untold' in why or 'imu_mounting_rpy_deg:' in why, why

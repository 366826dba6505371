"""simulator_node's ``grade`` parameter and ``sins_align_record`` (a scenario into a rosbag2).

The node's messages over real DDS are compared field for field with the recorder's bag; the
bag's samples with the simulation; its replay with the pipeline fed the simulation.
"""
import os
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import ROOT, run_simulator
from sins_align_ros.align.output import Output
from sins_align_ros.align.session import AlignmentSession
from sins_align_ros.cli.record import main as record
from sins_align_ros.cli.replay import load_parameters, main as replay
from sins_align_ros.io.bag import read_bag
from sins_align_ros.io.results import read_csv
from sins_align_ros.io.sim_messages import TOPICS, simulated_scenario
from sins_align_ros.nav.frames import euler_to_quat, quat_to_euler
from sins_align_ros.sim.presets import SENSOR_GRADES
from sins_align_ros.sim.scenario import ScenarioStream
from sins_align_ros.units import ARCMIN, DEG, DPSH, UG

START = 1_700_000_000.0
START_NS = 1_700_000_000 * 10 ** 9


def _simulation(sc, seed, seconds):
    """The scenario simulated as the node and the recorder do it: in 1-s blocks (the noise
    draws depend on the blocks, sim/imu.py). Returns (imu, gnss) with the blocks joined."""
    st = ScenarioStream(sc, seed=seed)
    blocks = [st.next_block(100) for _ in range(seconds)]
    imu = SimpleNamespace(**{k: np.concatenate([getattr(b.imu, k) for b in blocks])
                             for k in ('t', 'dtheta', 'dv', 'euler')})
    gnss = SimpleNamespace(**{k: np.concatenate([getattr(b.gnss, k) for b in blocks])
                              for k in ('t', 'lat', 'lon', 'h', 'v_n', 'fix')},
                           pos_cov=blocks[0].gnss.pos_cov, vel_cov=blocks[0].gnss.vel_cov)
    return imu, gnss


def _raw_messages(bag):
    """Topic key -> list of (receive ns, raw CDR) of a rosbag2, in recording order."""
    from rosbags.rosbag2 import Reader
    key = {'/' + name: k for k, (name, _) in TOPICS.items()}
    out = {k: [] for k in TOPICS}
    with Reader(bag) as r:
        for conn, ns, raw in r.messages():
            out[key[conn.topic]].append((ns, bytes(raw)))
    return out


def _white_noise(msgs, field):
    """Per-sample white-noise sigma of a still IMU's rate or specific force, from differences."""
    x = np.array([[getattr(m, field).x, getattr(m, field).y, getattr(m, field).z]
                  for m in msgs])
    return np.std(np.diff(x, axis=0)) / np.sqrt(2.0)


@pytest.mark.ros
@pytest.mark.exclusive
def test_grade_parameter_sets_the_published_noise_and_the_bag_holds_the_same_messages(
        ros_context, tmp_path):
    """grade:=mems on the navigation-grade still scenario: the published covariances and
    the noise in the samples are the MEMS grade's; sins_align_record with the same
    settings writes every message the node published, field for field, at its stamp (not
    byte for byte: the CDR padding bytes rclpy sends are not initialised)."""
    from rclpy.serialization import deserialize_message
    dt = 0.01
    sims = {}
    for grade in ('', 'mems'):
        sims[grade] = run_simulator(ros_context, scenario='static_navigation', grade=grade,
                                    duration=30.0, seed=7, start_time=START)[:2]
    assert sims[''][0].imu is SENSOR_GRADES['navigation']
    assert sims['mems'][0].imu is SENSOR_GRADES['mems']
    for grade, (sc, got) in sims.items():
        spec = SENSOR_GRADES[grade or 'navigation']
        gyro = spec.gyro_arw_dpsh * DPSH / np.sqrt(dt)        # rad/s per sample
        accel = spec.accel_vrw_ug_rthz * UG / np.sqrt(dt)     # m/s^2 per sample
        imu = got['imu']
        assert len(imu) == 3000
        assert imu[0].angular_velocity_covariance[4] == pytest.approx(gyro ** 2, rel=1e-12)
        assert imu[0].linear_acceleration_covariance[8] == pytest.approx(accel ** 2, rel=1e-12)
        # 3 x 2999 differences (neighbours correlated): a sigma estimate good to about 1.3 %
        assert _white_noise(imu, 'angular_velocity') == pytest.approx(gyro, rel=0.05)
        assert _white_noise(imu, 'linear_acceleration') == pytest.approx(accel, rel=0.05)
    # 3000 times the ARW: the two runs are told apart by far more than the 5 % above
    assert (_white_noise(sims['mems'][1]['imu'], 'angular_velocity')
            > 1000 * _white_noise(sims[''][1]['imu'], 'angular_velocity'))

    bag = tmp_path / 'mems_bag'
    assert record(['--scenario', 'static_navigation', '--grade', 'mems', '--duration', '30',
                   '--seed', '7', '--start-time', str(START), '--out', str(bag)]) == 0
    raw = _raw_messages(bag)
    got = sims['mems'][1]
    assert {k: len(v) for k, v in raw.items()} == {'imu': 3000, 'fix': 30, 'vel': 30,
                                                   'truth': 300}
    for key in TOPICS:
        assert len(got[key]) == len(raw[key]), key
        for m, (ns, data) in zip(got[key], raw[key]):
            assert ns == m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec
            assert deserialize_message(data, type(m)) == m, key
    assert raw['imu'][0][0] == START_NS + 10_000_000
    assert raw['imu'][-1][0] == START_NS + 30 * 10 ** 9


def test_unknown_grade_is_refused_by_the_node_and_the_recorder(tmp_path, capsys, domain_id):
    """One line naming the known grades, exit code 2, nothing written."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    proc = subprocess.run([sys.executable, '-m', 'sins_align_ros.ros.simulator_node',
                           '--ros-args', '-p', 'grade:=memss'], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=60.0)
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and "unknown sensor grade 'memss'" in err[0], proc.stderr
    assert ', '.join(SENSOR_GRADES) in err[0]
    assert record(['--scenario', 'seed003_car', '--grade', 'memss', '--out',
                   str(tmp_path / 'bag')]) == 2
    err = capsys.readouterr().err
    assert "unknown sensor grade 'memss'" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / 'bag').exists()
    assert record(['--scenario', 'seed003_car', '--duration', '-5', '--out',
                   str(tmp_path / 'bag')]) == 2
    assert '--duration -5.0 is outside' in capsys.readouterr().err
    (tmp_path / 'bag').mkdir()
    assert record(['--scenario', 'seed003_car', '--out', str(tmp_path / 'bag')]) == 2
    assert 'exists already' in capsys.readouterr().err


def test_simulator_warns_about_an_unknown_parameter(domain_id):
    """A misspelt override (``grdae``) is named with the closest parameter; the node runs."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    proc = subprocess.run([sys.executable, '-m', 'sins_align_ros.ros.simulator_node',
                           '--ros-args', '-p', 'grdae:=mems', '-p', 'duration:=1.0',
                           '-p', 'real_time_factor:=0.0', '-p', 'shutdown_when_done:=true'],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=60.0)
    assert proc.returncode == 0, proc.stderr
    warn = [line for line in proc.stderr.splitlines() if 'grdae' in line]
    assert warn and 'WARN' in warn[0] and "'grade'" in warn[0], proc.stderr


def test_recorded_bag_replays_the_simulation_sample_for_sample(tmp_path):
    """The USV in severe sea (GNSS outliers) with the low-grade USV IMU: every IMU sample,
    GNSS epoch and truth attitude read back from the bag is the simulation's, stamped
    start + k dt."""
    bag = tmp_path / 'usv_bag'
    assert record(['--scenario', 'seed004_high', '--grade', 'usv_low', '--duration', '30',
                   '--seed', '3', '--start-time', str(START), '--out', str(bag)]) == 0
    rec = read_bag(bag)
    assert rec.error is None
    imu, g = _simulation(simulated_scenario('seed004_high', 'usv_low', 30.0), 3, 30)
    dt = 0.01
    assert len(rec.t) == 3000
    np.testing.assert_array_equal(np.round((rec.t - START) / dt), np.arange(1, 3001))
    assert np.abs(rec.t - (START + imu.t)).max() < 1e-6        # float seconds of 1.7e9
    # rates = increments / dt, through float64 CDR: the same numbers
    np.testing.assert_array_equal(rec.w, imu.dtheta / dt)
    np.testing.assert_array_equal(rec.f, imu.dv / dt)
    assert not rec.missing.any()
    fixes = [e for e in rec.events if e.kind == 'fix']
    vels = [e for e in rec.events if e.kind == 'vel']
    truth = [e for e in rec.events if e.kind == 'truth']
    assert len(fixes) == len(g.t) == 30 and len(vels) == int(g.fix.sum())
    fix_ok = [e for e in fixes if e.data[0] == 0]
    assert len(fix_ok) == int(g.fix.sum())
    lat = np.array([e.data[1] for e in fix_ok])
    np.testing.assert_array_equal(lat, np.degrees(g.lat[g.fix]))
    v = np.array([e.data[0] for e in vels])
    np.testing.assert_array_equal(v, g.v_n[g.fix])
    assert fix_ok[0].data[4] == tuple(g.pos_cov[:2])
    assert len(truth) == 300
    q = np.array([e.data[0] for e in truth])
    np.testing.assert_array_equal(q, euler_to_quat(imu.euler[9::10]))


def test_replay_of_a_recorded_bag_matches_the_session_fed_the_simulation(tmp_path):
    """sins_align_record then sins_align_replay gives, row for row to the CSV's decimals,
    what an AlignmentSession gives fed the same simulation directly, as the node receives
    it: rates (increment / dt) at the stamps ``start + round(t, ns)``, an IMU sample
    before a GNSS epoch of the same stamp (the simulator publishes in that order); and
    the final attitude is the truth's within its 3 sigma."""
    bag, out = tmp_path / 'ship', tmp_path / 'ship.csv'
    assert record(['--scenario', 'ship_underway', '--grade', 'tactical', '--duration', '150',
                   '--seed', '2', '--start-time', str(START), '--out', str(bag)]) == 0
    sets = ['fine_filter=asckf', 'coarse_duration=30.0', 'gyro_bias_dph=1.0',
            'gyro_arw_dpsh=0.05', 'accel_bias_ug=300.0', 'accel_vrw_ug_rthz=50.0']
    assert replay([str(bag), *[a for s in sets for a in ('--set', s)], '--out', str(out),
                   '--quiet']) == 0
    cols = read_csv(out)

    imu, g = _simulation(simulated_scenario('ship_underway', 'tactical', 150.0), 2, 150)
    dt = 0.01
    ns, g_ns = (START_NS + np.round(x * 1e9).astype(np.int64) for x in (imu.t, g.t))
    t, g_t = ((x // 10 ** 9) + (x % 10 ** 9) * 1e-9 for x in (ns, g_ns))
    session = AlignmentSession(load_parameters(None, sets), block=2000)
    outs, k = [], 0
    for j in range(len(g_t)):
        k1 = int(np.searchsorted(ns, g_ns[j], side='right'))
        outs.append(session.imu_block(t[k:k1], imu.dtheta[k:k1] / dt, imu.dv[k:k1] / dt))
        k = k1
        assert g.fix[j]
        outs.append(session.fix(g_t[j], 0, np.degrees(g.lat[j]), np.degrees(g.lon[j]), g.h[j],
                                tuple(g.pos_cov[:2])))
        outs.append(session.velocity(g_t[j], tuple(g.v_n[j]), tuple(g.vel_cov[:2])))
    outs += [session.imu_block(t[k:], imu.dtheta[k:] / dt, imu.dv[k:] / dt), session.finish()]
    direct = Output.concat(outs)

    assert len(cols['t']) == len(direct.t) == 14999            # sample 0 starts the clock
    np.testing.assert_allclose(cols['t'], direct.t, rtol=0, atol=1e-9)
    assert list(cols['phase']) == list(direct.phase) and direct.phase[-1] == 'aligned'
    fine = np.isfinite(direct.q[:, 0])
    assert fine.sum() > 10_000
    q = np.column_stack([cols[k] for k in ('qx', 'qy', 'qz', 'qw')])
    np.testing.assert_allclose(q[fine], direct.q[fine], rtol=0, atol=1e-12)
    sig = np.column_stack([cols[f'sigma_{a}_deg'] for a in ('roll', 'pitch', 'yaw')]) * DEG
    np.testing.assert_allclose(sig[fine], direct.sigma[fine], rtol=1e-8, atol=1e-11)
    err = quat_to_euler(q[-1]) - imu.euler[-1]                 # REP-103 angles, as sigma
    err[2] = (err[2] + np.pi) % (2 * np.pi) - np.pi
    assert np.all(np.abs(err) <= 3 * sig[-1]), (err / ARCMIN, sig[-1] / ARCMIN)


def test_gnss_outage_is_recorded_as_no_fix_without_velocity(tmp_path):
    """Epochs in an outage: NavSatFix STATUS_NO_FIX, NaN position, covariance unknown; no
    gnss/vel message (the node's contents, through the recorder's writer)."""
    from dataclasses import replace

    from sins_align_ros.io.sim_messages import write_simulated_bag
    sc = simulated_scenario('static_navigation', duration=10.0)
    sc.gnss = replace(sc.gnss, outages=((3.5, 6.5),))
    counts = write_simulated_bag(tmp_path / 'bag', sc, seed=1, start_ns=START_NS)
    assert counts == {'imu': 1000, 'fix': 10, 'vel': 7, 'truth': 100}
    rec = read_bag(tmp_path / 'bag')
    fixes = {round(e.t - START): e.data for e in rec.events if e.kind == 'fix'}
    vels = {round(e.t - START) for e in rec.events if e.kind == 'vel'}
    for s in range(1, 11):
        status, lat, lon, h, pos_var = fixes[s]
        if 3.5 < s < 6.5:
            assert status == -1 and np.isnan([lat, lon, h]).all() and pos_var is None
            assert s not in vels
        else:
            assert status == 0 and abs(lat - 34.0) < 1e-3 and pos_var == (1.0, 1.0)
            assert s in vels


def test_installed_record_command_answers_help():
    """The console script (setup.py) as installed: needs the package built with colcon."""
    from test_package import resolve_executable
    r = subprocess.run([resolve_executable('sins_align_record'), '--help'], capture_output=True,
                       text=True, env=dict(os.environ), timeout=60.0)
    assert r.returncode == 0 and '--grade' in r.stdout and 'seed003_car' in r.stdout

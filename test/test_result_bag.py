"""The replay's result bag (issue 47 item 2): the node's topics as a rosbag2 in MCAP storage.

Read back with rosbags and checked against the CSV of the same run: types, counts, values,
stamps, the typed status's transitions and the copied input.
"""
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import shared_data
from sins_align_ros.cli.replay import main as replay
from sins_align_ros.io.bag import write_scenario_bag
from sins_align_ros.io.diagnostic_report import MESSAGE_MAX
from sins_align_ros.io.psins import read_psins
from sins_align_ros.io.results import read_csv
from sins_align_ros.sim.presets import scenario

START = 1_700_000_000.0
NODE = '/alignment_node'
TYPES = {'/imu/data': 'sensor_msgs/msg/Imu',
         f'{NODE}/euler': 'geometry_msgs/msg/Vector3Stamped',
         f'{NODE}/odom': 'nav_msgs/msg/Odometry',
         '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
         f'{NODE}/phase': 'std_msgs/msg/String', f'{NODE}/reason': 'std_msgs/msg/String',
         f'{NODE}/tilt_ready': 'std_msgs/msg/Bool',
         f'{NODE}/heading_ready': 'std_msgs/msg/Bool'}
INPUT = {'/imu/data_raw': 'sensor_msgs/msg/Imu', '/gnss/fix': 'sensor_msgs/msg/NavSatFix',
         '/gnss/vel': 'geometry_msgs/msg/TwistWithCovarianceStamped',
         '/sim/truth': 'nav_msgs/msg/Odometry'}
DURATION = 70.0


def read_bag_back(folder):
    """Return ``({topic: [(log time s, message)]}, {topic: connection})`` of a result bag."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    reader = AnyReader([Path(folder)], default_typestore=get_typestore(Stores.ROS2_JAZZY))
    reader.open()
    try:
        msgs = {c.topic: [] for c in reader.connections}
        for conn, t_ns, raw in reader.messages():
            msgs[conn.topic].append((t_ns * 1e-9, reader.deserialize(raw, conn.msgtype)))
        return msgs, {c.topic: c for c in reader.connections}
    finally:
        reader.close()


def stamp(msg):
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


@pytest.fixture(scope='module')
def car_run(tmp_path_factory):
    """A car that stands still, then drives (RTK): ``kf`` with its navigation solution."""
    d = tmp_path_factory.mktemp('result_bag')
    bag = write_scenario_bag(str(d / 'car'), scenario('car_rtk'), seed=3, duration=DURATION,
                             start_time=START)
    args = ['--set', 'fine_filter=kf', '--set', 'continue_navigation=true', '--quiet']
    assert replay([bag, '--out', str(d / 'r.csv'), '--out', str(d / 'r.mcap'),
                   '--copy-input', *args]) == 0
    msgs, conns = read_bag_back(d / 'r')
    return d, read_csv(d / 'r.csv'), msgs, conns


def test_topics_types_and_schemas_are_the_nodes(car_run):
    d, _, msgs, conns = car_run
    assert sorted((d / 'r').iterdir()) == [d / 'r' / 'metadata.yaml', d / 'r' / 'r.mcap']
    assert {t: c.msgtype for t, c in conns.items()} == {**TYPES, **INPUT}
    for conn in conns.values():                 # what Foxglove and PlotJuggler decode
        assert conn.msgdef.format.name == 'MSG' and conn.msgdef.data
    # a ros2msg schema carries the definitions it depends on, as rosbag2 writes them
    assert '\nMSG: std_msgs/Header\n' in conns['/imu/data'].msgdef.data
    assert '\nMSG: diagnostic_msgs/KeyValue\n' in conns['/diagnostics'].msgdef.data
    raw = (d / 'r' / 'r.mcap').read_bytes()
    assert raw[:8] == b'\x89MCAP0\r\n' and raw[-8:] == b'\x89MCAP0\r\n'
    assert raw[9 + 8 + 4:9 + 8 + 4 + 4] == b'ros2'          # the header record's profile
    meta = yaml.safe_load((d / 'r' / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['storage_identifier'] == 'mcap'
    qos = {t['topic_metadata']['name']: t['topic_metadata']['offered_qos_profiles']
           for t in meta['topics_with_message_count']}
    for name in ('phase', 'reason', 'tilt_ready', 'heading_ready'):
        profile = yaml.safe_load(qos[f'{NODE}/{name}'])[0]
        assert profile['durability'] == 1 and profile['depth'] == 1       # transient local


def test_imu_data_and_euler_are_the_csv_rows(car_run):
    _, cols, msgs, _ = car_run
    imu = [m for _, m in msgs['/imu/data']]
    assert len(imu) == len(cols['t']) > 0.99 * DURATION * 100
    t = np.array([stamp(m) for m in imu])
    assert np.abs(t - cols['t']).max() < 1e-6                  # stamps through a float
    assert [lt for lt, _ in msgs['/imu/data']] == pytest.approx(t, abs=1e-6)
    q = np.array([[m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w]
                  for m in imu])
    known = np.isfinite(cols['qw'])
    assert 0 < known.sum() < len(known)
    csv_q = np.stack([cols[k] for k in ('qx', 'qy', 'qz', 'qw')], axis=1)
    # the CSV's 12 decimals: half a unit, and the round-off of the value itself (< 1)
    assert np.abs(q[known] - csv_q[known]).max() <= 0.5e-12 + 4e-16
    cov = np.array([m.orientation_covariance for m in imu])
    assert (cov[~known, 0] == -1.0).all() and (q[~known] == (0, 0, 0, 1)).all()
    P = cov[known].reshape(-1, 3, 3)
    assert np.allclose(P, P.transpose(0, 2, 1)) and (np.diagonal(P, axis1=1, axis2=2) > 0).all()
    euler = msgs[f'{NODE}/euler']
    assert len(euler) == known.sum()
    e = np.degrees([[m.vector.x, m.vector.y, m.vector.z] for _, m in euler])
    csv_e = np.stack([cols[k] for k in ('roll_deg', 'pitch_deg', 'yaw_deg')], axis=1)[known]
    finite = np.isfinite(e)
    assert (finite[:, :2]).all()
    assert np.abs(e[finite] - csv_e[finite]).max() <= 5e-9          # 9 decimals
    assert np.array([stamp(m) for _, m in euler]) == pytest.approx(cols['t'][known], abs=1e-6)


def test_typed_status_follows_the_csv_phases(car_run):
    _, cols, msgs, _ = car_run
    phases = [m.data for _, m in msgs[f'{NODE}/phase']]
    changes = [p for k, p in enumerate(cols['phase']) if k == 0 or p != cols['phase'][k - 1]]
    assert phases == ['waiting'] + changes
    assert phases[-1] == 'aligned'
    reasons = [m.data for _, m in msgs[f'{NODE}/reason']]
    assert reasons[0] == 'waiting for IMU data' and reasons[-1] == ''
    # said when the batch holding the first such row is done: within a diagnostic period
    at = {p: lt for lt, m in msgs[f'{NODE}/phase'] for p in [m.data]}
    assert 'aligned' in at
    for p in set(at) & {'fine', 'aligned'}:     # a reprocessed window may skip 'fine'
        first = cols['t'][np.argmax(cols['phase'] == p)]
        assert first - 1e-6 <= at[p] <= first + 1.0


def test_diagnostics_every_period_with_the_phase_of_their_time(car_run):
    _, cols, msgs, _ = car_run
    diag = msgs['/diagnostics']
    assert abs(len(diag) - DURATION) <= 1                   # one a second of data
    gaps = np.diff([stamp(m) for _, m in diag])
    assert np.abs(gaps - 1.0).max() < 1e-6
    said = []
    for _, m in diag:
        (st,) = m.status
        assert st.name == f'{NODE}: alignment' and st.level in (0, 1, 2)
        assert len(st.message) <= MESSAGE_MAX
        values = {kv.key: kv.value for kv in st.values}
        said.append(values['phase'])
        # the phase when the report was made: the aided filters' rows of the last GNSS
        # interval come with the next fix, so the CSV row of that time may already say
        # the next phase; never one the CSV does not hold within a GNSS interval of it
        near = np.abs(cols['t'] - stamp(m)) <= 0.25
        assert values['phase'] in set(cols['phase'][near])
    assert said[-1] == 'aligned' and said.count('aligned') > 0.3 * len(said)
    counts = {kv.key: kv.value for kv in diag[-1][1].status[0].values}
    assert int(counts['imu_count']) == len(cols['t']) == DURATION * 100 - 1    # first: clock


def test_odometry_rows_are_the_navigation_rows(car_run):
    _, cols, msgs, _ = car_run
    odom = msgs[f'{NODE}/odom']
    nav = np.isfinite(cols['lat_deg']) & np.isfinite(cols['qw'])
    assert len(odom) == nav.sum() > 0
    assert np.array([stamp(m) for _, m in odom]) == pytest.approx(cols['t'][nav], abs=1e-6)
    v = np.array([[m.twist.twist.linear.x, m.twist.twist.linear.y] for _, m in odom])
    speed = np.hypot(cols['ve_mps'][nav], cols['vn_mps'][nav])
    # the body-frame velocity's horizontal part is the ENU speed but for the tilt (< 2 deg)
    assert np.abs(np.hypot(*v.T) - speed).max() < 0.01 * speed.max() + 1e-3
    assert odom[0][1].header.frame_id == 'odom'


def test_copied_input_is_the_input_bag(car_run):
    d, _, msgs, _ = car_run
    inp, _ = read_bag_back(d / 'car')
    for topic in INPUT:
        assert len(msgs[topic]) == len(inp[topic])
    a, b = msgs['/gnss/fix'][5][1], inp['/gnss/fix'][5][1]
    assert (a.latitude, a.longitude, stamp(a)) == (b.latitude, b.longitude, stamp(b))


def test_a_result_bag_is_replaced_and_anything_else_refused(car_run, tmp_path, capsys):
    d = car_run[0]
    bag, out = str(d / 'car'), tmp_path / 'again.mcap'
    for _ in range(2):
        assert replay([bag, '--duration', '5', '--out', str(out), '--quiet']) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ['again']          # no leftovers
    other = tmp_path / 'notes'
    other.mkdir()
    (other / 'keep.txt').write_text('mine')
    assert replay([bag, '--duration', '5', '--out', str(tmp_path / 'notes.mcap'),
                   '--quiet']) == 1
    assert 'not a rosbag2 folder' in capsys.readouterr().err
    assert (other / 'keep.txt').read_text() == 'mine'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['again', 'notes']


@pytest.mark.parametrize('args,needle', [
    (['--out', 'a.mcap', '--out', 'b.mcap'], 'at most one'),
    (['--out', 'a.csv', '--copy-input'], '--copy-input needs a result bag'),
])
def test_misused_outputs_give_one_line_and_exit_2(car_run, tmp_path, capsys, args, needle):
    args = [a if not a.endswith(('.mcap', '.csv')) else str(tmp_path / a) for a in args]
    assert replay([str(car_run[0] / 'car'), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0]


def test_psins_log_into_a_result_bag(tmp_path):
    data = shared_data('psins_lasergyro.imu')
    csv, out = tmp_path / 'p.csv', tmp_path / 'p.mcap'
    assert replay([str(data), '--duration', '120', '--out', str(csv), '--out', str(out),
                   '--quiet']) == 0
    cols = read_csv(csv)
    msgs, conns = read_bag_back(tmp_path / 'p')
    assert len(msgs['/imu/data']) == len(cols['t'])
    assert f'{NODE}/odom' not in conns                   # no navigation filter ran
    assert abs(len(msgs['/diagnostics']) - 120) <= 1
    assert msgs['/imu/data'][0][1].header.frame_id == 'imu'
    rec = read_psins(str(data))
    t = np.array([stamp(m) for _, m in msgs['/imu/data']])
    k = np.searchsorted(rec.t, t - 1e-9)
    assert np.abs(rec.t[k] - t).max() < 1e-6
    w = np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z]
                  for _, m in msgs['/imu/data']])
    f = np.array([[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z]
                  for _, m in msgs['/imu/data']])
    # rates, not increments: each increment over its 10-ms interval (float stamps' round-off)
    dt = 0.01
    assert np.abs(w - rec.dtheta[k] / dt).max() <= 1e-6 * np.abs(rec.dtheta[k] / dt).max()
    assert np.abs(f - rec.dv[k] / dt).max() <= 1e-6 * 9.81
    assert np.linalg.norm(f.mean(axis=0)) == pytest.approx(9.79, abs=0.01)    # gravity

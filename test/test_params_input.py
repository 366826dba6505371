"""Parameters and input names a new user gets wrong (issue 43 items 4 and 6).

Typos in parameter overrides (node: WARN with the closest name, keeps running; replay:
error with the closest name), integers for doubles, missing or malformed params files,
topics not in the bag, the latitude left unset, and the report's truth matched by stamp.
The node cases run on real rclpy nodes with real Context arguments.
"""
import math
import os
import subprocess
import sys
import time
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import ROOT, running
from sins_align_ros.align import params as prm
from sins_align_ros.cli.replay import load_parameters
from sins_align_ros.cli.replay_one import _truth_euler, replay_bag
from sins_align_ros.cli.replay import main as replay
from sins_align_ros.io.bag import write_scenario_bag
from sins_align_ros.io.report import truth_euler_at
from sins_align_ros.io.results import read_csv
from sins_align_ros.nav.frames import euler_error, euler_to_quat, quat_to_euler
from sins_align_ros.sim.presets import alignment_params, scenario
from sins_align_ros.sim.scenario import ScenarioStream
from sins_align_ros.units import ARCMIN, DEG

rclpy = pytest.importorskip('rclpy')

from rcl_interfaces.msg import ParameterType  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from sins_align_ros.ros import params as ros_params  # noqa: E402
from sins_align_ros.ros.alignment_node import AlignmentNode  # noqa: E402

START = 1_700_000_000.0
TYPOS = """/**:
  ros__parameters:
    fine_fliter: ukf
    coarse_duraton: 30.0
"""
INTEGERS = """alignment_node:
  ros__parameters:
    max_gap: 1
    gnss_lever_arm_m: [0, 0, 1]
    initial_latitude_deg: .nan
"""
WRONG_NODE = """alignment_nod:
  ros__parameters:
    coarse_duration: 30.0
"""


def _node(tmp_path, domain_id, text, *extra):
    """An AlignmentNode in a Context started with ``--params-file`` (``text``) and ``extra``."""
    path = tmp_path / 'params.yaml'
    path.write_text(text)
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain_id,
               args=['--ros-args', '--params-file', str(path), *extra])
    return AlignmentNode(context=ctx), ctx, path


# -- the node ------------------------------------------------------------------------------
def test_node_warns_about_unknown_overrides_with_the_closest_name_and_runs(
        tmp_path, domain_id, capfd):
    node, ctx, _ = _node(tmp_path, domain_id, TYPOS)
    try:
        err = capfd.readouterr().err
        assert "unknown parameter 'fine_fliter' ignored (did you mean 'fine_filter'?)" in err
        assert "unknown parameter 'coarse_duraton' ignored (did you mean 'coarse_duration'?)" \
            in err
        assert '[WARN]' in err
        # the node runs with the defaults for what the typos meant
        assert node.pipeline.cfg['fine_filter'] == 'auto'
        assert node.pipeline.cfg['coarse_duration'] == 60.0
        assert node.pipeline.phase == 'waiting'
    finally:
        node.destroy_node()
        ctx.try_shutdown()


def test_node_takes_integers_for_doubles_at_start_and_at_runtime(tmp_path, domain_id):
    node, ctx, _ = _node(tmp_path, domain_id, INTEGERS, '-p', 'coarse_duration:=60')
    try:
        for name, value in (('coarse_duration', 60.0), ('max_gap', 1.0)):
            p = node.get_parameter(name)
            assert p.type_ == Parameter.Type.DOUBLE and p.value == value
            assert type(node.pipeline.cfg[name]) is float and node.pipeline.cfg[name] == value
        arm = node.get_parameter('gnss_lever_arm_m')
        assert arm.type_ == Parameter.Type.DOUBLE_ARRAY and list(arm.value) == [0.0, 0.0, 1.0]
        assert math.isnan(node.get_parameter('initial_latitude_deg').value)
        # the descriptor keeps its type and range
        d = node.describe_parameters(['coarse_duration'])[0]
        assert d.type == ParameterType.PARAMETER_DOUBLE
        assert (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value) \
            == (1.0, 3600.0)
        # runtime: an integer is the double; the range still holds
        res = node.set_parameters([Parameter('coarse_duration', value=45)])[0]
        assert res.successful, res.reason
        assert node.get_parameter('coarse_duration').value == 45.0
        assert node.pipeline.cfg['coarse_duration'] == 45.0
        res = node.set_parameters([Parameter('coarse_duration', value=0)])[0]
        assert not res.successful and 'coarse_duration' in res.reason
        # the latitude: set, refused outside its range, unset again with NaN
        res = node.set_parameters([Parameter('initial_latitude_deg', value=34)])[0]
        assert res.successful and node.pipeline.cfg['initial_latitude_deg'] == 34.0
        res = node.set_parameters([Parameter('initial_latitude_deg', value=95.0)])[0]
        assert not res.successful and 'outside [-89.0, 89.0]' in res.reason
        res = node.set_parameters([Parameter('initial_latitude_deg', value=math.nan)])[0]
        assert res.successful and math.isnan(node.pipeline.cfg['initial_latitude_deg'])
        d = node.describe_parameters(['initial_latitude_deg'])[0]
        assert d.type == ParameterType.PARAMETER_DOUBLE
        assert d.additional_constraints == 'from -89.0 to 89.0, or .nan: not set'
    finally:
        node.destroy_node()
        ctx.try_shutdown()


def test_params_file_without_an_entry_for_the_node_is_named(tmp_path, domain_id):
    node, ctx, path = _node(tmp_path, domain_id, WRONG_NODE)
    try:
        argv = ['alignment_node', '--ros-args', '--params-file', str(path)]
        (text,) = ros_params.unmatched_params_files(node, argv)
        assert str(path) in text and 'alignment_nod' in text and '/alignment_node' in text
        # the layouts rcl applies to /alignment_node are not warned about
        for key in ('/**', 'alignment_node', '/alignment_node', '/**/alignment_node', '/*'):
            path.write_text(f'{key}:\n  ros__parameters:\n    coarse_duration: 30.0\n')
            assert ros_params.unmatched_params_files(node, argv) == [], key
        path.write_text('/ship/alignment_node:\n  ros__parameters:\n    max_gap: 1.0\n')
        assert len(ros_params.unmatched_params_files(node, argv)) == 1
    finally:
        node.destroy_node()
        ctx.try_shutdown()


def test_alignment_node_executable_warns_and_takes_an_integer(tmp_path, domain_id):
    """`alignment_node --ros-args --params-file` with typos and a wrong node name, and
    ``-p coarse_duration:=60``: two WARNs naming what is wrong, runs, exit 0 on Ctrl-C."""
    from test_package import resolve_executable
    typos, wrong = tmp_path / 'typos.yaml', tmp_path / 'wrong.yaml'
    typos.write_text(TYPOS)
    wrong.write_text(WRONG_NODE)
    with running([resolve_executable('alignment_node'), '--ros-args',
                  '--params-file', str(typos), '--params-file', str(wrong),
                  '-p', 'coarse_duration:=60'], domain_id, source_tree=True) as proc:
        time.sleep(8.0)
        assert proc.poll() is None
    code, out, err = proc.returncode, proc.out, proc.err
    assert code == 0, err
    assert "(did you mean 'fine_filter'?)" in err, err
    assert f'params file {wrong}: no entry for this node /alignment_node' in err, err
    assert 'coarse auto 60 s' in err + out
    assert 'Traceback' not in err


@pytest.mark.parametrize('text, cause', [
    (None, 'cannot open it (no such file, or not readable)'),
    ('alignment_node:\n  ros__parameters:\n    coarse_duration: [\n', 'Error parsing'),
])
def test_missing_or_malformed_params_file_is_one_line(tmp_path, domain_id, text, cause):
    """rcl refuses the file in rclpy.init (RCLError with source locations): one line."""
    path = tmp_path / 'p.yaml'
    if text is not None:
        path.write_text(text)
    ctx = rclpy.Context()
    with pytest.raises(Exception) as info:
        rclpy.init(context=ctx, domain_id=domain_id,
                   args=['--ros-args', '--params-file', str(path)])
    line = ros_params.startup_error(info.value)
    assert line.startswith(f'params file {path}: {cause}'), line
    assert '\n' not in line and '.c:' not in line


# -- the replay tool -----------------------------------------------------------------------
@pytest.fixture(scope='module')
def short_bag(tmp_path_factory):
    """20 s of a still navigation-grade IMU with GNSS (imu/data_raw, gnss/fix, gnss/vel)."""
    path = tmp_path_factory.mktemp('bag') / 'still'
    return str(write_scenario_bag(path, scenario('static_navigation'), seed=1, duration=20.0,
                                  start_time=START))


def test_replay_refuses_unknown_names_with_the_closest_and_takes_integers(
        tmp_path, short_bag, capsys):
    params = tmp_path / 'typos.yaml'
    params.write_text(TYPOS)
    out = str(tmp_path / 'o.csv')
    assert replay([short_bag, '--params', str(params), '--out', out]) == 2
    assert ("error: unknown parameter 'fine_fliter' (did you mean 'fine_filter'?)"
            in capsys.readouterr().err)
    assert replay([short_bag, '--set', 'coarse_duraton=30', '--out', out]) == 2
    assert "(did you mean 'coarse_duration'?)" in capsys.readouterr().err
    values = load_parameters(None, ['coarse_duration=30', 'max_gap=1',
                                    'gnss_lever_arm_m=[0, 0, 1]'])
    assert values == {'coarse_duration': 30.0, 'max_gap': 1.0,
                      'gnss_lever_arm_m': (0.0, 0.0, 1.0)}
    assert type(values['coarse_duration']) is float
    params.write_text(INTEGERS)
    values = load_parameters(str(params), [])
    assert values['max_gap'] == 1.0 and math.isnan(values['initial_latitude_deg'])
    assert math.isnan(load_parameters(None, ['initial_latitude_deg=.nan'])
                      ['initial_latitude_deg'])


@pytest.mark.parametrize('text, says', [
    (None, 'cannot open it (No such file or directory)'),
    ('a: [\n', "not valid YAML at line 2: expected the node content, but found '<stream end>'"),
    (WRONG_NODE, 'no parameters for alignment_node (its node names: alignment_nod; use '
                 'alignment_node or /**)'),
])
def test_replay_params_file_errors_are_one_line(tmp_path, short_bag, text, says):
    params = tmp_path / 'p.yaml'
    if text is not None:
        params.write_text(text)
    proc = subprocess.run([sys.executable, '-m', 'sins_align_ros.cli.replay', short_bag,
                           '--params', str(params), '--out', str(tmp_path / 'o.csv')],
                          capture_output=True, text=True, timeout=120, cwd=ROOT,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 2
    assert proc.stderr.splitlines() == [
        f'sins_align_replay: error: params file {params}: {says}'], proc.stderr


@pytest.mark.parametrize('option, topic', [('--fix-topic', 'gnss/fixx'),
                                           ('--vel-topic', 'gnss/veel'),
                                           ('--imu-topic', 'imu/data_rwa')])
def test_replay_topic_not_in_the_bag_is_an_error_listing_its_topics(
        tmp_path, short_bag, capsys, option, topic):
    assert replay([short_bag, option, topic, '--out', str(tmp_path / 'o.csv')]) == 1
    err = capsys.readouterr().err
    assert f"error: no topic '{topic}' in the bag (did you mean '/{topic[:-2]}" in err, err
    assert 'its topics: /gnss/fix, /gnss/vel, /imu/data_raw, /sim/truth' in err
    # the same topics spelt right (or the defaults) run
    good = {'--fix-topic': 'gnss/fix', '--vel-topic': 'gnss/vel', '--imu-topic': 'imu/data_raw'}
    assert replay([short_bag, option, good[option], '--set', 'coarse_duration=5',
                   '--out', str(tmp_path / 'o.csv'), '--quiet']) == 0


def test_replay_default_gnss_topics_may_be_absent(tmp_path):
    sc = scenario('static_navigation', gnss=None)
    bag = write_scenario_bag(tmp_path / 'bag', sc, seed=1, duration=10.0, start_time=START)
    assert replay([str(bag), '--set', 'coarse_duration=5', '--set', 'initial_latitude_deg=34',
                   '--out', str(tmp_path / 'o.csv'), '--quiet']) == 0
    assert replay([str(bag), '--fix-topic', 'gps/fix', '--out', str(tmp_path / 'o.csv'),
                   '--quiet']) == 1


# -- the latitude not set --------------------------------------------------------------------
def _no_gnss_replay(tmp_path, name, values, duration=300.0):
    sc = scenario(name, gnss=None)
    bag = write_scenario_bag(tmp_path / name, sc, seed=2, duration=duration, start_time=START)
    args = SimpleNamespace(imu_topic='imu/data_raw', fix_topic=None, vel_topic=None,
                           duration=None)
    out, pipe, _ = replay_bag(str(bag), prm.validate(values), args, lambda m: None,
                              with_truth=False)
    return sc, out, pipe


def test_still_navigation_imu_without_gnss_or_latitude_estimates_it(tmp_path):
    """34 N, no GNSS, latitude not set: estimated from the gyros within its sigma; the
    heading is found and honest; nothing blames the gyro."""
    sc, out, pipe = _no_gnss_replay(tmp_path, 'static_navigation', {})
    assert pipe.position_source == 'gyro_latitude'      # the estimate is used
    lat, sigma = pipe.check.latitude
    assert abs(lat - 34.0 * DEG) < sigma, (lat / DEG, sigma / DEG)
    assert sigma < 0.1 * DEG
    assert pipe.position[0] == lat                     # the fine filter uses it
    text = ' '.join(pipe.warnings)
    assert f'{lat / DEG:.2f} +- {sigma / DEG:.2f} deg (1 sigma) estimated' in text
    assert 'gyro bias of at least' not in text and 'accelerometer bias' not in text
    assert 'unobservable' not in text
    truth_yaw = (90.0 - sc.trajectory.heading_deg) * DEG
    err = abs(euler_error(out.euler[-1, 2], truth_yaw))
    assert out.phase[-1] == 'aligned'
    assert err < 3.0 * out.sigma[-1, 2] and out.sigma[-1, 2] < 5.0 * ARCMIN


def test_still_mems_imu_without_latitude_says_the_latitude_is_unknown(tmp_path):
    """A MEMS IMU told its grade but not the latitude: the latitude is said to be unknown,
    the heading unknown for that reason; no gyro-bias finding from the missing latitude."""
    sc = scenario('static_mems')
    values = alignment_params(sc, 'auto')
    del values['initial_latitude_deg']
    _, out, pipe = _no_gnss_replay(tmp_path, 'static_mems', values, duration=120.0)
    text = ' | '.join(pipe.warnings)
    assert 'latitude unknown: initial_latitude_deg is not set and no GNSS fix came' in text
    assert 'heading unobservable: the latitude is unknown' in text
    assert 'Earth rate by' not in text and 'gyro bias of at least' not in text
    assert pipe.check.latitude is None and pipe.check.latitude_unknown
    assert not pipe.check.heading_observable
    assert out.sigma[-1, 2] > 30.0 * DEG                    # published as unknown
    # the same IMU with the latitude told: no latitude finding
    values['initial_latitude_deg'] = 34.0
    _, _, told = _no_gnss_replay(tmp_path / 'told', 'static_mems', values, duration=120.0)
    assert not any('latitude' in w for w in told.warnings)


# -- the report's truth ----------------------------------------------------------------------
def test_truth_interpolation_follows_a_known_rotation():
    """Slow yaw-roll motion sampled at 10 Hz: the spline at 100 Hz stamps matches it."""
    t = np.arange(0.0, 20.0, 0.1)
    e = np.column_stack([4 * DEG * np.sin(2 * np.pi * t / 5), 0.5 * DEG * np.cos(t),
                         np.mod(0.3 * t + 3.0, 2 * np.pi) - np.pi])   # yaw wraps
    q = euler_to_quat(e)
    q[::3] *= -1.0                                         # either sign of a quaternion
    ts = np.arange(-0.05, 20.0, 0.01)
    got = truth_euler_at(ts, t, q)
    inside = (ts >= t[0]) & (ts <= t[-1])
    assert np.all(np.isnan(got[~inside])) and np.all(np.isfinite(got[inside]))
    want = np.column_stack([4 * DEG * np.sin(2 * np.pi * ts / 5), 0.5 * DEG * np.cos(ts),
                            np.mod(0.3 * ts + 3.0, 2 * np.pi) - np.pi])
    err = np.abs(euler_error(got[inside], want[inside]))
    mid = (ts[inside] > 0.5) & (ts[inside] < t[-1] - 0.5)
    assert np.max(err[mid]) < 0.05 * ARCMIN
    # a gap of more than 5 truth intervals is not bridged
    gap = (t < 8.0) | (t > 9.0)
    got = truth_euler_at(ts, t[gap], q[gap])
    assert np.all(np.isnan(got[(ts > 7.95) & (ts < 9.05)]))


def test_report_matches_truth_by_stamp_on_the_swaying_ship(tmp_path):
    """ship_sway: 100 Hz rows, 10 Hz truth. The last-sample truth swings by degrees of
    motion; the stamp-matched one follows the simulator's own attitude."""
    sc = scenario('ship_sway', duration=150.0)
    bag = write_scenario_bag(tmp_path / 'bag', sc, seed=0, start_time=START)
    args = SimpleNamespace(imu_topic='imu/data_raw', fix_topic=None, vel_topic=None,
                           duration=None)
    values = prm.validate({**alignment_params(sc, 'auto'), 'coarse_duration': 60.0})
    out, pipe, truth = replay_bag(str(bag), values, args, lambda m: None)
    stamped = _truth_euler(out, truth)
    tt = np.array([t for t, _ in truth])
    last = quat_to_euler(np.array([q for _, q in truth])[
        np.clip(np.searchsorted(tt, out.t + 1e-9) - 1, 0, len(tt) - 1)])
    st = ScenarioStream(sc, seed=0)
    block = st.next_block(int(round(sc.duration / st.dt)))
    exact = block.imu.euler[np.round((out.t - START) / st.dt).astype(int) - 1]
    fine = np.isin(out.phase, ('fine', 'aligned')) & np.isfinite(stamped[:, 0])
    fine &= out.t < tt[-1] - 0.1                  # the spline's last interval aside
    assert np.max(np.abs(euler_error(stamped[fine], exact[fine]))) < 0.05 * ARCMIN
    e_new = np.abs(euler_error(out.euler[fine], stamped[fine])) / ARCMIN
    e_old = np.abs(euler_error(out.euler[fine], last[fine])) / ARCMIN
    assert np.max(e_old[:, 0]) > 4.0                           # the old plot's roll swing
    assert np.max(e_new[:, :2]) < 0.5, np.max(e_new, axis=0)   # arcmin level
    assert np.all(e_new[:, 2] < 3.0 * out.sigma[fine, 2] / ARCMIN)
    png = tmp_path / 'r.png'
    assert replay([str(bag), '--set', 'coarse_duration=60', '--out', str(tmp_path / 'o.csv'),
                   '--report', str(png), '--quiet']) == 0
    assert png.stat().st_size > 10_000
    assert len(read_csv(tmp_path / 'o.csv')['t']) == len(out.t)

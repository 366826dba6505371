"""``imu_noise_file``: the noise files users already have (issue 47 item 1).

Each convention (Kalibr, OpenVINS, VINS-Fusion) converted on known values, the
expected figures worked out here from the unit definitions (not from the module's
constants); bad files refused with one line; values given as parameters kept; a replay
with the file identical to one with the same numbers as parameters; the self-check still
widening a file the data contradict; the node setting its declared parameters from the
file and saying so on /diagnostics (real rclpy nodes and executor).
"""
import math

import pytest

from conftest import spin_until
from sins_align_ros.align import params as prm
from sins_align_ros.cli.replay import load_parameters
from sins_align_ros.cli.replay import main as replay
from sins_align_ros.io import imu_noise_file as inf
from sins_align_ros.io.bag import write_scenario_bag
from sins_align_ros.io.results import read_csv
from sins_align_ros.sim.presets import scenario

#: an IMU's noise in SI units (a MEMS unit of the Kalibr examples' order)
GYRO_WHITE, GYRO_WALK, ACCEL_WHITE, ACCEL_WALK, RATE = 1.0e-3, 1.0e-5, 1.0e-2, 1.0e-4, 200.0

KALIBR = f"""# allan_variance_ros output
rostopic: /imu/data_raw
update_rate: {RATE}
accelerometer_noise_density: {ACCEL_WHITE}
accelerometer_random_walk: {ACCEL_WALK}
gyroscope_noise_density: {GYRO_WHITE}
gyroscope_random_walk: {GYRO_WALK}
"""
OPENVINS = f"""%YAML:1.0
imu0:
  T_i_b:
    - [1.0, 0.0, 0.0, 0.0]
    - [0.0, 1.0, 0.0, 0.0]
    - [0.0, 0.0, 1.0, 0.0]
    - [0.0, 0.0, 0.0, 1.0]
  accelerometer_noise_density: {ACCEL_WHITE}
  accelerometer_random_walk: {ACCEL_WALK}
  gyroscope_noise_density: {GYRO_WHITE}
  gyroscope_random_walk: {GYRO_WALK}
  model: kalibr
  rostopic: /imu0
  time_offset: 0.0
  update_rate: {RATE}
"""
VINS = f"""%YAML:1.0
imu: 1
imu_topic: "/imu0"
extrinsicRotation: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [0, -1, 0, 1, 0, 0, 0, 0, 1]
acc_n: {ACCEL_WHITE}
gyr_n: {GYRO_WHITE}
acc_w: {ACCEL_WALK}
gyr_w: {GYRO_WALK}
g_norm: 9.81007
"""


def expected(tau_g=300.0, tau_a=3600.0, turn_on_ug=100.0):
    """The model values from first principles: deg = pi/180 rad, h = 3600 s, g = 9.80665."""
    deg_per_rad = 180.0 / math.pi
    walk_a_ug = ACCEL_WALK * math.sqrt(tau_a / 2.0) / 9.80665e-6
    return {
        # rad/s/sqrt(Hz) = rad/sqrt(s) = deg/sqrt(s) * pi/180 = deg/sqrt(h) * pi/180 / 60
        'gyro_arw_dpsh': GYRO_WHITE * deg_per_rad * 60.0,
        # a Gauss-Markov with the walk's driving noise: sigma = w sqrt(tau / 2), in deg/h
        'gyro_bias_instability_dph': GYRO_WALK * math.sqrt(tau_g / 2.0) * deg_per_rad * 3600.0,
        'accel_vrw_ug_rthz': ACCEL_WHITE / 9.80665e-6,
        'accel_bias_ug': math.sqrt(turn_on_ug ** 2 + walk_a_ug ** 2),
    }


@pytest.mark.parametrize('text, convention', [(KALIBR, 'kalibr'), (OPENVINS, 'openvins'),
                                              (VINS, 'vins')])
def test_each_convention_converts_to_the_model_units(tmp_path, text, convention):
    path = tmp_path / 'imu.yaml'
    path.write_text(text)
    noise = inf.read(path)
    assert noise.convention == convention
    assert noise.rate_hz == (None if convention == 'vins' else RATE)
    values, said = inf.apply({'imu_noise_file': str(path)}, set(), prm.defaults())
    want = expected()
    for k, v in want.items():
        assert values[k] == pytest.approx(v, rel=1e-12), k
    # the figures themselves, as a reader checks them by hand
    assert want['gyro_arw_dpsh'] == pytest.approx(3.43775, rel=1e-5)
    assert want['gyro_bias_instability_dph'] == pytest.approx(25.2622, rel=1e-5)
    assert want['accel_vrw_ug_rthz'] == pytest.approx(1019.72, rel=1e-5)
    assert want['accel_bias_ug'] == pytest.approx(444.036, rel=1e-5)
    assert said.startswith(f'imu_noise_file {path} ({convention}')
    assert 'gyro_arw_dpsh 3.438' in said and 'kept' not in said


def test_given_values_are_kept_and_the_correlation_times_are_used(tmp_path):
    path = tmp_path / 'imu.yaml'
    path.write_text(KALIBR)
    values = {'imu_noise_file': str(path), 'gyro_arw_dpsh': 0.5, 'gyro_bias_tau_s': 100.0,
              'accel_bias_tau_s': 200.0, 'accel_bias_ug': 2000.0}
    out, said = inf.apply(values, {'gyro_arw_dpsh', 'accel_bias_ug', 'gyro_bias_tau_s',
                                   'accel_bias_tau_s'}, prm.defaults())
    want = expected(tau_g=100.0, tau_a=200.0, turn_on_ug=2000.0)
    assert out['gyro_arw_dpsh'] == 0.5 and out['accel_bias_ug'] == 2000.0
    assert out['gyro_bias_instability_dph'] == pytest.approx(want['gyro_bias_instability_dph'])
    assert out['accel_vrw_ug_rthz'] == pytest.approx(want['accel_vrw_ug_rthz'])
    assert said.endswith('given as parameters, kept: gyro_arw_dpsh, accel_bias_ug')
    # no file: nothing changes, nothing said
    assert inf.apply({'gyro_arw_dpsh': 0.5}, set(), prm.defaults()) == ({'gyro_arw_dpsh': 0.5},
                                                                        '')


@pytest.mark.parametrize('text, says', [
    (None, 'cannot open it (No such file or directory)'),
    ('a: [\n', 'not valid YAML at line 2'),
    ('- 1\n- 2\n', 'not a YAML mapping of IMU noise keys'),
    ('foo: 1\nbar: 2\n', 'no IMU noise keys (Kalibr gyroscope_noise_density..., OpenVINS '
                         'imu0: {...}, or VINS-Fusion gyr_n/gyr_w/acc_n/acc_w); its keys: '
                         'bar, foo'),
    (KALIBR.replace('gyroscope_random_walk', 'gyro_random_walk'),
     '(kalibr): missing gyroscope_random_walk'),
    (KALIBR.replace(f'gyroscope_noise_density: {GYRO_WHITE}', 'gyroscope_noise_density: 0.2'),
     'gyroscope_noise_density = 0.2 rad/s/sqrt(Hz) is outside [1e-07, 0.1]: almost certainly '
     'a unit mistake'),
    (KALIBR.replace(f'gyroscope_noise_density: {GYRO_WHITE}', 'gyroscope_noise_density: 1e-9'),
     'gyroscope_noise_density = 1e-09 rad/s/sqrt(Hz) is outside'),
    (KALIBR.replace(f'accelerometer_noise_density: {ACCEL_WHITE}',
                    'accelerometer_noise_density: high'),
     "accelerometer_noise_density = 'high' is not a number"),
    (KALIBR.replace(f'update_rate: {RATE}', 'update_rate: -5'), 'update_rate = -5 is not a rate'),
    (VINS.replace(f'gyr_w: {GYRO_WALK}', 'gyr_w: .nan'), "gyr_w = nan is not a number"),
    ('imu1:\n  gyroscope_noise_density: 1e-3\nimu2:\n  gyroscope_noise_density: 1e-3\n',
     'several IMUs (imu1, imu2) and no imu0'),
])
def test_bad_files_are_refused_with_one_line(tmp_path, text, says):
    path = tmp_path / 'imu.yaml'
    if text is not None:
        path.write_text(text)
    with pytest.raises(ValueError) as info:
        inf.read(path)
    line = str(info.value)
    assert line.startswith(f'imu_noise_file {path}') and says in line, line
    assert '\n' not in line


# -- the replay tool -----------------------------------------------------------------------
@pytest.fixture(scope='module')
def tactical_bag(tmp_path_factory):
    """60 s of a still tactical-grade IMU at 34 N with GNSS."""
    path = tmp_path_factory.mktemp('bag') / 'tactical'
    return str(write_scenario_bag(path, scenario('static_tactical'), seed=3, duration=60.0,
                                  start_time=1_700_000_000.0))


def test_replay_with_the_file_equals_the_same_numbers_as_parameters(tmp_path, tactical_bag):
    path = tmp_path / 'imu.yaml'
    path.write_text(KALIBR)
    logged = []
    from_file = load_parameters(None, [f'imu_noise_file={path}', 'coarse_duration=20'],
                                logged.append)
    want = {k: from_file[k] for k in expected()}
    assert want == pytest.approx(expected(), rel=1e-12)
    by_hand = load_parameters(None, ['coarse_duration=20'] + [
        f'{k}={v!r}' for k, v in want.items()])
    assert from_file == dict(by_hand, imu_noise_file=str(path))
    assert any(m.startswith(f'imu_noise_file {path} (kalibr, update_rate 200 Hz)')
               for m in logged)
    a, b = tmp_path / 'file.csv', tmp_path / 'hand.csv'
    assert replay([tactical_bag, '--set', f'imu_noise_file={path}', '--set',
                   'coarse_duration=20', '--out', str(a), '--quiet']) == 0
    assert replay([tactical_bag, '--set', 'coarse_duration=20', '--out', str(b), '--quiet']
                  + [x for k, v in want.items() for x in ('--set', f'{k}={v!r}')]) == 0
    assert a.read_bytes() == b.read_bytes()
    # the file changed the result: the default model gives other sigmas
    c = tmp_path / 'defaults.csv'
    assert replay([tactical_bag, '--set', 'coarse_duration=20', '--out', str(c),
                   '--quiet']) == 0
    assert a.read_bytes() != c.read_bytes()
    assert len(read_csv(str(a))['t']) == len(read_csv(str(c))['t'])


def test_the_self_check_still_widens_a_file_the_data_contradict(tmp_path, tactical_bag,
                                                                capsys):
    """A file claiming a navigation-grade gyro on a tactical IMU (ARW 0.05 deg/sqrt(h))."""
    path = tmp_path / 'imu.yaml'
    path.write_text(KALIBR.replace(f'gyroscope_noise_density: {GYRO_WHITE}',
                                   'gyroscope_noise_density: 2.9e-7'))
    assert replay([tactical_bag, '--set', f'imu_noise_file={path}', '--set',
                   'coarse_duration=20', '--out', str(tmp_path / 'o.csv')]) == 0
    err = capsys.readouterr().err
    assert 'gyro_arw_dpsh 0.0009969' in err, err
    assert 'gyro_arw_dpsh widened' in err, err


def test_replay_refuses_a_bad_file_with_one_line(tmp_path, tactical_bag, capsys):
    path = tmp_path / 'imu.yaml'
    path.write_text(VINS.replace('gyr_n', 'gyro_n'))
    assert replay([tactical_bag, '--set', f'imu_noise_file={path}', '--out',
                   str(tmp_path / 'o.csv')]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f'sins_align_replay: error: imu_noise_file {path} (vins): missing gyr_n']


# -- the node ------------------------------------------------------------------------------
rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from sins_align_ros.ros.alignment_node import AlignmentNode  # noqa: E402


def test_node_sets_its_parameters_from_the_file_and_says_so(tmp_path, ros_context, capfd):
    path = tmp_path / 'imu.yaml'
    path.write_text(OPENVINS)
    node = AlignmentNode(context=ros_context, parameter_overrides=[
        Parameter('imu_noise_file', value=str(path)), Parameter('gyro_arw_dpsh', value=0.5),
        Parameter('diagnostic_period', value=0.2)])
    probe = rclpy.create_node('probe', context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    try:
        want = dict(expected(), gyro_arw_dpsh=0.5)
        for k, v in want.items():
            assert node.get_parameter(k).value == pytest.approx(v, rel=1e-12), k
            assert node.pipeline.cfg[k] == pytest.approx(v, rel=1e-12), k
        err = capfd.readouterr().err
        assert f'imu_noise_file {path} (openvins, update_rate 200 Hz)' in err, err
        assert 'given as parameters, kept: gyro_arw_dpsh' in err
        diags = []
        probe.create_subscription(DiagnosticArray, '/diagnostics',
                                  lambda m: diags.append(m.status[0]), 10)
        ex.add_node(node)
        ex.add_node(probe)
        assert spin_until(ex, lambda: diags, timeout_s=10.0)
        kv = {v.key: v.value for v in diags[-1].values}
        assert kv['imu_noise_file'].startswith(f'imu_noise_file {path} (openvins')
        # read at start-up only
        res = node.set_parameters([Parameter('imu_noise_file', value='')])[0]
        assert not res.successful
    finally:
        ex.shutdown()
        probe.destroy_node()
        node.destroy_node()


def test_node_refuses_a_bad_file_at_start_with_one_line(tmp_path, ros_context):
    path = tmp_path / 'imu.yaml'
    path.write_text(KALIBR.replace(f'gyroscope_noise_density: {GYRO_WHITE}',
                                   'gyroscope_noise_density: 0.5'))
    with pytest.raises(ValueError) as info:
        AlignmentNode(context=ros_context, parameter_overrides=[
            Parameter('imu_noise_file', value=str(path))])
    assert str(info.value).startswith(f'imu_noise_file {path}: gyroscope_noise_density = 0.5')


def test_managed_node_refuses_configure_with_the_files_line(tmp_path, ros_context):
    from rclpy.lifecycle import TransitionCallbackReturn
    from sins_align_ros.ros.alignment_lifecycle_node import AlignmentLifecycleNode
    path = tmp_path / 'imu.yaml'
    path.write_text('foo: 1\n')
    node = AlignmentLifecycleNode(context=ros_context, parameter_overrides=[
        Parameter('imu_noise_file', value=str(path))])
    try:
        assert node.params.refused().startswith(f'imu_noise_file {path}: no IMU noise keys')
        assert node.trigger_configure() == TransitionCallbackReturn.FAILURE
        assert node.session is None
    finally:
        node.destroy_node()

"""The golden replay cases: one table shared by ``test_golden.py`` and ``regenerate.py``.

Each case is a short, seeded, deterministic run of the alignment pipeline whose result
CSV is kept in this folder as ``<name>.csv`` (recorded from commit 3010b60). Simulated
cases write a preset scenario to a rosbag2 (``write_scenario_bag``, fixed seed and start
stamp) and run the replay CLI on it; the PSINS recording goes through the replay CLI
too, the fog_mems car recording through ``AlignmentPipeline`` + ``feed_arrays`` +
``write_csv``. Every fine filter has one case; parameters are written out here (not
taken from ``alignment_params`` or bench/) so that only the pipeline, filters,
simulation and I/O code decide the numbers.

``run_case(case, workdir, data)`` writes ``workdir/<name>.csv`` and returns its path;
``data(filename)`` gives the path of a recording in ../shared/data. Bags are cached in
``workdir`` by (scenario, seed, duration), so cases sharing a bag simulate it once.
"""
import os

# Small-matrix numerics: a multi-threaded BLAS only spins (see sins_align_ros/ros/__init__.py).
# Effective only when numpy is not imported yet (regenerate.py, a lone test file).
for _var in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_var, '1')

from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

GOLDEN_DIR = Path(__file__).resolve().parent
#: stamp of the first simulated sample (s since the epoch), as test_replay.py uses
START = 1_700_000_000.0

# Sensor and GNSS parameters of the presets (what sim.presets.alignment_params gave at
# commit 3010b60), copied so that a change there does not move the goldens.
STATIC_TACTICAL = {'initial_latitude_deg': 34.0, 'initial_longitude_deg': 108.0,
                   'initial_height_m': 50.0, 'gyro_bias_dph': 1.0, 'gyro_arw_dpsh': 0.05,
                   'gyro_bias_instability_dph': 0.5, 'gyro_bias_tau_s': 300.0,
                   'accel_bias_ug': 300.0, 'accel_vrw_ug_rthz': 50.0,
                   'gnss_pos_sigma_m': 1.0, 'gnss_vel_sigma_mps': 0.05,
                   'gnss_height_sigma_m': 2.0}
SHIP = {'initial_latitude_deg': 45.7796, 'initial_longitude_deg': 126.6705,
        'initial_height_m': 0.0, 'gyro_bias_dph': 0.003, 'gyro_arw_dpsh': 0.0005,
        'gyro_bias_instability_dph': 0.0, 'gyro_bias_tau_s': 3600.0, 'accel_bias_ug': 30.0,
        'accel_vrw_ug_rthz': 5.0, 'gnss_pos_sigma_m': 0.2, 'gnss_vel_sigma_mps': 0.05,
        'gnss_height_sigma_m': 0.4}
USV_HIGH = {'initial_latitude_deg': 22.0, 'initial_longitude_deg': 113.5,
            'initial_height_m': 0.0, 'gyro_bias_dph': 0.02, 'gyro_arw_dpsh': 0.002,
            'gyro_bias_instability_dph': 0.0, 'gyro_bias_tau_s': 3600.0,
            'accel_bias_ug': 50.0, 'accel_vrw_ug_rthz': 10.0, 'gnss_pos_sigma_m': 1.0,
            'gnss_vel_sigma_mps': 0.05, 'gnss_height_sigma_m': 2.0}
FLIGHT = {'initial_latitude_deg': 34.0, 'initial_longitude_deg': 108.0,
          'initial_height_m': 3000.0, 'gyro_bias_dph': 1.0, 'gyro_arw_dpsh': 0.05,
          'gyro_bias_instability_dph': 0.5, 'gyro_bias_tau_s': 300.0, 'accel_bias_ug': 300.0,
          'accel_vrw_ug_rthz': 50.0, 'gnss_pos_sigma_m': 5.0, 'gnss_vel_sigma_mps': 0.1,
          'gnss_height_sigma_m': 8.0}
CAR = {'initial_latitude_deg': 30.5, 'initial_longitude_deg': 114.3, 'initial_height_m': 30.0,
       'gyro_bias_dph': 200.0, 'gyro_arw_dpsh': 3.0, 'gyro_bias_instability_dph': 50.0,
       'gyro_bias_tau_s': 300.0, 'accel_bias_ug': 5000.0, 'accel_vrw_ug_rthz': 350.0,
       'gnss_pos_sigma_m': 10.0, 'gnss_vel_sigma_mps': 0.1, 'gnss_height_sigma_m': 5.0}
#: bench/moving_base.py fog_params at commit 3010b60 (without fine_filter)
FOG = {'gyro_bias_dph': 200.0, 'gyro_arw_dpsh': 1.0, 'accel_bias_ug': 2000.0,
       'accel_vrw_ug_rthz': 200.0, 'coarse_duration': 10.0, 'gnss_pos_sigma_m': 0.5,
       'gnss_vel_sigma_mps': 0.05}
#: the MEMS car cases ended in fine while the gyro scale-factor model took twice the told
#: sigma for the heading too (align/engines/rotation_error.py): it held the heading sigma at
#: 2.8 deg after the turn at 100 s. At the told sigma (HEADING_COHERENCE_FACTOR 1) MVBAKF is
#: aligned from 105 s, 1.4 deg off under a 1.9 deg sigma at the end (simulator truth); the
#: UKF's heading sigma stayed above the aligned bound in the bag's 120 s until the coarse
#: window ended 5 s after the car starts to drive (issue 46, ``coarse_motion_s``). Since the
#: aided stage runs over the window (``coarse_reprocess_aided``, session 47) both are
#: aligned at the window's end and left it as the heading sigma grew on the straight leg
#: (3.8 deg at most). Since the vertical drift is measured in the 30-s rest
#: (``zero_rate_at_rest``, session 50) that sigma stays under 1.8 deg and both stay aligned
#: (end: UKF 0.29 deg off under 1.65, MVBAKF 0.42 under 1.64, simulator truth)
MEMS_CAR_PHASES_ALIGNED = ('coarse', 'aligned')
#: short stages so that a 100-160 s still run reaches ``aligned``; a tactical gyro finds
#: north to about 5 deg at rest, so the heading bound for ``aligned`` is set to 10 deg
QUICK_STAGES = {'coarse_duration': 20.0, 'stage_min_duration': 10.0,
                'aligned_max_heading_sigma_deg': 10.0}


@dataclass
class Case:
    """One golden run.

    ``source``: 'bag' (``scenario`` simulated with ``seed`` for ``bag_duration`` s into a
    rosbag2, then the replay CLI), 'psins' (the replay CLI on ``recording``) or 'fog'
    (the Python API on the fog_mems car). ``params``: alignment parameters besides
    ``fine_filter``, given to the CLI as ``--set`` or, with ``via_yaml``, as a
    ``--params`` file in the ROS layout. ``args``: further CLI arguments. ``every``:
    one CSV row in ``every``. ``expect``: phases the run must pass through (checked
    when the goldens are regenerated, so a case keeps exercising the fine filter).
    """

    name: str
    fine_filter: str
    source: str
    what: str
    scenario: str = None
    seed: int = 0
    bag_duration: float = None
    recording: str = None
    params: dict = field(default_factory=dict)
    via_yaml: bool = False
    args: tuple = ()
    every: int = 40
    expect: tuple = ('coarse', 'fine', 'aligned')

    @property
    def golden(self):
        """Path of this case's golden CSV."""
        return GOLDEN_DIR / f'{self.name}.csv'


#: a still-base stage runs over its coarse window before its first row (issue 46,
#: align/stages/reprocess.py) and may hand over ``aligned``
STILL_PHASES = ('coarse', 'aligned')

CASES = (
    # still base (seed 002's models) on one 160 s bag of a still tactical-grade IMU
    Case('reduced7_static_tactical', 'reduced7', 'bag', 'reduced 7-state filter, still '
         'tactical IMU, 3 stages, params from a YAML file, first 120 s of the bag',
         scenario='static_tactical', seed=11, bag_duration=160.0,
         params={**STATIC_TACTICAL, **QUICK_STAGES}, via_yaml=True,
         args=('--duration', '120'), expect=STILL_PHASES),
    # (its restage at 59 s widens the heading 1-sigma to 16 deg, past 1.2 x the 10-deg
    # bound, for 14 s: the 10-state model's guard against counting the bias twice)
    Case('stationary10_static_tactical', 'stationary10', 'bag', '10-state filter, still '
         'tactical IMU, 2 stages', scenario='static_tactical', seed=11, bag_duration=160.0,
         params={**STATIC_TACTICAL, **QUICK_STAGES, 'max_stages': 2},
         expect=('coarse', 'aligned', 'fine')),
    Case('stationary12_static_tactical', 'stationary12', 'bag', '12-state filter, still '
         'tactical IMU, one stage, first 100 s of the bag', scenario='static_tactical',
         seed=11, bag_duration=160.0,
         params={**STATIC_TACTICAL, **QUICK_STAGES, 'max_stages': 1},
         args=('--duration', '100'), expect=STILL_PHASES),
    # seed 000 ship (GNSS position; the ASCKF also the velocity)
    Case('ckf_ship_position_only', 'ckf', 'bag', 'CKF on the seed 000 ship, GNSS position '
         'only (velocity topic ignored)', scenario='seed000_case1', seed=4,
         bag_duration=120.0, params={**SHIP, 'coarse_duration': 30.0},
         args=('--vel-topic', ''), expect=('coarse', 'fine', 'aligned')),
    Case('asckf_ship', 'asckf', 'bag', 'ASCKF (fading, Sage-Husa) on the seed 000 ship, '
         'GNSS position and velocity', scenario='seed000_case1', seed=4, bag_duration=120.0,
         params={**SHIP, 'coarse_duration': 30.0}, expect=('coarse', 'fine', 'aligned')),
    # seed 004 USV in severe sea with GNSS outliers (GNSS velocity measured)
    Case('vbckf_usv', 'vbckf', 'bag', 'VBCKF on the seed 004 USV; the filter is told a '
         '5 deg/h gyro (the consistency monitor inflates its covariance)',
         scenario='seed004_high', seed=1,
         bag_duration=120.0, params={**USV_HIGH, 'gyro_bias_dph': 5.0,
                                     'stage_min_duration': 10.0,
                                     'aligned_max_heading_sigma_deg': 5.0},
         # the stage runs over the window (coarse_reprocess_aided); the USV moves from the
         # start, so since session 52 its window ends after 20 s, before the filter is
         # aligned (its first row was aligned after the 60-s window before)
         expect=('coarse', 'fine', 'aligned')),
    Case('vbch_usv_preprocess', 'vbch', 'bag', 'VBCH on the seed 004 USV through the '
         'pre-processing stage (resampling + wavelet denoising), params from a YAML file',
         scenario='seed004_high', seed=1, bag_duration=120.0,
         params={**USV_HIGH, 'preprocess': True}, via_yaml=True,
         expect=('coarse', 'fine', 'aligned')),          # as vbckf_usv
    # integrated navigation filters: the CSV carries the navigation columns
    Case('kf_flight', 'kf', 'bag', '15-state KF on seed 001\'s flight (straight and level, '
         'then the 2 m/s^2 acceleration from 120 s), navigation columns',
         scenario='seed001_flight', seed=1, bag_duration=150.0, params=dict(FLIGHT),
         every=50, expect=('coarse', 'fine', 'aligned')),
    Case('vbakf_flight', 'vbakf', 'bag', 'VBAKF on seed 001\'s flight with the paper\'s '
         '9x Q, 30 s coarse', scenario='seed001_flight', seed=1, bag_duration=200.0,
         params={**FLIGHT, 'coarse_duration': 30.0, 'nav_q_scale': 9.0}, every=50),
    Case('mvbakf_car', 'mvbakf', 'bag', 'MVBAKF on seed 003\'s car (MEMS), params from a '
         'YAML file', scenario='seed003_car', seed=5, bag_duration=120.0,
         params={**CAR, 'mvbakf_tau': 6.0, 'nav_forgetting': 0.95, 'nav_iterations': 5},
         via_yaml=True, expect=MEMS_CAR_PHASES_ALIGNED),
    Case('ukf_car', 'ukf', 'bag', '18-state UKF on seed 003\'s car (MEMS)',
         scenario='seed003_car', seed=5, bag_duration=120.0, params=dict(CAR),
         expect=MEMS_CAR_PHASES_ALIGNED),
    # real recordings
    Case('psins_lasergyro_reduced7_300s', 'reduced7', 'psins', 'laser-gyro recording, '
         'default parameters, first 300 s', recording='psins_lasergyro.imu',
         args=('--duration', '300'), every=100, expect=STILL_PHASES),
    Case('psins_lasergyro_stationary12_300s', 'stationary12', 'psins', 'laser-gyro '
         'recording, 12-state filter, first 300 s', recording='psins_lasergyro.imu',
         args=('--duration', '300'), every=100, expect=STILL_PHASES),
    Case('fog_mems_car_asckf', 'asckf', 'fog', 'fog_mems car recording (100 s) through '
         'AlignmentPipeline + feed_arrays, GNSS-like position and velocity',
         params=dict(FOG), every=25, expect=('coarse', 'fine')),
)
BY_NAME = {c.name: c for c in CASES}


def _bag(case, workdir):
    """Return the case's rosbag2 in ``workdir`` (simulated once per scenario, seed, duration)."""
    from sins_align_ros.io.bag import write_scenario_bag
    from sins_align_ros.sim.presets import scenario
    path = Path(workdir) / f'bag_{case.scenario}_seed{case.seed}_{case.bag_duration:g}s'
    if not path.exists():
        sc = scenario(case.scenario, duration=case.bag_duration)
        write_scenario_bag(path, sc, seed=case.seed, start_time=START)
    return path


def _param_args(case, workdir):
    values = {'fine_filter': case.fine_filter, **case.params}
    if case.via_yaml:
        import yaml
        path = Path(workdir) / f'{case.name}.yaml'
        path.write_text(yaml.safe_dump({'alignment_node': {'ros__parameters': values}}))
        return ['--params', str(path)]
    out = []
    for k, v in values.items():
        out += ['--set', f'{k}={str(v).lower() if isinstance(v, bool) else v}']
    return out


def run_case(case, workdir, data):
    """Run ``case`` with the code imported now; write ``workdir/<name>.csv``, return its path.

    ``data(filename)`` returns the path of a recording in ../shared/data.
    """
    workdir = Path(workdir)
    out = workdir / f'{case.name}.csv'
    if case.source == 'fog':
        from sins_align_ros.align.pipeline import AlignmentPipeline
        from sins_align_ros.eval.feed import feed_arrays
        from sins_align_ros.io.fog import read_fog_mems
        from sins_align_ros.io.results import write_csv
        rec = read_fog_mems(data('fog_mems_imu.csv'), data('fog_mems_reference.csv'))
        p = AlignmentPipeline({'fine_filter': case.fine_filter, **case.params})
        p.start_clock(rec.t[0] - 0.01)
        result = feed_arrays(p, rec.imu_like(), rec.gnss_like(), use_velocity=True)
        write_csv(out, result, every=case.every)
        return out
    from sins_align_ros.cli.replay import main as replay
    src = _bag(case, workdir) if case.source == 'bag' else data(case.recording)
    argv = [str(src), *_param_args(case, workdir), *case.args, '--out', str(out),
            '--every', str(case.every), '--quiet']
    rc = replay(argv)
    if rc != 0:
        raise RuntimeError(f'replay exited with {rc}: sins_align_replay {" ".join(argv)}')
    return out

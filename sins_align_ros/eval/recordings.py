"""The real recordings of ``../shared/data`` through the pipeline.

- ``fog_mems_imu.csv`` / ``fog_mems_reference.csv``: a car with a MEMS IMU and a FOG
  INS reference (:mod:`sins_align_ros.io.fog`); the reference position and velocity
  are the GNSS aiding, its attitude the truth;
- ``psins_lasergyro.imu``: a still laser-gyro IMU (:mod:`sins_align_ros.io.psins`),
  no reference attitude (only a yaw hint in the file).
"""
from pathlib import Path
from types import SimpleNamespace

from ..units import DEG
from .run import run_pipeline

#: ``../shared/data`` beside the checkout holding this package
SHARED_DATA = Path(__file__).resolve().parents[3] / 'shared' / 'data'
#: pipeline parameters describing the fog_mems car's sensors (MEMS grade, reference as GNSS)
FOG_PARAMS = {'gyro_bias_dph': 200.0, 'gyro_arw_dpsh': 1.0, 'accel_bias_ug': 2000.0,
              'accel_vrw_ug_rthz': 200.0, 'coarse_duration': 10.0, 'gnss_pos_sigma_m': 0.5,
              'gnss_vel_sigma_mps': 0.05}
FOG_FILES = ('fog_mems_imu.csv', 'fog_mems_reference.csv')
PSINS_FILE = 'psins_lasergyro.imu'


def read_fog(data_dir=None):
    """Read the fog_mems recording (a :class:`~sins_align_ros.io.fog.FogRecording`) or None."""
    from ..io.fog import read_fog_mems
    d = Path(SHARED_DATA if data_dir is None else data_dir)
    if not (d / FOG_FILES[0]).exists():
        return None
    return read_fog_mems(d / FOG_FILES[0], d / FOG_FILES[1])


def run_fog(rec, fine_filter, **extra):
    """Run the fog_mems recording ``rec`` through the pipeline with :data:`FOG_PARAMS`.

    Returns ``(run, errors)``: the :class:`~.run.Run` and the final attitude error
    against the FOG reference (:meth:`~sins_align_ros.io.fog.FogRecording.errors`, deg).
    """
    data = SimpleNamespace(imu=rec.imu_like(), gnss=rec.gnss_like())
    run = run_pipeline({'fine_filter': fine_filter, **extra, **FOG_PARAMS}, data,
                       use_velocity=True, t0=rec.t[0] - 0.01)
    return run, rec.errors(run.out)


def read_psins_log(data_dir=None):
    """Read the PSINS recording (:func:`~sins_align_ros.io.psins.read_psins`); None if absent."""
    from ..io.psins import read_psins
    f = Path(SHARED_DATA if data_dir is None else data_dir) / PSINS_FILE
    return read_psins(f) if f.exists() else None


def run_psins(log, fine_filter, seconds=None):
    """Run the first ``seconds`` (all if None) of the PSINS recording ``log`` through the pipeline.

    Still base, no GNSS: the file's initial position as the parameters. Returns the
    :class:`~.run.Run`.
    """
    n = len(log.t) if seconds is None else int(seconds / log.dt)
    data = SimpleNamespace(imu=SimpleNamespace(t=log.t[:n], dtheta=log.dtheta[:n],
                                               dv=log.dv[:n]), gnss=None)
    return run_pipeline({'fine_filter': fine_filter,
                         'initial_latitude_deg': float(log.pos0[0] / DEG),
                         'initial_longitude_deg': float(log.pos0[1] / DEG),
                         'initial_height_m': float(log.pos0[2])},
                        data, block=None, t0=log.t[0] - log.dt)

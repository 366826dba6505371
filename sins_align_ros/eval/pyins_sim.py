"""An independent IMU simulator for cross-checks: ``pyins.sim.generate_imu`` (PyPI python-ins).

Our simulator (``sim/imu.py``) integrates closed-form body rates and specific force
with Gauss-Legendre quadrature in ENU/FLU with Somigliana normal gravity. pyins
builds splines of the same trajectory in the inertial frame (NED/FRD, its own
gravitation model) and integrates them analytically. Both produce plain integrals
``int w_ib_b dt`` and ``int f_b dt`` over each interval, so after the frame
conversion they must agree to the spline and gravity-model differences.

Test and benchmark only: pyins is not a dependency of the package; it is imported
when :func:`pyins_increments` is called, never when this module is imported.
"""
from types import SimpleNamespace

import numpy as np

from ..nav.frames import euler_to_dcm
from ..sim.gnss import GnssErrors
from ..sim.imu import ImuErrors
from ..sim.trajectory import PositionIntegrator

#: ENU -> NED (also NED -> ENU: symmetric, its own inverse)
C_ENU_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: body FRD -> FLU (its own inverse)
C_FRD_FLU = np.diag([1.0, -1.0, -1.0])


def truth_on_grid(traj, t):
    """Closed-form truth of ``traj`` at times ``t`` (N,): euler (REP-103), v_n (ENU), pos."""
    pos_fn = PositionIntegrator(traj).advance(float(t[-1]))
    kin = traj.kinematics(t)
    return kin.euler, kin.v_n, pos_fn(t)


def pyins_increments(traj, t):
    """IMU increments along ``traj`` from pyins, in our frames.

    Parameters
    ----------
    traj : sins_align_ros.sim.trajectory.Trajectory
    t : ndarray (N+1,)
        Sample times, s; increment k covers ``[t[k], t[k+1]]``.

    Returns
    -------
    dtheta, dv : ndarray (N, 3)
        rad and m/s, body FLU axes.
    """
    from pyins import sim as pyins_sim
    from pyins import transform as pyins_tf
    euler, v_n, pos = truth_on_grid(traj, t)
    C_frd_ned = C_ENU_NED @ euler_to_dcm(euler) @ C_FRD_FLU
    rph = pyins_tf.mat_to_rph(C_frd_ned)
    lla = np.column_stack([np.rad2deg(pos[:, 0]), np.rad2deg(pos[:, 1]), pos[:, 2]])
    _, imu = pyins_sim.generate_imu(t, lla, rph, v_n @ C_ENU_NED.T, sensor_type='increment')
    gyro = imu[['gyro_x', 'gyro_y', 'gyro_z']].to_numpy()[1:]
    accel = imu[['accel_x', 'accel_y', 'accel_z']].to_numpy()[1:]
    return gyro @ C_FRD_FLU.T, accel @ C_FRD_FLU.T


def simulate_with_pyins(sc, seed, duration=None):
    """Run scenario ``sc`` with pyins's increments and our sensor and GNSS error models.

    The errors are drawn as :class:`~sins_align_ros.sim.scenario.ScenarioStream` draws
    them for the same seed, so a run differs from ours only by the ideal increments.

    Returns
    -------
    SimpleNamespace
        ``imu`` (t, dtheta, dv, euler (N, 3)) and ``gnss`` (an epoch record or None),
        like a :class:`~sins_align_ros.sim.scenario.SimBlock`.
    """
    duration = sc.duration if duration is None else duration
    n = int(round(duration * sc.imu_rate_hz))
    t = np.arange(n + 1) / sc.imu_rate_hz
    dtheta, dv = pyins_increments(sc.trajectory, t)
    ss_imu, ss_gnss = np.random.SeedSequence(seed).spawn(2)
    if not sc.imu.ideal:
        errors = ImuErrors(sc.imu, np.random.default_rng(ss_imu))
        dtheta, dv = errors.apply(dtheta, dv, 1.0 / sc.imu_rate_hz)
    euler, v_n, pos = truth_on_grid(sc.trajectory, t)
    imu = SimpleNamespace(t=t[1:], dtheta=dtheta, dv=dv, euler=euler[1:])
    gnss = None
    if sc.gnss is not None:
        k = np.arange(1, int(np.floor(duration * sc.gnss.rate_hz + 1e-9)) + 1)
        tg = k / sc.gnss.rate_hz
        idx = np.searchsorted(t, tg - 1e-9)
        prof = sc.extra.get('gnss_noise_profile')
        scale = None if prof is None else np.interp(tg, *np.asarray(prof, dtype=float).T)
        gnss = GnssErrors(sc.gnss, np.random.default_rng(ss_gnss)).measure(
            tg, pos[idx], v_n[idx], noise_scale=scale)
    return SimpleNamespace(imu=imu, gnss=gnss)

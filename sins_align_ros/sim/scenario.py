"""Run a :class:`~sins_align_ros.sim.presets.Scenario`: IMU and GNSS streams with truth."""
from dataclasses import dataclass

import numpy as np

from ..nav import earth
from ..nav.frames import euler_rates_to_w_nb_b, euler_to_dcm
from ..units import DEG
from .gnss import GnssErrors
from .imu import ImuSimulator


def antenna_truth(traj, t, pos, lever_arm_m):
    """Return the true position (N, 3) and ENU velocity (N, 3) of a GNSS antenna on an arm.

    ``pos`` (N, 3) the IMU's (lat, lon rad, h m) at times ``t`` (N,); ``lever_arm_m`` (3,)
    the antenna relative to the IMU in the vehicle frame (FLU). ``p + C l`` and
    ``v + C (w_eb_b x l)``, the rate of the body against the Earth.
    """
    kin = traj.kinematics(t)
    l_b = np.asarray(lever_arm_m, dtype=float)
    C = euler_to_dcm(kin.euler)
    w_eb_b = euler_rates_to_w_nb_b(kin.euler, kin.euler_rate) + np.einsum(
        'kji,kj->ki', C, earth.w_en_n(pos[:, 0], pos[:, 2], kin.v_n))
    a_n = np.einsum('kij,j->ki', C, l_b)
    R_M, R_N = earth.radii(pos[:, 0])
    ant = pos + np.column_stack([a_n[:, 1] / (R_M + pos[:, 2]),
                                 a_n[:, 0] / ((R_N + pos[:, 2]) * np.cos(pos[:, 0])), a_n[:, 2]])
    return ant, kin.v_n + np.einsum('kij,kj->ki', C, np.cross(w_eb_b, l_b))


@dataclass
class SimBlock:
    """IMU samples of one block and the GNSS epochs that fall inside it.

    ``imu``: :class:`~sins_align_ros.sim.imu.ImuChunk`; ``gnss``:
    :class:`~sins_align_ros.sim.gnss.GnssEpoch` or None; ``gnss_truth_pos`` and
    ``gnss_truth_v`` (M, 3): the truth at the GNSS epochs.
    """

    imu: object
    gnss: object = None
    gnss_truth_pos: np.ndarray = None
    gnss_truth_v: np.ndarray = None


class ScenarioStream:
    """Deterministic block-by-block simulation of a scenario.

    Parameters
    ----------
    sc : Scenario
    seed : int
        One seed for the whole run; IMU and GNSS draw from independent child streams.
    imu_rate_hz, gnss_rate_hz : float or None
        Override the scenario's rates.
    """

    def __init__(self, sc, seed=0, imu_rate_hz=None, gnss_rate_hz=None):
        self.sc = sc
        ss_imu, ss_gnss = np.random.SeedSequence(seed).spawn(2)
        rate = imu_rate_hz or sc.imu_rate_hz
        self.imu = ImuSimulator(sc.trajectory, sc.imu, rate, seed=ss_imu)
        self.gnss_rate = (gnss_rate_hz or sc.gnss.rate_hz) if sc.gnss else 0.0
        self.gnss = GnssErrors(sc.gnss, np.random.default_rng(ss_gnss)) if sc.gnss else None
        self._gnss_k = 1
        rpy = np.asarray(sc.imu_mounting_rpy_deg, dtype=float)
        #: IMU -> vehicle rotation, or None
        self.C_s_v = euler_to_dcm(rpy * DEG) if np.any(rpy) else None
        prof = sc.extra.get('gnss_noise_profile')
        self._noise_profile = None if prof is None else np.asarray(prof, dtype=float)

    @property
    def dt(self):
        """IMU sample interval, s."""
        return self.imu.dt

    @property
    def t(self):
        """Time of the last sample produced, s."""
        return self.imu.k * self.imu.dt

    def next_block(self, n):
        """Simulate the next ``n`` IMU samples and the GNSS epochs in the same interval."""
        t_start = self.t
        chunk = self.imu.next_chunk(n)
        if self.C_s_v is not None:              # x_s = C_s_v^T x_v, as rows
            chunk.dtheta = chunk.dtheta @ self.C_s_v
            chunk.dv = chunk.dv @ self.C_s_v
        block = SimBlock(imu=chunk)
        if self.gnss is None:
            return block
        t_end = chunk.t[-1]
        k1 = int(np.floor(t_end * self.gnss_rate + 1e-9))
        if k1 < self._gnss_k:
            return block
        tg = np.arange(self._gnss_k, k1 + 1) / self.gnss_rate
        tg = tg[tg > t_start - 1e-12]
        self._gnss_k = k1 + 1
        pos = chunk.extra['pos_fn'](tg)
        if np.any(self.sc.gnss_lever_arm_m):
            pos, v_n = antenna_truth(self.sc.trajectory, tg, pos, self.sc.gnss_lever_arm_m)
        else:
            v_n = self.sc.trajectory.kinematics(tg).v_n
        scale = None
        if self._noise_profile is not None:
            scale = np.interp(tg, self._noise_profile[:, 0], self._noise_profile[:, 1])
        block.gnss = self.gnss.measure(tg, pos, v_n, noise_scale=scale)
        block.gnss_truth_pos = pos
        block.gnss_truth_v = v_n
        return block

"""Accuracy limits of stationary alignment for a simulated scenario (DESIGN.md).

For a still base the achievable accuracy is set by the sensors (seed 002 eq. 15):
east tilt ``phi_E ~ a_N/g``, north tilt ``phi_N ~ -a_E/g``, heading
``phi_U ~ -eps_E/(W cos L)`` (biases projected on the navigation axes), plus the
noise-driven spread over the fine-alignment time ``T``: ``VRW/(g sqrt(T))`` for
tilt and ``ARW/(W cos L sqrt(T))`` for heading.
"""
from dataclasses import dataclass

import numpy as np

from ..nav import earth
from ..nav.frames import DEG, euler_to_dcm
from ..sim.imu import DPH, DPSH, UG


@dataclass
class LimitBand:
    """Per-axis (east, north, up) bias-driven and noise-driven error terms, rad."""

    bias: np.ndarray
    noise: np.ndarray

    def tolerance(self, bias_factor=1.2, noise_factor=3.0):
        """Return the acceptance band of issue 3: ``1.2 x bias + 3 x noise`` per axis."""
        return bias_factor * self.bias + noise_factor * self.noise


def scenario_limits(sc, T):
    """Return the :class:`LimitBand` of a still scenario after ``T`` s of fine alignment."""
    lat = sc.trajectory.lat_deg * DEG
    g = earth.gravity(lat, sc.trajectory.h)
    wc = earth.OMEGA_IE * np.cos(lat)
    C = euler_to_dcm(sc.trajectory.kinematics(0.0).euler[0])
    a_n = C @ (np.broadcast_to(np.asarray(sc.imu.accel_bias_ug, float), (3,)) * UG)
    e_n = C @ (np.broadcast_to(np.asarray(sc.imu.gyro_bias_dph, float), (3,)) * DPH)
    bias = np.array([abs(a_n[1]) / g, abs(a_n[0]) / g, abs(e_n[0]) / wc])
    tilt_noise = sc.imu.accel_vrw_ug_rthz * UG / (g * np.sqrt(T))
    noise = np.array([tilt_noise, tilt_noise, sc.imu.gyro_arw_dpsh * DPSH / (wc * np.sqrt(T))])
    return LimitBand(bias=bias, noise=noise)

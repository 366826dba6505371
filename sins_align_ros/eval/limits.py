"""Accuracy limits of stationary alignment for a simulated scenario.

As docs/contracts.md's "What aligned well means" defines them.

For a still base the achievable accuracy is set by the sensors (seed 002 eq. 15):
east tilt ``phi_E ~ a_N/g``, north tilt ``phi_N ~ -a_E/g``, heading
``phi_U ~ -eps_E/(W cos L)`` (biases projected on the navigation axes), plus the
noise-driven spread over the fine-alignment time ``T``: ``VRW/(g sqrt(T))`` for
tilt and ``ARW/(W cos L sqrt(T))`` for heading.
"""
from dataclasses import dataclass

import numpy as np

from ..nav import earth
from ..nav.frames import euler_to_dcm
from ..units import DEG, DPH, DPSH, UG


@dataclass
class LimitBand:
    """Per-axis (east, north, up) bias-driven and noise-driven error terms, rad."""

    bias: np.ndarray
    noise: np.ndarray

    def tolerance(self, bias_factor=1.2, noise_factor=3.0):
        """Return the acceptance band of issue 3: ``1.2 x bias + 3 x noise`` per axis."""
        return bias_factor * self.bias + noise_factor * self.noise


def velocity_reference_heading_noise(sigma_v, rate_hz, T, lat, g):
    """Heading noise (rad, 1 sigma) that a noisy velocity reference leaves after ``T`` s.

    A heading error ``psi`` tilts the platform at ``psi W cos(L)`` per second, so the
    horizontal velocity error grows as ``g W cos(L) psi t^2 / 2``. Fitting a quadratic
    (unknown initial velocity and tilt) to ``N = rate_hz T`` velocity measurements of
    noise ``sigma_v`` over ``[0, T]`` gives its second-order coefficient with variance
    ``180 sigma_v^2 / (N T^4)``, hence ``psi`` with
    ``2 sigma_v sqrt(180 / N) / (T^2 g W cos L)``. A still base's zero velocity is
    exact (no such term); a GNSS velocity of 0.05 m/s at 1 Hz leaves 1.4' after
    540 s at 45 deg latitude, more than a marine-grade gyro's terms. Manoeuvres make
    heading more observable than this; it is the bound for a base that does not.
    """
    n = max(rate_hz * T, 1.0)
    return 2.0 * sigma_v * np.sqrt(180.0 / n) / (T * T * g * earth.OMEGA_IE * np.cos(lat))


def scenario_limits(sc, T, t_att=0.0):
    """Return the :class:`LimitBand` of a still scenario after ``T`` s of fine alignment.

    The biases are projected on the navigation axes with the attitude at ``t_att``
    (the end of the run for a vehicle that turns).
    """
    lat = sc.trajectory.lat_deg * DEG
    g = earth.gravity(lat, sc.trajectory.h)
    wc = earth.OMEGA_IE * np.cos(lat)
    C = euler_to_dcm(sc.trajectory.kinematics(float(t_att)).euler[0])
    a_n = C @ (np.broadcast_to(np.asarray(sc.imu.accel_bias_ug, float), (3,)) * UG)
    e_n = C @ (np.broadcast_to(np.asarray(sc.imu.gyro_bias_dph, float), (3,)) * DPH)
    bias = np.array([abs(a_n[1]) / g, abs(a_n[0]) / g, abs(e_n[0]) / wc])
    tilt_noise = sc.imu.accel_vrw_ug_rthz * UG / (g * np.sqrt(T))
    noise = np.array([tilt_noise, tilt_noise, sc.imu.gyro_arw_dpsh * DPSH / (wc * np.sqrt(T))])
    return LimitBand(bias=bias, noise=noise)


def alignment_limits(sc, T, fine_filter, t_att=0.0):
    """Return the :class:`LimitBand` of ``fine_filter`` on scenario ``sc`` after ``T`` s.

    :func:`scenario_limits`, plus for the GNSS-aided (moving-base) filters the heading
    noise of their velocity reference (:func:`velocity_reference_heading_noise` with
    the scenario's GNSS velocity noise and rate) in the up-axis noise term. A still
    base's zero velocity is exact and adds nothing.
    """
    from ..align.params import MOVING_FILTERS
    band = scenario_limits(sc, T, t_att)
    if fine_filter in MOVING_FILTERS and sc.gnss is not None:
        lat = sc.trajectory.lat_deg * DEG
        ref = velocity_reference_heading_noise(sc.gnss.vel_sigma, sc.gnss.rate_hz, T, lat,
                                               earth.gravity(lat, sc.trajectory.h))
        band.noise = band.noise.copy()
        band.noise[2] = np.hypot(band.noise[2], ref)
    return band

"""Zero-velocity fine-alignment models of seed 002 (12-, 10- and 7-state).

Misalignment ``phi`` (ENU, rad) is defined by seed 002 eq. 3,
``C~_b_n = (I - [phi x]) C_b_n``; the filter feeds it back as
``C_b_n <- exp([phi x]) C~_b_n``. The specific force of a still base is
``f_n = [0, 0, g]`` so ``[f_n x] phi = [-g phi_N, g phi_E, 0]``.

* ``stationary12`` — seed 002 eq. 6-7: ``x = [dV(3), phi(3), a_b(3), eps_b(3)]``,
  ``dV' = -2 [w_ie x] dV + [f_n x] phi + C a_b``, ``phi' = -[w_ie x] phi - C eps_b``,
  three velocity measurements; mechanization with Coriolis, free vertical channel.
* ``stationary10`` — the classic 10-state form: horizontal velocity only
  (vertical held at zero), ``x = [dV_E, dV_N, phi(3), a_x, a_y, eps_b(3)]``,
  Coriolis kept (seed 002's 10-state model "without the improvements").
* ``reduced7`` — seed 002 eq. 16: ``x = [dV_E, dV_N, phi(3), eps_N, eps_U]`` with
  nav-frame equivalent biases, no Coriolis (eq. 8), the unobservable
  ``(a_E, a_N, eps_E)`` removed (eq. 15) and constant F, G (eq. 17-18).

Because the 7-state model drops the unobservable biases, its covariance alone
would claim more accuracy than is possible; :meth:`StationaryModel.attitude_floor`
adds their effect back (tilt ``a/g``, heading ``eps_E/(W cos L)``) so that the
reported uncertainty stays honest.
"""
from dataclasses import dataclass

import numpy as np

from ..nav import earth
from ..nav.mechanization import MechanizationOptions


@dataclass(frozen=True)
class NoiseSpec:
    """Sensor error statistics used by the filters (SI units).

    ``gyro_bias`` (rad/s) and ``accel_bias`` (m/s^2) are the 1-sigma constant
    biases; ``gyro_arw`` (rad/sqrt(s)) and ``accel_vrw`` (m/s^2/sqrt(Hz)) the
    white-noise densities.
    """

    gyro_bias: float
    gyro_arw: float
    accel_bias: float
    accel_vrw: float


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


class StationaryModel:
    """A seed 002 fine-alignment model (see module docstring).

    Attributes
    ----------
    name : str
    n : int
        State dimension.
    labels : tuple of str
    i_v : ndarray
        Indices of the velocity-error states.
    i_phi : ndarray (3,)
        Indices of phi_E, phi_N, phi_U.
    meas : ndarray
        ENU components of velocity measured (zero-velocity update).
    mech : MechanizationOptions
        The equivalence operations the mechanization must apply with this model.
    """

    def __init__(self, name):
        if name == 'stationary12':
            self.labels = ('dVE', 'dVN', 'dVU', 'phiE', 'phiN', 'phiU',
                           'ax', 'ay', 'az', 'ex', 'ey', 'ez')
            self.i_v, self.i_phi, self.meas = np.arange(3), np.arange(3, 6), np.arange(3)
            self.mech = MechanizationOptions(transport_rate=False, update_position=False,
                                             coriolis=True, hold_vertical=False)
        elif name == 'stationary10':
            self.labels = ('dVE', 'dVN', 'phiE', 'phiN', 'phiU', 'ax', 'ay', 'ex', 'ey', 'ez')
            self.i_v, self.i_phi, self.meas = np.arange(2), np.arange(2, 5), np.arange(2)
            self.mech = MechanizationOptions.stationary(coriolis=True)
        elif name == 'reduced7':
            self.labels = ('dVE', 'dVN', 'phiE', 'phiN', 'phiU', 'eN', 'eU')
            self.i_v, self.i_phi, self.meas = np.arange(2), np.arange(2, 5), np.arange(2)
            self.mech = MechanizationOptions.stationary(coriolis=False)
        else:
            raise ValueError(f'unknown stationary model {name!r}')
        self.name = name
        self.n = len(self.labels)

    # -- continuous-time model ---------------------------------------------------
    def F(self, C_b_n, lat, g):
        """System matrix (n, n) at attitude ``C_b_n``, latitude ``lat``, gravity ``g``."""
        w = earth.w_ie_n(lat)
        Fp = -_skew(w)                                   # phi' = -[w_ie x] phi
        Fv = _skew([0.0, 0.0, g])                        # dV' = [f_n x] phi
        F = np.zeros((self.n, self.n))
        if self.name == 'stationary12':
            F[0:3, 0:3] = -2.0 * _skew(w)
            F[0:3, 3:6] = Fv
            F[0:3, 6:9] = C_b_n
            F[3:6, 3:6] = Fp
            F[3:6, 9:12] = -C_b_n
        elif self.name == 'stationary10':
            F[0:2, 0:2] = (-2.0 * _skew(w))[:2, :2]
            F[0:2, 2:5] = Fv[:2]
            F[0:2, 5:7] = C_b_n[:2, :2]
            F[2:5, 2:5] = Fp
            F[2:5, 7:10] = -C_b_n
        else:                                            # seed 002 eq. 16
            F[0:2, 2:5] = Fv[:2]
            F[2:5, 2:5] = Fp
            F[3, 5] = -1.0
            F[4, 6] = -1.0
        return F

    def G_Qc(self, C_b_n, noise):
        """Noise input matrix G (n, k) and white-noise PSD Qc (k, k).

        Velocity noise is the accelerometer VRW, attitude noise the gyro ARW; in
        the nav frame they are isotropic (seed 002 eq. 17-18), so G is constant.
        """
        nv = len(self.i_v)
        G = np.zeros((self.n, nv + 3))
        G[self.i_v, np.arange(nv)] = 1.0
        G[self.i_phi, nv + np.arange(3)] = 1.0
        Qc = np.diag([noise.accel_vrw ** 2] * nv + [noise.gyro_arw ** 2] * 3)
        return G, Qc

    def H(self):
        """Measurement matrix: the measured velocity components."""
        H = np.zeros((len(self.meas), self.n))
        H[np.arange(len(self.meas)), self.i_v[self.meas]] = 1.0
        return H

    def P0(self, sigma_v, sigma_phi, noise):
        """Return the initial covariance: velocity sigma (m/s), misalignment sigmas (3,) rad."""
        d = np.zeros(self.n)
        d[self.i_v] = sigma_v ** 2
        d[self.i_phi] = np.asarray(sigma_phi, dtype=float) ** 2
        if self.name == 'stationary12':
            d[6:9] = noise.accel_bias ** 2
            d[9:12] = noise.gyro_bias ** 2
        elif self.name == 'stationary10':
            d[5:7] = noise.accel_bias ** 2
            d[7:10] = noise.gyro_bias ** 2
        else:
            d[5:7] = noise.gyro_bias ** 2
        return np.diag(d)

    def reset_biases(self, x, P, noise):
        """Zero the bias states and give them their prior covariance again (staged re-init)."""
        nb0 = len(self.i_v) + 3
        x = x.copy()
        x[nb0:] = 0.0
        P = P.copy()
        P[nb0:, :] = 0.0
        P[:, nb0:] = 0.0
        prior = self.P0(0.0, np.zeros(3), noise)
        P[nb0:, nb0:] = prior[nb0:, nb0:]
        return x, P

    def attitude_floor(self, lat, noise):
        """Variance (3,) of the misalignment the model cannot see (zero for 12/10 states).

        Seed 002 eq. 15: ``phi_N = -a_E/g``, ``phi_E = a_N/g`` and
        ``phi_U = -eps_E/(W cos L)`` are indistinguishable from the biases.
        """
        if self.name != 'reduced7':
            return np.zeros(3)
        return unobservable_variance(lat, noise)


def sees_earth_rate(lat, noise):
    """Tell whether the gyro of ``noise`` (:class:`NoiseSpec`) can find north at rest.

    Its bias sigma at most half the horizontal Earth rate at latitude ``lat`` (rad): above
    it, the heading of a still base is the bias's, not north's (a MEMS gyro).
    """
    return noise.gyro_bias <= 0.5 * earth.OMEGA_IE * np.cos(lat)


def unobservable_variance(lat, noise):
    """Misalignment variances (3,) rad^2 the biases leave at rest (seed 002 eq. 15).

    Tilt ``(a/g)^2`` east and north, heading ``(eps_E/(W cos L))^2``, from the bias
    sigmas of ``noise`` (:class:`NoiseSpec`) at latitude ``lat`` (rad).
    """
    g = earth.gravity(lat, 0.0)
    tilt = (noise.accel_bias / g) ** 2
    head = (noise.gyro_bias / (earth.OMEGA_IE * np.cos(lat))) ** 2
    return np.array([tilt, tilt, head])


MODELS = ('reduced7', 'stationary10', 'stationary12')


def limits(lat, accel_bias, gyro_bias_east, gyro_arw, T):
    """Analytic accuracy limits of stationary alignment (docs/contracts.md "aligned well").

    Returns ``(tilt_bias, heading_bias, heading_noise)`` in rad: tilt ``a/g``,
    heading ``eps_E/(W cos L)`` from the biases, and heading
    ``ARW/(W cos L sqrt(T))`` from the noise over the fine-alignment time ``T``.
    """
    g = earth.gravity(lat, 0.0)
    wc = earth.OMEGA_IE * np.cos(lat)
    return (abs(accel_bias) / g, abs(gyro_bias_east) / wc, gyro_arw / (wc * np.sqrt(T)))

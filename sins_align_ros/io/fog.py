"""The fog_mems car recording (../shared/data): MEMS IMU increments and a FOG-INS reference.

``fog_mems_imu.csv``: ``t, dtheta_xyz (rad), dv_xyz (m/s)`` at 100 Hz, body RFU.
``fog_mems_reference.csv``: ``t, pitch, roll, yaw (deg, PSINS: yaw CCW from north),
vE, vN, vU, lat, lon (deg), h`` at 10 Hz. Converted here to the package conventions
(FLU body, REP-103 Euler angles, radians); the reference position and velocity
serve as GNSS-like aiding, its attitude as the truth.
"""
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from ..nav.frames import (C_RFU_TO_FLU, attitude_error, dcm_to_euler, psins_att_to_dcm,
                          quat_to_dcm)
from ..units import DEG


class FogFormatError(ValueError):
    """The files are not in the documented format."""


@dataclass
class FogRecording:
    """The recording in package conventions.

    IMU ``t`` (N,), ``dtheta``/``dv`` (N, 3) FLU; reference ``ref_t`` (M,), ``ref_C``
    (M, 3, 3) body FLU -> ENU, ``ref_v`` (M, 3) ENU, ``ref_pos`` (M, 3) rad, rad, m.
    """

    t: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    ref_t: np.ndarray
    ref_C: np.ndarray
    ref_v: np.ndarray
    ref_pos: np.ndarray

    def imu_like(self):
        """Return the IMU part with the attribute names of a simulated chunk (t, dtheta, dv)."""
        return SimpleNamespace(t=self.t, dtheta=self.dtheta, dv=self.dv)

    def gnss_like(self, rate_hz=1.0, pos_sigma=0.5, vel_sigma=0.05):
        """Return the reference position/velocity decimated to ``rate_hz`` as GNSS epochs.

        Attributes as a simulated GNSS epoch: t, lat, lon, h, v_n, fix, pos_cov, vel_cov.
        """
        step = max(1, int(round(1.0 / (rate_hz * np.median(np.diff(self.ref_t))))))
        idx = np.arange(step - 1, len(self.ref_t), step)
        n = len(idx)
        return SimpleNamespace(t=self.ref_t[idx], lat=self.ref_pos[idx, 0],
                               lon=self.ref_pos[idx, 1], h=self.ref_pos[idx, 2],
                               v_n=self.ref_v[idx], fix=np.ones(n, bool),
                               pos_cov=np.full(3, pos_sigma ** 2),
                               vel_cov=np.full(3, vel_sigma ** 2))

    def errors(self, out):
        """Return the final attitude error of a pipeline output against the reference, in degrees.

        Returns a dict: ``heading``, ``roll``, ``pitch`` (estimate minus reference,
        heading clockwise-from-north sense), ``t`` the output time compared, and
        ``sigma_yaw`` (the reported 1-sigma).
        """
        k = len(out.t) - 1
        j = int(np.argmin(np.abs(self.ref_t - out.t[k])))
        C = quat_to_dcm(out.q[k])
        e_est, e_ref = dcm_to_euler(C), dcm_to_euler(self.ref_C[j])
        d = (e_est - e_ref + np.pi) % (2 * np.pi) - np.pi
        phi = attitude_error(C, self.ref_C[j])
        return {'t': float(out.t[k]), 'roll': d[0] / DEG, 'pitch': -d[1] / DEG,
                'heading': -d[2] / DEG, 'phi_enu': phi / DEG,
                'sigma_yaw': float(out.sigma[k, 2] / DEG)}


def _load(path, ncol):
    try:
        a = np.loadtxt(path, delimiter=',', comments='#', ndmin=2)
    except (OSError, ValueError) as exc:
        raise FogFormatError(f'{path}: {exc}') from None
    if a.shape[1] != ncol or len(a) < 2:
        raise FogFormatError(f'{path}: expected {ncol} columns, got {a.shape[1]}')
    return a


def read_fog_mems(imu_path, ref_path):
    """Read both files; returns a :class:`FogRecording` in package conventions."""
    imu = _load(imu_path, 7)
    ref = _load(ref_path, 10)
    att = ref[:, 1:4] * DEG
    return FogRecording(t=imu[:, 0], dtheta=imu[:, 1:4] @ C_RFU_TO_FLU.T,
                        dv=imu[:, 4:7] @ C_RFU_TO_FLU.T, ref_t=ref[:, 0],
                        ref_C=psins_att_to_dcm(att), ref_v=ref[:, 4:7],
                        ref_pos=np.column_stack([ref[:, 7] * DEG, ref[:, 8] * DEG, ref[:, 9]]))

"""Reader for PSINS ``.imu`` text logs (Yan Gongmin's PSINS toolbox format).

Layout: ``%`` comment lines; data line 1 ``pitch0 roll0 yaw0 VE0 VN0 VU0`` (deg,
m/s); line 2 ``lat0 lon0 h0 t0 sample_interval_ms g``; line 3 scale factors
``gf_x gf_y gf_z`` (arcsec per count) and ``af_x af_y af_z`` (micro-g * s per
count, the micro-g taken with the file's g); then one line per sample of six
integer counts: angle increments x y z, velocity increments x y z. Bodies are
RFU; we convert to FLU (:data:`sins_align_ros.nav.frames.C_RFU_TO_FLU`).
Sample k (from 0) covers ``(t0 + k dt, t0 + (k+1) dt]`` and is stamped at its end.
"""
from dataclasses import dataclass

import numpy as np

from ..nav.frames import C_RFU_TO_FLU
from ..units import ARCSEC, DEG


class PsinsFormatError(ValueError):
    """The file is not a readable PSINS .imu log; the message says where and why."""


@dataclass
class PsinsLog:
    """A PSINS recording in package conventions.

    ``t`` (N,) end stamps (s, the file's time base); ``dtheta``, ``dv`` (N, 3) FLU
    increments; ``att0_psins`` (3,) the file's initial ``[pitch, roll, yaw]`` (rad,
    PSINS convention, "maybe inaccurate"); ``vel0`` (3,) ENU; ``pos0`` (3,) lat, lon
    (rad), h (m); ``t0``, ``dt`` (s); ``g`` (m/s^2).
    """

    t: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    att0_psins: np.ndarray
    vel0: np.ndarray
    pos0: np.ndarray
    t0: float
    dt: float
    g: float


def read_psins(path):
    """Read a PSINS ``.imu`` file; raises :class:`PsinsFormatError` with a one-line reason."""
    try:
        with open(path) as f:
            lines = [(i + 1, ln) for i, ln in enumerate(f)
                     if ln.strip() and not ln.lstrip().startswith('%')]
    except (OSError, UnicodeDecodeError) as exc:
        raise PsinsFormatError(f'{path}: cannot read: {exc}') from None
    if len(lines) < 4:
        raise PsinsFormatError(f'{path}: fewer than 4 data lines (header of 3 lines + samples)')

    def floats(k, n):
        lineno, text = lines[k]
        try:
            vals = [float(v) for v in text.split()]
        except ValueError:
            raise PsinsFormatError(
                f'{path}:{lineno}: not numeric: {text.strip()[:60]!r}') from None
        if len(vals) != n:
            raise PsinsFormatError(f'{path}:{lineno}: expected {n} numbers, got {len(vals)}')
        return np.array(vals)

    head1, head2, scale = floats(0, 6), floats(1, 6), floats(2, 6)
    t0, dt_ms, g = head2[3], head2[4], head2[5]
    if not dt_ms > 0 or not g > 0:
        raise PsinsFormatError(f'{path}:{lines[1][0]}: sample interval and g must be > 0')
    body = ''.join(text for _, text in lines[3:])
    try:
        counts = np.array(body.split(), dtype=float)
    except ValueError:
        bad = next((ln for ln, text in lines[3:] if not _numeric(text)), '?')
        raise PsinsFormatError(f'{path}:{bad}: non-numeric sample line') from None
    if counts.size % 6:
        raise PsinsFormatError(f'{path}: {counts.size} sample values is not a multiple of 6 '
                               f'(truncated or corrupt last line)')
    counts = counts.reshape(-1, 6)
    dt = dt_ms * 1e-3
    dtheta_rfu = counts[:, :3] * scale[:3] * ARCSEC
    dv_rfu = counts[:, 3:] * scale[3:] * 1e-6 * g
    n = len(counts)
    return PsinsLog(t=t0 + dt * np.arange(1, n + 1), dtheta=dtheta_rfu @ C_RFU_TO_FLU.T,
                    dv=dv_rfu @ C_RFU_TO_FLU.T, att0_psins=head1[:3] * DEG,
                    vel0=head1[3:], pos0=np.array([head2[0] * DEG, head2[1] * DEG, head2[2]]),
                    t0=t0, dt=dt, g=g)


def _numeric(text):
    try:
        [float(v) for v in text.split()]
        return True
    except ValueError:
        return False

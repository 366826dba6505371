"""Whether GNSS shows the base moving, and the filter ``fine_filter: auto`` runs then.

An IMU cannot see a constant velocity, so motion is judged from GNSS: the largest
horizontal speed over a span of stamps against ``motion_speed_mps`` (and four times the
velocity's noise). A stationary (zero-velocity) filter must never run on a moving base:
``auto`` picks ``auto_moving_filter`` there and ``auto_still_filter`` at rest or
without GNSS; a stationary filter chosen by name refuses to start on a moving base, and
one that is running restarts when the base starts moving.

Without GNSS the IMU alone can still tell a vehicle that drives from a base at rest or
swaying (:func:`imu_translation`): a drive accelerates and turns in one direction, so
the specific force integrated in the initial body frame leaves a smooth (quadratic)
curve by metres per second, or the body turns by tens of degrees, where sway and
disturbance give centimetres per second and a few degrees (a constant velocity stays
invisible). Then no filter can align without GNSS, and the pipeline says so.
"""
import math

import numpy as np

from ..nav.coarse import body_attitude_increments

#: the integrated specific force departs from a quadratic in time by more than this, m/s
DRIVE_DV_MPS = 1.0
#: the body turns by more than this over the window, rad
DRIVE_TURN_RAD = math.radians(30.0)
#: what a moving base without GNSS is told
NEEDS_GNSS = ('the IMU shows the base moving (it {what}) and there is no GNSS: a moving base '
              'cannot be aligned without GNSS (publish gnss/fix, and gnss/vel if you have it) '
              'or an external heading; coarse alignment starts again')


def gnss_motion(gnss, cfg, tt):
    """Return ``(moving, speed)`` over stamps ``tt`` (``speed`` m/s, None without GNSS).

    ``gnss`` is the :class:`~.gnss_buffer.GnssBuffer`, ``cfg`` the parameter values.
    """
    speed, v_sig = gnss.speed_over(tt, cfg['gnss_vel_sigma_mps'], cfg['gnss_pos_sigma_m'])
    return speed is not None and speed > max(cfg['motion_speed_mps'], 4.0 * v_sig), speed


def choose_filter(cfg, moving):
    """Return the fine filter to run: ``cfg['fine_filter']``, or ``auto`` resolved."""
    if cfg['fine_filter'] != 'auto':
        return cfg['fine_filter']
    return cfg['auto_moving_filter' if moving else 'auto_still_filter']


def refusal(speed, fine_filter, what):
    """Return the reason a stationary filter gives when GNSS shows the base moving."""
    return (f'GNSS shows the base moving at {speed:.1f} m/s: the stationary filter '
            f'{fine_filter} {what}')


def cannot_start(fine_filter, aided, moving, speed, window):
    """Return why no fine filter can start at the end of the coarse ``window``, or None.

    A stationary filter on a base GNSS shows ``moving`` (at ``speed``); any filter on
    a base the IMU shows driving when there is no GNSS (``speed`` None).
    """
    if moving and not aided:
        return refusal(speed, fine_filter, 'cannot align it (use fine_filter auto or a '
                       'GNSS-aided filter)')
    drive = None if speed is not None else imu_translation(window)
    return None if drive is None else NEEDS_GNSS.format(what=drive)


def imu_translation(window):
    """Return what the coarse ``window`` (t, dtheta, dv, dt) shows of a drive, or None.

    ``'changes its velocity by X m/s'`` when the specific force integrated in the initial body
    frame departs from its best quadratic in time (gravity turning with the Earth and
    with a gyro bias, and a constant tilt, are quadratic) by more than
    :data:`DRIVE_DV_MPS`; ``'turns by X deg'`` when the body turns by more than
    :data:`DRIVE_TURN_RAD`; None otherwise.
    """
    tt, dth, dvv, dts = window
    if len(tt) < 10:
        return None
    C = body_attitude_increments(dth)
    turn = math.acos(max(-1.0, min(1.0, (np.trace(C[-1]) - 1.0) / 2.0)))
    C_prev = np.concatenate([np.eye(3)[None], C[:-1]])
    V = np.cumsum(np.einsum('kij,kj->ki', C_prev, dvv), axis=0)
    t = tt - tt[0]
    A = np.column_stack([np.ones_like(t), t, t * t])
    coef, *_ = np.linalg.lstsq(A, V, rcond=None)
    dev = float(np.max(np.linalg.norm(V - A @ coef, axis=1)))
    if dev > DRIVE_DV_MPS:
        return f'changes its velocity by {dev:.1f} m/s'
    if turn > DRIVE_TURN_RAD:
        return f'turns by {math.degrees(turn):.0f} deg'
    return None

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

A base that rests and then drives (a car at a traffic light, a robot waiting for its
mission) need not wait out the coarse window once it moves (issue 46): :class:`Onset`
keeps when GNSS first showed the motion, and the window ends ``coarse_motion_s`` seconds
after it, and not before it has lasted ``coarse_min_duration`` (the sensor self-check
reads that much, as on a still base). The moving-base coarse alignment then takes its
heading from those seconds (the GNSS track once faster than ``track_min_speed_mps``, else
the inertial-frame fit of the GNSS velocity change) and the GNSS-aided filter, run over
the window from its first sample (``coarse_reprocess_aided``), finds the rest in the
manoeuvres that follow. A base moving from the start ends its window so after
``coarse_min_duration`` too, where its gyro finds north (tactical grade or better); a MEMS
IMU keeps the whole ``coarse_duration``
(:meth:`~..stages.coarse_window.CoarseWindow.refuse_short_end`, which says why). Until
session 52 every such window lasted ``coarse_duration``; the filter, run over the window
from its start, held the same estimate at 60 s either way, only published 40 s later (the
navigation-grade ship under way, the USV, the tactical flight: first published at 20 s;
bench/results/time_to_align.md).
"""
import math
from dataclasses import dataclass

import numpy as np

from ...nav.coarse import velocity_integral_b0

#: spans (s) over which a running filter's watch judges the fixes' track (:func:`watch`)
TRACK_S = (30.0,)
#: the integrated specific force departs from a quadratic in time by more than this, m/s
DRIVE_DV_MPS = 1.0
#: the body turns by more than this over the window, rad
DRIVE_TURN_RAD = math.radians(30.0)
#: what a moving base without GNSS is told
NEEDS_GNSS = ('the IMU shows the base moving (it {what}) and there is no GNSS: a moving base '
              'cannot be aligned without GNSS (publish gnss/fix, and gnss/vel if you have it) '
              'or an external heading; coarse alignment starts again')


def gnss_motion(gnss, cfg, tt, arm_speed=0.0, track_s=(), arm_m=0.0):
    """Return ``(moving, speed)`` over stamps ``tt`` (``speed`` m/s, None without GNSS).

    ``gnss`` is the :class:`~.gnss_buffer.GnssBuffer`, ``cfg`` the parameter values;
    ``arm_speed`` (m/s) the largest speed of the GNSS antenna about the IMU over the span
    (a lever arm on a rolling mast): the IMU moves at least ``speed - arm_speed``, and
    that is what is judged (and returned).

    ``track_s``: spans (s) ending at ``tt[-1]`` over which the fixes' track is judged too
    (:meth:`~.gnss_buffer.GnssBuffer.track_speed`) where the speed over ``tt`` does not
    show motion: a speed from positions over a few epochs is too noisy to see a robot at
    1 m/s behind a consumer receiver (1.5 m: 4 sigma is 2.8 m/s at 2.5 Hz), the slope over
    10 s is not (0.5 m/s, its time-correlated wander counted: the configured
    ``gnss_position_markov_sigma_m``, else the position sigma itself; the fixes' scatter
    about their line where it exceeds the configured sigma). The antenna's swing about
    the IMU, at most twice the lever arm ``arm_m`` (m) over a span, is taken off.
    """
    sigmas = gnss.sigmas_over(tt, cfg)
    speed, v_sig = gnss.speed_over(tt, *sigmas)
    if speed is not None:
        speed = max(speed - arm_speed, 0.0)
        if speed > max(cfg['motion_speed_mps'], 4.0 * v_sig):
            return True, speed
    for span in track_s:
        v, sig, k = gnss.track_speed(tt[-1], span, sigmas[1],
                                     cfg['gnss_position_markov_sigma_m'],
                                     cfg['gnss_position_markov_tau_s'])
        if v is None:
            continue
        v = max(v - 2.0 * arm_m / span, 0.0)
        if v > max(cfg['motion_speed_mps'], k * sig):
            return True, v
        speed = v if speed is None else max(speed, v)
    return False, speed


def choose_filter(cfg, moving):
    """Return the fine filter to run: ``cfg['fine_filter']``, or ``auto`` resolved."""
    if cfg['fine_filter'] != 'auto':
        return cfg['fine_filter']
    return cfg['auto_moving_filter' if moving else 'auto_still_filter']


def watch(gnss, cfg, t, aided, heading_known, arm_speed=0.0, arm_m=0.0):
    """Return why a running filter must restart now that GNSS shows motion, or None.

    A stationary filter cannot take motion; an aided filter started at rest without a
    heading (a gyro that cannot find north) restarts so that its coarse stage takes the
    heading from the GNSS track. ``t``: the stamp of the latest GNSS message; ``arm_speed``
    and ``arm_m`` as :func:`gnss_motion`'s; the fixes' track over :data:`TRACK_S` is
    judged too.
    """
    if aided and heading_known:
        return None
    moving, speed = gnss_motion(gnss, cfg, np.array([t - 3.0, t]), arm_speed, TRACK_S, arm_m)
    if not moving:
        return None
    if not aided:
        return refusal(speed, cfg['fine_filter'], 'no longer holds')
    return f'GNSS shows the base moving at {speed:.1f} m/s: the heading becomes observable'


def refusal(speed, fine_filter, what):
    """Return the reason a stationary filter gives when GNSS shows the base moving."""
    return (f'GNSS shows the base moving at {speed:.1f} m/s: the stationary filter '
            f'{fine_filter} {what}')


@dataclass
class Motion:
    """What the coarse window shows of motion.

    ``gnss``: GNSS shows the base moving; ``speed`` its largest horizontal speed (m/s,
    None without GNSS); ``drive``: what the IMU shows of a drive (:func:`imu_translation`)
    or None.
    """

    gnss: bool
    speed: float
    drive: str

    @property
    def moving(self):
        """Tell whether the base moves: GNSS says so, or GNSS is there and the IMU drives.

        (A robot crawling below ``motion_speed_mps`` still accelerates and turns.)
        """
        return self.gnss or (self.speed is not None and self.drive is not None)


def judge(gnss, cfg, window, install=None):
    """Return the :class:`Motion` of the coarse ``window`` (t, dtheta, dv, dt).

    ``install``: the :class:`~.installation.Installation`, whose lever arm's speed over
    the window is taken off the GNSS speed (:func:`gnss_motion`). The fixes' track over
    the whole window is judged too.
    """
    arm = 0.0 if install is None else install.speed_bound(window[1] / window[3][:, None])
    tt = window[0]
    moving, speed = gnss_motion(gnss, cfg, tt, arm, (float(tt[-1] - tt[0]),),
                                0.0 if install is None else install.arm_m)
    return Motion(moving, speed, None if moving else imu_translation(window))


def cannot_start(fine_filter, aided, m):
    """Return why no fine filter can start after a coarse window of motion ``m``, or None.

    A stationary filter on a moving base; any filter on a base the IMU shows driving
    when there is no GNSS.
    """
    if m.moving and not aided:
        if m.gnss:
            return refusal(m.speed, fine_filter, 'cannot align it (use fine_filter auto or a '
                           'GNSS-aided filter)')
        return (f'the IMU shows the base moving (it {m.drive}): the stationary filter '
                f'{fine_filter} cannot align it (use fine_filter auto or a GNSS-aided filter)')
    if m.speed is None and m.drive is not None:
        return NEEDS_GNSS.format(what=m.drive)
    return None


def imu_translation(window):
    """Return what the coarse ``window`` (t, dtheta, dv, dt) shows of a drive, or None.

    ``'changes its velocity by X m/s'`` when the specific force integrated in the initial body
    frame departs from its best quadratic in time (gravity turning with the Earth and
    with a gyro bias, and a constant tilt, are quadratic) by more than
    :data:`DRIVE_DV_MPS`; ``'turns by X deg'`` when the body turns away from its
    first attitude by more than :data:`DRIVE_TURN_RAD` at some time in the window;
    None otherwise.
    """
    tt, dth, dvv, dts = window
    if len(tt) < 10:
        return None
    C, V = velocity_integral_b0(dth, dvv)
    cos_turn = (np.trace(C, axis1=1, axis2=2) - 1.0) / 2.0
    turn = float(np.max(np.arccos(np.clip(cos_turn, -1.0, 1.0))))
    t = tt - tt[0]
    A = np.column_stack([np.ones_like(t), t, t * t])
    coef, *_ = np.linalg.lstsq(A, V, rcond=None)
    dev = float(np.max(np.linalg.norm(V - A @ coef, axis=1)))
    if dev > DRIVE_DV_MPS:
        return f'changes its velocity by {dev:.1f} m/s'
    if turn > DRIVE_TURN_RAD:
        return f'turns by {math.degrees(turn):.0f} deg'
    return None


class Onset:
    """When GNSS first showed the base moving in the current coarse window (module docstring).

    Decided by the GNSS messages in their order alone, so that the replay's blocks and the
    node's single samples end the window at the same sample: a motion that has lasted
    ``coarse_motion_s`` is latched (a later stop does not undo an end already due).
    """

    def __init__(self):
        #: stamp of the first GNSS message of the motion (s), None at rest
        self.t = None

    def fix(self, gnss, cfg, t):
        """Take the GNSS message at ``t``: motion over its last second starts or ends the onset."""
        moving, _ = gnss_motion(gnss, cfg, np.array([t - 1.0, t]))
        if moving:
            if self.t is None:
                self.t = float(t)
        elif self.t is not None and t < self.t + cfg['coarse_motion_s']:
            self.t = None

    def window_end(self, cfg, t_first):
        """Return the stamp at which the coarse window begun at ``t_first`` ends early, or None.

        ``coarse_motion_s`` after the onset, at the earliest ``coarse_min_duration`` after
        ``t_first``; None without an onset or with ``coarse_motion_s`` 0.
        """
        s, need = self.t, cfg['coarse_motion_s']
        if s is None or not need > 0.0:
            return None
        return max(s + need, t_first + cfg['coarse_min_duration'])

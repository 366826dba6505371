"""Whether GNSS shows the base moving, and the filter ``fine_filter: auto`` runs then.

An IMU cannot see a constant velocity, so motion is judged from GNSS: the largest
horizontal speed over a span of stamps against ``motion_speed_mps`` (and four times the
velocity's noise). A stationary (zero-velocity) filter must never run on a moving base:
``auto`` picks ``auto_moving_filter`` there and ``auto_still_filter`` at rest or
without GNSS; a stationary filter chosen by name refuses to start on a moving base, and
one that is running restarts when the base starts moving.
"""


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

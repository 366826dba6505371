"""Sensor self-check: the configured sensor model against what the coarse window shows.

A sigma we publish is only as honest as the sensor model behind it, and most users
keep the defaults (a navigation-grade IMU) whatever IMU they carry. So before the
fine filter starts, the coarse window is checked against the model, and where the
data contradict it the model is widened to what the data show (never narrowed) and
the finding is reported. :func:`check` runs the checks in this order:

* the GNSS noise, the GNSS lever arm and the velocity jitter, where GNSS comes
  (:mod:`.gnss_noise_check`);
* the mounting (below);
* the white noise and the grade it shows (:mod:`.grade_check`, measured by
  :mod:`.noise_estimates`); on a moving base nothing more but the heading;
* at rest, the base velocity (below), and on a still base the bias bounds
  (:mod:`.bias_bounds`) with the latitude estimate where the latitude is not known
  (:mod:`.latitude_estimate`);
* heading observability (below).

* **Base velocity at rest** (the zero-velocity measurement): the specific force
  integrated in the initial body frame, levelled, less its best quadratic over each
  :data:`VELOCITY_CHUNK_S` seconds, is the velocity the base really has (sway, heave,
  people walking on it) plus a little sensor random walk (the vertical is each piece's own
  mean specific force). Left to the data (``zero_velocity_sigma`` 0, the default), the
  zero-velocity sigma is this RMS with a margin (:data:`READ_MARGIN`, at least
  :data:`ZERO_VELOCITY_FLOOR`): the default 0.01 m/s of sessions before 53 was 30-100 times
  what a moored ship or a still base shows, and kept the moored ship's heading sigma at
  3-7 times the accelerometers' limit over its first 40 s. A configured sigma is a claim,
  widened only: the RMS widens ``zero_velocity_sigma`` when more than
  :data:`~.noise_estimates.NOISE_RATIO` times larger (horizontal; the vertical one widens
  ``zero_velocity_sigma_up`` for ``stationary12``, which measures the vertical velocity: a
  moored ship's 0.5 m heave moves it at 0.5 m/s).
* **Mounting** (the vehicle frame is near level): the window's mean specific force, in the
  vehicle frame the told ``imu_mounting_rpy_deg`` gives, points within
  ``mounting_check_max_tilt_deg`` (45 deg) of up on any vehicle at rest or under way (a
  sailing boat heels 30 deg, a steep road is 17 deg; sway and accelerations average out
  over the window). Beyond it the IMU is mounted rotated and the mounting was not told
  (robot_localization's test robot reads 90 deg): the attitude found is the IMU's, not
  ``base_link``'s, and nothing in the data says how the two differ about the vertical.
  The finding says so, with the roll and pitch a level vehicle would give the mounting;
  the fine stage then publishes roll, pitch and heading as unknown and is never
  ``aligned`` (:attr:`SelfCheck.mounting_doubt`). A mounting turned about the vertical
  only is not seen here; under way the GNSS velocity shows it (:mod:`.sideslip`).
* **Heading observability**: a gyro whose bias sigma (after widening) is not small
  against the horizontal Earth rate cannot find north at rest; the result says so
  and the stationary filters publish the heading as unknown.

Not in the seeds; it is what makes the published sigma a claim that holds with a
wrong or default sensor model.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from ...nav import earth
from ...nav.coarse import detect_motion, velocity_integral_b0
from ...units import DPSH, UG
from .angle_walk import walk_density
from .bias_bounds import _biases, _gyro_bias_sigma
from .gnss_noise_check import gnss_check
from .grade_check import ACCEL_VRW_BY_GYRO_NOISE, _class_value, _noise
from .latitude_estimate import _latitude_unknown
from .noise_estimates import NOISE_RATIO, coherent, difference_density, white_density
from ..params import ZERO_VELOCITY_UNREAD

#: seconds of the pieces :func:`base_velocity_rms` fits a quadratic to
VELOCITY_CHUNK_S = 10.0
#: a zero-velocity sigma read from the data is the measured RMS times this, an upper
#: confidence bound: over the shortest window (20 s: two pieces, two axes) the RMS of a
#: random walk less its quadratic falls under 1/1.24 of its expectation in 5 % of draws and
#: under 1/1.35 in 1 % (4000 seeded draws); a sway's RMS, near a sinusoid's, scatters less
READ_MARGIN = 1.5
#: the least zero-velocity sigma read from the data (m/s): a still base's own figure is
#: the accelerometers' random walk (navigation grade 0.06 mm/s), which the filter carries
#: as process noise already. Below this the moored ship's heading error stops shrinking
#: while its sigma does not: over 40 seeds at 20 s, 16.7' RMS under a 16.6' sigma at
#: 3e-4 m/s, 16.5' under 13.8' at 1e-4 (without heave too; what the model leaves out at
#: that level is not traced)
ZERO_VELOCITY_FLOOR = 3e-4
#: a gyro bias sigma above this fraction of the horizontal Earth rate: no heading at rest
HEADING_BIAS_FRACTION = 0.5
#: the heading warning when the latitude is unknown
NO_HEADING_LATITUDE = ('heading unobservable: the latitude is unknown (initial_latitude_deg '
                       'not set, no GNSS fix, and the gyros cannot estimate it), so north '
                       'cannot be found at rest; heading published as unknown (set '
                       'initial_latitude_deg, or give a GNSS fix or an external heading)')
#: the reason given when the heading cannot be found at rest
NO_HEADING = ('heading unobservable: the gyro bias is not small against the horizontal Earth '
              'rate, so this IMU cannot find north at rest (needs motion with GNSS aiding, '
              'or an external heading); heading published as unknown')
#: the same for a GNSS-aided filter started at rest
NO_HEADING_YET = ('heading unobservable at rest: the gyro bias is not small against the '
                  'horizontal Earth rate; heading published as unknown until GNSS shows the '
                  'base moving (then alignment restarts from coarse, with the GNSS track)')


def heading_warning(check, at_rest, aided):
    """Return the warning a failed Earth-rate check gives, or None.

    Only where the gyro would have to find north: at rest, or for a stationary filter.
    ``aided``: a GNSS-aided filter, whose heading motion may still make observable later.
    With the latitude unknown the warning says so, not that the gyro is too poor (unless
    it is that too).
    """
    if check.heading_observable or not (at_rest or not aided):
        return None
    if check.latitude_unknown:
        return NO_HEADING_LATITUDE + ('' if check.gyro_finds_north else
                                      '; the gyro bias is not small against the Earth rate '
                                      'either')
    return NO_HEADING_YET if aided else NO_HEADING


@dataclass
class SelfCheck:
    """Outcome of :func:`check`.

    ``widened``: parameter name -> new value (datasheet units) where the data contradict
    the configured model; ``read``: the same where the parameter was left to the data (the
    zero-velocity sigmas, 0), said in ``note``; ``unread``: those the stage takes where it
    does not use ``read`` (``params.ZERO_VELOCITY_UNREAD`` widened as a configured figure
    would be: where absent, that figure); ``findings``: one sentence per widened
    parameter (warnings); ``note``: which checks were skipped and why (informational);
    ``at_rest``: nothing says the base moves (as given); ``still``: the window shows no
    motion either; ``heading_observable``: the gyro can find north at rest;
    ``mounting_doubt``: why the
    vehicle frame cannot be the told one (the mounting check; '' when it can be);
    ``latitude``: ``(lat, sigma)`` rad estimated from the gyros when the latitude was not
    set (None otherwise); ``latitude_unknown``: it was not set and could not be estimated
    (0 used, heading unobservable); ``gyro_finds_north``: the gyro bias alone allows north
    at rest; ``figures``: the measured bounds for diagnostics.
    """

    widened: dict = field(default_factory=dict)
    read: dict = field(default_factory=dict)
    unread: dict = field(default_factory=dict)
    findings: list = field(default_factory=list)
    note: str = ''
    at_rest: bool = True
    still: bool = True
    heading_observable: bool = True
    mounting_doubt: str = ''
    latitude: tuple = None
    latitude_unknown: bool = False
    gyro_finds_north: bool = True
    figures: dict = field(default_factory=dict)


def base_velocity_rms(dth, dvv, dts):
    """RMS (m/s) of the base's horizontal and vertical velocity over a window at rest.

    See the module docstring; ``(nan, nan)`` with less than one piece of data.
    """
    m = int(round(VELOCITY_CHUNK_S / float(np.mean(dts))))
    k = len(dth) // m
    if k < 1:
        return float('nan'), float('nan')
    V = velocity_integral_b0(dth, dvv)[1][:k * m].reshape(k, m, 3)
    t = np.cumsum(dts[:m]) - dts[0]
    A = np.column_stack([np.ones(m), t, t * t])
    # the quadratic fit of each chunk, A (A^+ V): the projector A A^+ itself is (m, m), and
    # applying it cost m^2 per chunk (3 s of a 1 kHz IMU's coarse end, bench/scaling.py)
    coef = np.einsum('ij,kjl->kil', np.linalg.pinv(A), V)
    res = V - np.einsum('ij,kjl->kil', A, coef)
    # each piece's own vertical, its mean specific force: b0 is inertial, so the local
    # vertical turns in it with the Earth (0.25 deg a minute), and against the window's
    # mean vertical a moored ship's 0.35 m/s heave leaked 0.4 mm/s into the horizontal
    up = coef[:, 1, :] + coef[:, 2, :] * t[-1]
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    vert = np.einsum('kjl,kl->kj', res, up)
    horiz = res - vert[..., None] * up[:, None, :]
    return (math.sqrt(float(np.mean(np.sum(horiz * horiz, axis=-1))) / 2.0),
            math.sqrt(float(np.mean(vert * vert))))


def check(window, position, cfg, at_rest=True, gnss=None):
    """Check the coarse window ``(t, dtheta, dv, dt)`` against the sensor model in ``cfg``.

    ``position`` (3,) rad, rad, m; ``at_rest``: nothing says the base moves (no GNSS
    speed; an IMU cannot see a constant velocity, and on a moving base the transport
    rate and Coriolis terms would read as biases); ``gnss``: the
    :class:`~.gnss_buffer.GnssBuffer` whose fixes in the window are checked (or None).
    Where the latitude is not known (``gnss`` given and ``initial_latitude_deg`` not set,
    no fix: ``GnssBuffer.latitude_known``) and the gyros estimate it, the estimate is written
    into ``position[0]`` (a numpy array) for the stages that follow.
    Returns a :class:`SelfCheck`.
    """
    tt, dth, dvv, dts = window
    dt = float(np.mean(dts))
    T = float(np.sum(dts))
    lat, _, h = position
    out = SelfCheck()
    lat_known = gnss is None or gnss.latitude_known(cfg)
    w = dth / dts[:, None]
    f = dvv / dts[:, None]
    if gnss is not None:
        gnss_check(out, gnss, tt[0] - dts[0], tt[-1], cfg, window)
    _mounting(out, cfg, dvv.sum(axis=0) / T)
    if not at_rest:
        out.at_rest = out.still = False
        arw = difference_density(w, dt)
        # the accelerometer's high-frequency content on a moving base is mostly vibration,
        # which averages out over a GNSS interval: count at most the white noise of IMUs
        # of the class the gyro noise shows
        vrw_cap = _class_value(ACCEL_VRW_BY_GYRO_NOISE, arw / DPSH) * UG
        _noise(out, cfg, arw, min(difference_density(f, dt), vrw_cap), moving=True,
               walk=walk_density(dth, dts))
        out.note = ('bias bounds skipped: GNSS shows the base moving, or a moving-base filter '
                    'runs without GNSS (white noise from third differences of the samples)')
        if not lat_known:
            _latitude_unknown(out, 'the base moves')
        return _heading(out, cfg, lat)
    # where sway makes the 1-s scatter disagree with the sample-level one, the third
    # differences still bound the white noise (a swaying ship at the quay), unless the
    # gyro and accelerometer differences move together: then they are the base's
    # disturbance (people, wind, engines), not sensor noise
    arw, vrw = white_density(w, dt), white_density(f, dt)
    if not (math.isfinite(arw) and math.isfinite(vrw)):
        if coherent(dth, dvv):
            out.note = ('noise check skipped: the sample-level scatter is the base\'s '
                        'disturbance (gyro and accelerometer move together), not sensor noise')
        else:
            arw = arw if math.isfinite(arw) else difference_density(w, dt)
            vrw = vrw if math.isfinite(vrw) else difference_density(f, dt)
    arw, vrw = _noise(out, cfg, arw, vrw, moving=False)
    out.still = not detect_motion(dth, dvv, dts, arw, vrw)[0]
    _base_velocity(out, cfg, dth, dvv, dts)
    if out.still:
        lat = _biases(out, dth.sum(axis=0) / T, dvv.sum(axis=0) / T, T,
                      lat if lat_known else None, h, cfg, arw, vrw)
        if out.latitude is not None and isinstance(position, np.ndarray):
            position[0] = lat
    else:
        out.note = '; '.join(n for n in (out.note, 'bias bounds skipped: the base moves '
                                         '(sways) in the coarse window') if n)
        if not lat_known:
            _latitude_unknown(out, 'the base sways or moves in the coarse window')
    return _heading(out, cfg, lat)


def _base_velocity(out, cfg, dth, dvv, dts):
    """Read or widen the zero-velocity sigmas from the velocity the base shows at rest.

    A sigma left to the data (``zero_velocity_sigma`` 0, the default) is read: the
    measured RMS times :data:`READ_MARGIN`, at least :data:`ZERO_VELOCITY_FLOOR`
    (``out.read``, an informational note). A configured sigma is the user's claim, widened
    only: the horizontal RMS widens ``zero_velocity_sigma``; for ``stationary12``, which
    measures the vertical velocity too, the vertical RMS (heave) widens
    ``zero_velocity_sigma_up`` apart from it (one sigma for both gave the horizontal rows,
    which carry the tilt and heading, a moored ship's heave: heading sigma 4-5x its error).
    """
    horiz, vert = base_velocity_rms(dth, dvv, dts)
    out.figures.update(base_velocity_h_mps=horiz, base_velocity_v_mps=vert)
    zv = cfg['zero_velocity_sigma']
    axes = [('zero_velocity_sigma', horiz, zv, 'horizontally')]
    if cfg['fine_filter'] == 'stationary12':
        axes.append(('zero_velocity_sigma_up', vert, cfg['zero_velocity_sigma_up'] or zv,
                     'vertically'))
    for name, v, model, how in axes:
        widen = v > NOISE_RATIO * (model or ZERO_VELOCITY_UNREAD)
        if model == 0.0:
            if math.isfinite(v):
                out.read[name] = max(ZERO_VELOCITY_FLOOR, READ_MARGIN * v)
                out.figures[name + '_read'] = out.read[name]
            if widen:
                out.unread[name] = v
        elif widen:
            out.widened[name] = v
            out.findings.append(f'the base moves {how} at {v:.3g} m/s RMS at rest (sway, heave '
                                f'or disturbance), {name} {model:.3g} m/s configured: widened')
    if out.read:
        out.note = '; '.join(n for n in (out.note, 'zero-velocity sigma read from the base '
                                         'velocity at rest: ' + ', '.join(
                                             f'{k} {v:.2g} m/s' for k, v in out.read.items()))
                             if n)


def _mounting(out, cfg, f_b):
    """Flag an IMU mounted rotated and untold (module docstring); ``f_b`` (3,) mean force."""
    g = float(np.linalg.norm(f_b))
    limit = cfg['mounting_check_max_tilt_deg']
    if not g > 1.0:                          # no gravity to judge by (or no data)
        return
    tilt = math.degrees(math.acos(min(1.0, max(-1.0, f_b[2] / g))))
    out.figures['vehicle_tilt_deg'] = tilt
    if tilt <= limit or limit >= 180.0:
        return
    roll = round(math.degrees(math.atan2(f_b[1], f_b[2])))
    pitch = round(math.degrees(math.atan2(-f_b[0], math.hypot(f_b[1], f_b[2]))))
    told = ', '.join(f'{v:g}' for v in cfg['imu_mounting_rpy_deg'])
    out.mounting_doubt = (
        f'the vehicle frame is tilted {tilt:.0f} deg in the coarse window (roll {roll}, '
        f'pitch {pitch} deg; mounting_check_max_tilt_deg {limit:g}): the IMU is probably '
        f'mounted rotated and imu_mounting_rpy_deg [{told}] is not its mounting, so the '
        'attitude found is not base_link\'s: roll, pitch and heading published as unknown, '
        'never aligned. Set imu_mounting_rpy_deg (for a level vehicle its roll and pitch are '
        f'about [{roll}, {pitch}], its yaw not seen here), or raise '
        'mounting_check_max_tilt_deg if the vehicle really is this tilted')
    out.findings.append(out.mounting_doubt)


def _heading(out, cfg, lat):
    """Set ``out.heading_observable`` from the (widened) gyro bias sigma; return ``out``.

    An unknown latitude makes the heading unobservable as well.
    """
    gyro_sigma = _gyro_bias_sigma(out, cfg)
    out.gyro_finds_north = bool(
        gyro_sigma <= HEADING_BIAS_FRACTION * earth.OMEGA_IE * math.cos(lat))
    out.heading_observable = out.gyro_finds_north and not out.latitude_unknown
    return out

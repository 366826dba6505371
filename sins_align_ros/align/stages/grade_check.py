"""The IMU's white noise against the configured model, and the grade that noise shows.

Part of the sensor self-check (:mod:`.self_check`), which measures the noise
(:mod:`.noise_estimates`) and hands it to :func:`_noise`:

* **White noise** (Allan-style): for white noise the Allan variance of the 1-s means of
  the rate and the specific force is ARW^2 / 1 s (VRW^2 / 1 s), and the variance of
  sample-to-sample differences is 2 ARW^2 / dt. Each is inflated by something else:
  base motion and sway (low frequencies) inflate the first, quantization and vibration
  (high frequencies) the second. Only where the two agree (within
  :data:`~.noise_estimates.WHITE_AGREE`) is the noise evidently white; then their
  geometric mean widens the configured density when it is more than
  :data:`~.noise_estimates.NOISE_RATIO` times larger. Where they disagree (sway at the
  quay inflates the 1-s scatter), the third differences below bound it.
* **White noise on a moving base**: the 1-s scatter is the motion's, but motion is
  smooth at the sample level, so the third differences of the samples (whose variance
  is 20 sigma^2 for white noise; a smooth motion's third difference falls as (w dt)^3)
  still show the noise: :func:`~.noise_estimates.difference_density`. Vibration and
  quantization add to it, so it is an upper bound, used only to widen (by the same rule),
  never to narrow.
  The grade is judged by it; ``gyro_arw_dpsh``, which the filters take as a random walk
  of the attitude, is widened only to the smaller of it and the random walk's bound over
  spans of seconds (:func:`~.angle_walk.walk_density`): a vibrating mount's jitter is
  bounded in angle (a skid-steer robot: 37 deg/sqrt(h) at the sample level, at most
  8.5-9.4 over seconds, from a 3 or 0.42 deg/sqrt(h) gyro).
* **Grade**: noise found larger than configured means the IMU is not of the configured
  grade, and its biases are then larger too; the bias sigmas are raised to at least
  :data:`GYRO_BIAS_PER_ARW` (:data:`GYRO_BIAS_PER_ARW_NAVIGATION` for a gyro of the
  navigation class) / :data:`ACCEL_BIAS_PER_VRW` times the measured noise, and
  the gyro bias instability to :data:`GYRO_INSTABILITY_PER_ARW` times it (near
  the upper end of the bias-to-noise ratios of our sensor-grade presets, which span
  10-67 deg/h per deg/sqrt(h) and 6-14 ug per ug/sqrt(Hz)). At rest a horizontal
  accelerometer bias and most of a gyro bias cannot be told from tilt and heading, so
  this is the only check that catches them. The accelerometer bias is also raised to
  the class the *gyro* noise shows (:data:`ACCEL_BIAS_BY_GYRO_NOISE`): on a moving base
  the accelerometer noise is mostly vibration, and at rest a raw industrial AHRS's
  accelerometers have 6-8 mg of bias and 0.5 % misalignment for 120 ug/sqrt(Hz) of noise
  (58x, beyond the 14x of :data:`ACCEL_BIAS_PER_VRW`): session 46 found a car with such
  an IMU, told the node defaults and still for 30 s, publishing its north tilt 61' off under
  a 5.8' sigma from the still-base filter (bench/integrity.py car_still:rtk, mems_ahrs,
  3 runs of 10; the rest rule gave 1.6 mg). The gyro bias instability
  counts the gyro noise at most to :data:`GYRO_NOISE_FOR_INSTABILITY_MOVING` (a vibrating
  chassis's is no sign of a wandering bias).
"""
import math

from ...units import DPSH, UG
from .angle_walk import walk_or_noise
from .noise_estimates import NOISE_RATIO

#: typical bias-to-noise ratios: gyro deg/h per deg/sqrt(h), accelerometer ug per ug/sqrt(Hz)
GYRO_BIAS_PER_ARW = 30.0
ACCEL_BIAS_PER_VRW = 14.0
#: the gyro ratio at rest for a gyro whose noise is of the navigation class (at most the
#: first edge of :data:`ACCEL_BIAS_BY_GYRO_NOISE`, 0.003 deg/sqrt(h)): such gyros have
#: biases of 2-10x their noise (our navigation, marine and USV-high presets 6-10); 30x
#: made the heading sigma of a navigation-grade IMU told 10x too good 3.3x its error
GYRO_BIAS_PER_ARW_NAVIGATION = 15.0
#: the same on a moving base (the upper end of our presets' 10-67)
GYRO_BIAS_PER_ARW_MOVING = 67.0
#: the varying part of the gyro bias (gyro_bias_instability_dph) per deg/sqrt(h) of noise
#: (our presets: 10-20; it keeps a heading learnt in a turn from being trusted for ever)
GYRO_INSTABILITY_PER_ARW = 15.0
#: on a moving base, the most gyro white noise (deg/sqrt(h)) counted for the bias
#: instability: our consumer MEMS preset's 3 (45 deg/h; that preset's is 50). Third
#: differences see a vibrating chassis as noise (robot_skid: 37 deg/sqrt(h) from a 0.42
#: deg/sqrt(h) gyro; ``gyro_arw_dpsh`` takes only its walk over seconds, :mod:`.angle_walk`),
#: which is no sign of a bias that wanders faster; 15 x 37 = 555 deg/h of instability
#: kept the robot's vertical drift from ever being learnt from its straight legs' courses
#: (its sigma still 500 deg/h after 300 s, the heading sigma growing by 1 deg every 8 s
#: between legs while the error held, and published unknown at the end of most runs).
#: The bias itself is still raised by the whole noise (a wide prior costs little under way)
GYRO_NOISE_FOR_INSTABILITY_MOVING = 3.0
#: on a moving base, accelerometer bias floor (ug) by gyro white noise (deg/sqrt(h), upper
#: edge): navigation, tactical, industrial and consumer MEMS classes. The industrial class's
#: is that of an industrial AHRS's raw triads: 6-8 mg of bias and 0.5 % misalignment under
#: gravity, 9 mg in all (issue 44; it was 2000 ug, a calibrated unit's, and car_consumer
#: with node defaults put its tilt 0.3 deg off under a 0.06 deg sigma); the consumer
#: class's is our MEMS preset's (unchanged: its cars were not silent-wrong)
ACCEL_BIAS_BY_GYRO_NOISE = ((0.003, 100.0), (0.15, 500.0), (0.6, 9000.0), (math.inf, 5000.0))
#: on a moving base, the gyro bias floor (deg/h) by the same classes (0: none; the bias is
#: raised to :data:`GYRO_BIAS_PER_ARW_MOVING` x the noise in any case): an industrial AHRS's
#: raw gyros have a turn-on bias of about 400 deg/h (issue 44) for a noise of 0.42
#: deg/sqrt(h), where 67 x the noise told the filter 28 deg/h. The consumer class keeps
#: 67 x its noise (200 deg/h at 3 deg/sqrt(h), our MEMS preset's; a 500 deg/h floor there
#: took the real fog_mems car's heading with node defaults from 4.2 to 4.8 deg RMS)
GYRO_BIAS_BY_GYRO_NOISE_MOVING = ((0.003, 0.0), (0.15, 0.0), (0.6, 500.0), (math.inf, 0.0))
#: on a moving base, the gyro scale-factor and misalignment sigmas (ppm) by gyro white noise
#: (the same classes): MEMS triads (industrial and consumer) that no one calibrated have
#: scale factors of 1-3 % and axis misalignment of about 0.5 % (issue 44); the navigation
#: and tactical classes' are left to the user (0 by default: their cells unchanged)
SCALE_BY_GYRO_NOISE = ((0.003, (0.0, 0.0)), (0.15, (0.0, 0.0)), (0.6, (20000.0, 5000.0)),
                       (math.inf, (20000.0, 5000.0)))
#: the same for the accelerometer triad (ppm): raw MEMS triads have scale factors of
#: 0.3-0.5 % and axis misalignment of 0.5 % (issue 44); :mod:`.force_error` models them
ACCEL_SCALE_BY_GYRO_NOISE = ((0.003, (0.0, 0.0)), (0.15, (0.0, 0.0)), (0.6, (5000.0, 5000.0)),
                             (math.inf, (5000.0, 5000.0)))
#: on a moving base, the most accelerometer white noise (ug/sqrt(Hz)) counted, by the
#: same gyro classes (vibration above it is not random walk at GNSS intervals)
ACCEL_VRW_BY_GYRO_NOISE = ((0.003, 10.0), (0.15, 80.0), (0.6, 200.0), (math.inf, 350.0))


def _noise(out, cfg, arw, vrw, moving, walk=None):
    """Widen the white noise (and raise the biases) where ``arw``/``vrw`` (SI) exceed the model.

    ``walk`` (rad/sqrt(s), moving base): the bound of the gyro's random walk over seconds
    (:func:`~.angle_walk.walk_density`); ``gyro_arw_dpsh`` is widened to the smaller of it
    and ``arw`` (a vibrating mount's jitter is bounded in angle), while the grade (the
    biases, the scale factors) is judged by ``arw``, the sample-level noise.
    Returns the densities as widened (the configured ones where not), rad/sqrt(s) and
    m/s^2/sqrt(Hz).
    """
    out.figures.update(gyro_noise_dpsh=arw / DPSH, accel_noise_ug_rthz=vrw / UG)
    q = walk_or_noise(walk, arw)
    if walk is not None and math.isfinite(walk):
        out.figures['gyro_walk_dpsh'] = walk / DPSH
    arw_cfg = cfg['gyro_arw_dpsh'] * DPSH
    vrw_cfg = cfg['accel_vrw_ug_rthz'] * UG
    if arw > NOISE_RATIO * arw_cfg:
        if q > NOISE_RATIO * arw_cfg:
            bounded = q < arw
            part = (f', its random walk over seconds at most {q / DPSH:.3g} (the rest bounded '
                    'in angle: vibration)' if bounded else '')
            out.widened['gyro_arw_dpsh'] = q / DPSH
            out.findings.append(f'gyro white noise {arw / DPSH:.3g} deg/sqrt(h) in the data'
                                f'{part}, {cfg["gyro_arw_dpsh"]:.3g} configured: '
                                'gyro_arw_dpsh widened'
                                + (f' to {q / DPSH:.3g}' if bounded else ''))
            arw_cfg = q
        # on a moving base a wide bias prior costs little (GNSS aiding observes the bias
        # through the motion), so take the upper end of the presets' ratios there
        per_arw = GYRO_BIAS_PER_ARW_MOVING if moving else (
            GYRO_BIAS_PER_ARW_NAVIGATION if arw / DPSH <= ACCEL_BIAS_BY_GYRO_NOISE[0][0]
            else GYRO_BIAS_PER_ARW)
        floor = _class_value(GYRO_BIAS_BY_GYRO_NOISE_MOVING, arw / DPSH) if moving else 0.0
        _raise(out, cfg, 'gyro_bias_dph', max(per_arw * arw / DPSH, floor), 'deg/h')
        counted = min(arw / DPSH, GYRO_NOISE_FOR_INSTABILITY_MOVING) if moving else arw / DPSH
        _raise(out, cfg, 'gyro_bias_instability_dph', GYRO_INSTABILITY_PER_ARW * counted,
               'deg/h')
        # at rest too: the accelerometer's own noise undercounts a raw triad's bias, which
        # there is tilt (module docstring)
        _raise(out, cfg, 'accel_bias_ug',
               _class_value(ACCEL_BIAS_BY_GYRO_NOISE, arw / DPSH), 'ug')
    if moving and math.isfinite(arw):    # the scale factors of the gyro's class
        _scale_factors(out, cfg, arw)
    if vrw > NOISE_RATIO * vrw_cfg:
        out.widened['accel_vrw_ug_rthz'] = vrw / UG
        out.findings.append(f'accelerometer white noise {vrw / UG:.3g} ug/sqrt(Hz) in the '
                            f'data, {cfg["accel_vrw_ug_rthz"]:.3g} configured: '
                            'accel_vrw_ug_rthz widened')
        vrw_cfg = vrw
        if not moving:
            _raise(out, cfg, 'accel_bias_ug', ACCEL_BIAS_PER_VRW * vrw / UG, 'ug')
    return arw_cfg, vrw_cfg


#: what a MEMS triad's scale factors and misalignment do, per triad (the finding's words)
_SCALE_EFFECT = {'gyro': 'turn each turn into attitude error',
                 'accel': 'turn each braking, acceleration and turn into velocity error, and '
                          'gravity into a bias'}


def _scale_factors(out, cfg, arw):
    """Raise the scale-factor and misalignment sigmas to the gyro noise's MEMS class (moving).

    Gyro (:mod:`.rotation_error`) and accelerometer (:mod:`.force_error`) alike; never
    narrowed. ``arw`` the gyro white noise, rad/sqrt(s).
    """
    for triad, table in (('gyro', SCALE_BY_GYRO_NOISE), ('accel', ACCEL_SCALE_BY_GYRO_NOISE)):
        for name, value in zip((f'{triad}_scale_factor_ppm', f'{triad}_misalignment_ppm'),
                               _class_value(table, arw / DPSH)):
            if value > _model(out, cfg, name):
                out.findings.append(
                    f'{name} raised from {_model(out, cfg, name):.3g} to {value:.3g} ppm: '
                    f'the gyro noise ({arw / DPSH:.3g} deg/sqrt(h)) is of a MEMS triad, whose '
                    f'scale factors and axis misalignment {_SCALE_EFFECT[triad]}')
                out.widened[name] = value


def _class_value(table, gyro_noise_dpsh):
    """Return the value of ``table`` ((upper edge, value), ...) for a gyro noise (deg/sqrt(h))."""
    if not math.isfinite(gyro_noise_dpsh):
        return math.inf
    return next(v for edge, v in table if gyro_noise_dpsh <= edge)


def _model(out, cfg, name):
    """Return parameter ``name`` of the model as the check has widened it so far."""
    return out.widened.get(name, cfg[name])


def _raise(out, cfg, name, value, unit):
    """Raise bias sigma ``name`` to ``value`` for the grade the noise shows (if larger)."""
    if value > _model(out, cfg, name):
        out.findings.append(f'{name} raised from {_model(out, cfg, name):.3g} to {value:.3g} '
                            f'{unit}: the noise shows an IMU of a lower grade than configured, '
                            'whose biases are larger too')
        out.widened[name] = value

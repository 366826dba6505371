"""Sensor self-check: the configured sensor model against what the coarse window shows.

A sigma we publish is only as honest as the sensor model behind it, and most users
keep the defaults (a navigation-grade IMU) whatever IMU they carry. So before the
fine filter starts, the coarse window is checked against the model, and where the
data contradict it the model is widened to what the data show (never narrowed) and
the finding is reported:

* **White noise** (Allan-style): for white noise the Allan variance of the 1-s means of
  the rate and the specific force is ARW^2 / 1 s (VRW^2 / 1 s), and the variance of
  sample-to-sample differences is 2 ARW^2 / dt. Each is inflated by something else:
  base motion and sway (low frequencies) inflate the first, quantization and vibration
  (high frequencies) the second. Only where the two agree (within :data:`WHITE_AGREE`)
  is the noise evidently white; then their geometric mean widens the configured
  density when it is more than :data:`NOISE_RATIO` times larger. Where they disagree
  (sway at the quay inflates the 1-s scatter), the third differences below bound it.
* **White noise on a moving base**: the 1-s scatter is the motion's, but motion is
  smooth at the sample level, so the third differences of the samples (whose variance
  is 20 sigma^2 for white noise; a smooth motion's third difference falls as (w dt)^3)
  still show the noise: :func:`difference_density`. Vibration and quantization add to
  it, so it is an upper bound, used only to widen (by the same rule), never to narrow.
  The grade is judged by it; ``gyro_arw_dpsh``, which the filters take as a random walk
  of the attitude, is widened only to the smaller of it and the random walk's bound over
  spans of seconds (:func:`~.angle_walk.walk_density`): a vibrating mount's jitter is
  bounded in angle (a skid-steer robot: 37 deg/sqrt(h) at the sample level, at most
  8.5-9.4 over seconds, from a 3 or 0.42 deg/sqrt(h) gyro).
* **Biases on a still base** (the window shows no motion once the noise is right):
  the mean specific force must have the magnitude of normal gravity, so
  ``|f| - g`` is the accelerometer bias along the vertical; the mean rate along the
  measured vertical must be ``W sin(L)`` and its horizontal magnitude ``W cos(L)``, so
  their differences bound the gyro bias. A bound beyond two model sigmas
  (plus what noise, gravity-model and scale-factor errors explain) widens the bias
  sigma to the bound. On a moving base this check is skipped (said so).
* **Grade**: noise found larger than configured means the IMU is not of the configured
  grade, and its biases are then larger too; the bias sigmas are raised to at least
  :data:`GYRO_BIAS_PER_ARW` (:data:`GYRO_BIAS_PER_ARW_NAVIGATION` for a gyro of the
  navigation class) / :data:`ACCEL_BIAS_PER_VRW` times the measured noise, and
  the gyro bias instability to :data:`GYRO_INSTABILITY_PER_ARW` times it (near
  the upper end of the bias-to-noise ratios of our sensor-grade presets, which span
  10-67 deg/h per deg/sqrt(h) and 6-14 ug per ug/sqrt(Hz)). At rest a horizontal
  accelerometer bias and most of a gyro bias cannot be told from tilt and heading, so
  this is the only check that catches them. On a moving base the accelerometer noise
  is mostly vibration, so the accelerometer bias is raised by the grade the *gyro*
  noise shows (:data:`ACCEL_BIAS_BY_GYRO_NOISE`) instead, and the gyro bias instability
  counts the gyro noise at most to :data:`GYRO_NOISE_FOR_INSTABILITY_MOVING` (a vibrating
  chassis's is no sign of a wandering bias).
* **GNSS noise**: the third differences of the fixes in the coarse window (horizontal
  position, height, and the GNSS velocity when it comes) show the receiver's noise the same
  way (a vehicle's jerk hardly enters them at 1-10 Hz); a robust (median) estimate
  ignores the few epochs where a manoeuvre starts. Where it is more than
  :data:`NOISE_RATIO` times the configured (or the receiver's reported) sigma, the
  sigma is widened to it (and reported covariances, then shown to be too small, are
  no longer used). On a still base and on a moving one alike.
* **GNSS lever arm**: the velocities are fitted to the IMU's view of the motion and an
  antenna lever arm (:mod:`.arm_check`); an arm the data show beyond :data:`ARM_CHI2`
  replaces the configured ``gnss_lever_arm_m`` (a mast-top antenna left untold otherwise
  sways at a metre per second in phase with the roll, and the filters read that as tilt),
  and the velocity noise counts what the fit leaves of it.
* **Velocity jitter** (a vibrating chassis): vibration is bounded in velocity, so the
  mechanized velocity carries it as an error that does not accumulate but is there at
  every GNSS epoch (a skid-steer robot on asphalt, ``ROBOT_VIBRATION`` of the simulator:
  0.05 m/s per axis, correlated over 0.05 s, white at a 5 Hz receiver). The specific
  force integrated in the initial body frame, less its best quadratic over each
  :data:`JITTER_CHUNK_S` seconds, shows it (:func:`velocity_jitter`; motion is smooth
  over two seconds). Where it is at least :data:`JITTER_COUNTED` times the GNSS velocity
  sigma the model takes, ``imu_velocity_jitter_mps`` is widened to it, and the aided
  filters add its variance to the GNSS velocity noise (:mod:`.epoch_noise`; during the
  fine stage :mod:`.motion_check` goes on measuring it).
* **Base velocity at rest** (the zero-velocity measurement): the specific force
  integrated in the initial body frame, levelled, less its best quadratic over each
  :data:`VELOCITY_CHUNK_S` seconds, is the velocity the base really has (sway, heave,
  people walking on it) plus a little sensor random walk; its RMS widens
  ``zero_velocity_sigma`` when more than :data:`NOISE_RATIO` times larger
  (horizontal; the vertical one widens ``zero_velocity_sigma_up`` for ``stationary12``,
  which measures the vertical velocity: a moored ship's 0.5 m heave moves it at 0.5 m/s).
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
* **Latitude** (``initial_latitude_deg`` not set and no GNSS fix): at rest the mean rate is
  the Earth rate, at the latitude's angle from the equatorial plane: the angle between
  the mean rate and the mean specific force (up) gives ``sin L = (w . f) / (|w| |f|)``,
  with a 1-sigma of the gyro bias and noise over the Earth rate. Where the gyro sees the
  Earth rate clearly (its magnitude as modelled, that sigma at most
  :data:`LATITUDE_MAX_SIGMA`: a navigation-grade IMU) the estimate replaces the
  position's latitude (in place: the coarse and fine stages use it) and a warning says
  so. Elsewhere (a lower grade, a swaying or moving base) the latitude is unknown: 0
  is used, the finding says so, the bias bounds compare only what needs no latitude
  (the rate's magnitude, gravity's range) and the heading is published as unknown (its
  sigma grows as 1 / cos L with a latitude nobody knows).

Not in the seeds; it is what makes the published sigma a claim that holds with a
wrong or default sensor model.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from ..nav import earth
from ..nav.coarse import arm_velocity_b0, detect_motion, velocity_integral_b0
from ..units import DEG, DPH, DPSH, UG
from .angle_walk import walk_density, walk_or_noise
from .arm_check import fit_lever_arm, levelling
from .gnss_fix import gnss_sigma, uses_reported_covariance

#: a noise estimate widens the configured density when it is this many times larger
NOISE_RATIO = 2.0
#: white noise: the sample-level and the 1-s densities agree within this factor
WHITE_AGREE = 2.0
#: specific-force magnitude that normal gravity, height and scale factor may explain, m/s^2
GRAVITY_TOL = 300.0 * UG
#: rate the gravity direction and scale factors may explain on a still base, rad/s
RATE_TOL = 0.05 * DPH
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
#: seconds of the pieces :func:`base_velocity_rms` fits a quadratic to
VELOCITY_CHUNK_S = 10.0
#: seconds of the pieces :func:`velocity_jitter` fits a quadratic to: some GNSS intervals
#: long (what a filter cannot follow between its epochs), short against a manoeuvre. The
#: quadratic takes part of a correlated jitter with it: 2 s read the simulated robot's
#: 0.051 m/s (30 Hz, 0.05 s) as 0.047-0.050, 1 s as 0.044-0.047; the cars' turns and
#: brakings leave 0.0003-0.0012 m/s in the median of the pieces (0.01-0.017 in their mean)
JITTER_CHUNK_S = 2.0
#: the velocity jitter counts (``imu_velocity_jitter_mps`` widened) where it is at least
#: this times the GNSS velocity sigma the model takes: it then at least doubles the
#: velocity noise variance, which the velocity innovations show (RTK's 0.02 m/s against a
#: skid-steer robot's 0.05); a smaller share is within the noise the consistency monitor
#: answers, and the cars' 0.001 m/s never counts (their cells and goldens unchanged)
JITTER_COUNTED = 1.0
#: gyro-accelerometer correlation of sample differences, in 1/sqrt(N), that means motion
COHERENCE_SIGMAS = 4.5
#: order of the differences of :func:`difference_density`
DIFF_ORDER = 3
#: a lever arm fit beyond this chi-square (3 degrees of freedom, about 6 sigma; no-arm
#: ships, USVs and cars with the arm right give 1-5) replaces the configured arm
ARM_CHI2 = 50.0
#: a gyro bias sigma above this fraction of the horizontal Earth rate: no heading at rest
HEADING_BIAS_FRACTION = 0.5
#: the latitude estimated at rest is used when its 1-sigma is at most this, rad (2 deg: a
#: gyro bias of 0.5 deg/h against the 15.04 deg/h Earth rate; tactical and lower grades
#: need initial_latitude_deg or a GNSS fix)
LATITUDE_MAX_SIGMA = 2.0 * DEG
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
    the configured model; ``findings``: one sentence per widened parameter (warnings);
    ``note``: which checks were skipped and why (informational); ``at_rest``: nothing
    says the base moves (as given); ``still``: the window shows no motion either;
    ``heading_observable``: the gyro can find north at rest; ``mounting_doubt``: why the
    vehicle frame cannot be the told one (the mounting check; '' when it can be);
    ``latitude``: ``(lat, sigma)`` rad estimated from the gyros when the latitude was not
    set (None otherwise); ``latitude_unknown``: it was not set and could not be estimated
    (0 used, heading unobservable); ``gyro_finds_north``: the gyro bias alone allows north
    at rest; ``figures``: the measured bounds for diagnostics.
    """

    widened: dict = field(default_factory=dict)
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


def white_density(x, dt):
    """White-noise density estimate from samples ``x`` (N, 3) at interval ``dt`` (s).

    The geometric mean of ``sqrt(AVAR(1 s) * 1 s)`` and the sample-difference density
    (root means over the axes; the unit of ``x`` times sqrt(s)) where they agree within
    :data:`WHITE_AGREE`, else NaN (also with fewer than 4 s of data).
    """
    m = max(1, int(round(1.0 / dt)))
    k = len(x) // m
    if k < 4:
        return float('nan')
    x1 = x[:k * m].reshape(k, m, 3).mean(axis=1)
    allan = math.sqrt(0.5 * float(np.mean(np.diff(x1, axis=0) ** 2)) * m * dt)
    sample = math.sqrt(0.5 * float(np.mean(np.diff(x, axis=0) ** 2)) * dt)
    if not allan / WHITE_AGREE <= sample <= allan * WHITE_AGREE:
        return float('nan')
    return math.sqrt(allan * sample)


def base_velocity_rms(dth, dvv, dts):
    """RMS (m/s) of the base's horizontal and vertical velocity over a window at rest.

    See the module docstring; ``(nan, nan)`` with less than one piece of data.
    """
    m = int(round(VELOCITY_CHUNK_S / float(np.mean(dts))))
    k = len(dth) // m
    if k < 1:
        return float('nan'), float('nan')
    V = velocity_integral_b0(dth, dvv)[1][:k * m].reshape(k, m, 3)
    up = dvv.sum(axis=0)
    up /= np.linalg.norm(up)
    t = np.cumsum(dts[:m]) - dts[0]
    A = np.column_stack([np.ones(m), t, t * t])
    # the quadratic fit of each chunk, A (A^+ V): the projector A A^+ itself is (m, m), and
    # applying it cost m^2 per chunk (3 s of a 1 kHz IMU's coarse end, bench/scaling.py)
    coef = np.einsum('ij,kjl->kil', np.linalg.pinv(A), V)
    res = V - np.einsum('ij,kjl->kil', A, coef)
    vert = res @ up
    horiz = res - vert[..., None] * up
    return (math.sqrt(float(np.mean(np.sum(horiz * horiz, axis=-1))) / 2.0),
            math.sqrt(float(np.mean(vert * vert))))


def velocity_jitter(dth, dvv, dts, chunk_s=JITTER_CHUNK_S):
    """1-sigma (m/s per horizontal axis) of the velocity jitter of IMU samples; module docstring.

    ``dth``, ``dvv`` (N, 3) increments, ``dts`` (N,) intervals. The specific force
    integrated in the initial body frame (:func:`~sins_align_ros.nav.coarse.velocity_integral_b0`),
    levelled by its own gravity integral, less its best quadratic over each ``chunk_s``
    seconds; the median over the pieces of their horizontal mean square (a piece with a
    manoeuvre's jerk is one of many), with the fit's three degrees of freedom taken out.
    Vibration bounded in velocity stays in it whole; white accelerometer noise of density
    ``q`` leaves about ``0.2 q sqrt(chunk_s)``. NaN with fewer than 5 pieces.
    """
    m = int(round(chunk_s / float(np.mean(dts))))
    k = len(dth) // m if m > 3 else 0
    if k < 5:
        return float('nan')
    V = velocity_integral_b0(dth, dvv)[1]
    up = V[-1] - V[0]
    up = up / np.linalg.norm(up)
    V = V[:k * m].reshape(k, m, 3)
    t = np.cumsum(dts[:m]) - dts[0]
    A = np.column_stack([np.ones(m), t, t * t])
    res = V - np.einsum('ij,kjl->kil', A, np.einsum('ij,kjl->kil', np.linalg.pinv(A), V))
    horiz = res - (res @ up)[..., None] * up
    return math.sqrt(float(np.median(np.sum(horiz * horiz, axis=(1, 2)))) / (2.0 * (m - 3)))


def coherent(dth, dvv, order=DIFF_ORDER):
    """Tell whether the gyro and accelerometer differences are correlated (base motion).

    Sensor noises are independent, so the correlation of each gyro axis's
    ``order``-th differences with each accelerometer axis's stays within a few
    ``1/sqrt(N)``; a physical disturbance turns and accelerates the IMU together.
    Threshold :data:`COHERENCE_SIGMAS` ``/ sqrt(N)`` (the disturbed laser-gyro recording
    of ../shared/data: 0.08 at N = 6000, simulated white noise 0.02).
    """
    a = np.diff(dth, n=order, axis=0)
    b = np.diff(dvv, n=order, axis=0)
    sa, sb = a.std(axis=0), b.std(axis=0)
    if len(a) < 100 or np.any(sa <= 0.0) or np.any(sb <= 0.0):
        return False
    r = ((a - a.mean(axis=0)) / sa).T @ ((b - b.mean(axis=0)) / sb) / len(a)
    return bool(np.max(np.abs(r)) > COHERENCE_SIGMAS / math.sqrt(len(a)))


def difference_density(x, dt, order=DIFF_ORDER):
    """White-noise density upper bound from ``order``-th differences of ``x`` (N, 3).

    For white samples of variance s^2 the ``k``-th difference has variance
    ``C(2k, k) s^2`` and the density is ``s sqrt(dt)``; smooth motion hardly enters a
    third difference at IMU rates. Root mean over the axes; NaN with fewer than 100
    samples.
    """
    if len(x) < 100:
        return float('nan')
    d = np.diff(x, n=order, axis=0)
    return math.sqrt(float(np.mean(d * d)) / math.comb(2 * order, order) * dt)


def robust_difference_sigma(x, order=DIFF_ORDER):
    """Noise 1-sigma of the columns of ``x`` (N, k) from the median of ``order``-th differences.

    For white noise the ``k``-th difference is normal with variance ``C(2k, k) sigma^2``
    and its absolute median is 0.6745 of its sigma. Root mean over the columns; NaN
    with fewer than 10 rows.
    """
    x = np.asarray(x, dtype=float)
    if len(x) < 10:
        return float('nan')
    d = np.diff(x, n=order, axis=0)
    s = np.median(np.abs(d), axis=0) / (0.6745 * math.sqrt(math.comb(2 * order, order)))
    return float(np.sqrt(np.mean(s * s)))


def _regular(t):
    """Tell whether stamps ``t`` are evenly spaced (within 10 %)."""
    d = np.diff(t)
    return len(d) > 0 and float(np.max(np.abs(d - np.median(d)))) <= 0.1 * float(np.median(d))


def gnss_check(out, gnss, t0, t1, cfg, window=None):
    """Widen the GNSS noise of ``cfg`` where the fixes of ``gnss`` in ``[t0, t1]`` show more.

    ``gnss``: the :class:`~.gnss_buffer.GnssBuffer` (its ``fixes`` and ``vels``);
    ``window`` the coarse IMU window, whose view of the motion is taken out of the
    velocities' differences (:func:`motion_free_velocity_sigma`).
    """
    pos_reported, vel_reported = gnss.reported_over(t0, t1)
    fixes = [f for f in gnss.fixes if t0 <= f[0] <= t1]
    if len(fixes) >= 10 and _regular([f[0] for f in fixes]):
        lat, lon, h = (np.array([f[i] for f in fixes]) for i in (1, 2, 3))
        enu = earth.local_offset_m(lat[0], lon[0], h[0], lat, lon, h)
        _gnss_sigma(out, cfg, 'gnss_pos_sigma_m', robust_difference_sigma(enu[:, :2]),
                    pos_reported, 'm')
        _gnss_sigma(out, cfg, 'gnss_height_sigma_m', robust_difference_sigma(enu[:, 2:]),
                    [], 'm')
    vels = [v for v in gnss.vels if t0 <= v[0] <= t1]
    if len(vels) >= 10 and _regular([v[0] for v in vels]):
        V = np.array([v[1] for v in vels])
        t_v = np.array([v[0] for v in vels])
        sigma = robust_difference_sigma(V[:, :2])
        if window is not None:
            arm, arm_sigma = _lever_arm(out, cfg, t_v, V, window)
            sigma = min(sigma, math.hypot(motion_free_velocity_sigma(t_v, V, window, arm),
                                          arm_sigma))
        _gnss_sigma(out, cfg, 'gnss_vel_sigma_mps', sigma, vel_reported, 'm/s')
        if window is not None and cfg['use_gnss_velocity']:
            _velocity_jitter(out, cfg, window, vel_reported)


def _velocity_jitter(out, cfg, window, reported):
    """Widen ``imu_velocity_jitter_mps`` to the coarse window's jitter where it counts.

    Counted where at least :data:`JITTER_COUNTED` times the GNSS velocity sigma the model
    takes (as the check has left it) and more than :data:`NOISE_RATIO` times the
    configured jitter (module docstring).
    """
    _, dth, dvv, dts = window
    j = velocity_jitter(dth, dvv, dts)
    out.figures['velocity_jitter_mps'] = j
    vel = out.widened.get('gnss_vel_sigma_mps', gnss_sigma(cfg, 'gnss_vel_sigma_mps', reported))
    model = cfg['imu_velocity_jitter_mps']
    if not (j >= JITTER_COUNTED * vel and j > NOISE_RATIO * model):
        return
    out.widened['imu_velocity_jitter_mps'] = j
    out.findings.append(f'IMU velocity jitter {j:.3g} m/s in the data (vibration, bounded), '
                        f'{model:.3g} configured, GNSS velocity noise {vel:.3g} m/s: '
                        'imu_velocity_jitter_mps widened (added to the GNSS velocity noise)')


def _lever_arm(out, cfg, t_v, V, window):
    """Check the configured lever arm against the velocities (:mod:`.arm_check`).

    Returns the arm to use (3,) m and the velocity 1-sigma (m/s) its uncertainty leaves.
    An arm beyond :data:`ARM_CHI2` replaces the configured one (``out.widened``); where
    its sign is ambiguous (the fit's ``-delta`` is as good) the antenna is taken above
    the IMU if the vertical part is beyond 3 sigma, else the finding only asks for it.
    """
    configured = np.asarray(cfg['gnss_lever_arm_m'], dtype=float)
    fit = fit_lever_arm(t_v, V, window, configured)
    if fit is None:
        return configured, 0.0
    out.figures['gnss_lever_arm_chi2'] = fit.chi2
    if not fit.chi2 > ARM_CHI2:
        return configured, 0.0
    arm = configured + fit.delta
    sd = np.sqrt(np.diag(fit.cov))
    shown = ', '.join(f'{x:.1f}' for x in arm)
    told = ', '.join(f'{x:.1f}' for x in configured)
    if fit.ambiguous:
        if abs(arm[2]) <= 3.0 * sd[2]:
            out.findings.append(
                f'GNSS velocities sway with the body\'s rotation as from an antenna at '
                f'+-[{shown}] m from the IMU (FLU; the sign cannot be told from this motion), '
                f'configured [{told}]: set gnss_lever_arm_m; until then the sway counts as '
                f'GNSS velocity noise')
            return configured, 0.0
        arm = arm if arm[2] > 0.0 else -arm           # the antenna above the IMU
        shown = ', '.join(f'{x:.1f}' for x in arm)
    out.widened['gnss_lever_arm_m'] = tuple(float(round(x, 2)) for x in arm)
    out.findings.append(
        f'GNSS velocities sway with the body\'s rotation as from an antenna at [{shown}] m '
        f'from the IMU (FLU, +-{np.max(sd):.2f} m), configured [{told}]: gnss_lever_arm_m '
        f'set to the fit' + (' (its sign taken with the antenna above the IMU)'
                             if fit.ambiguous else ''))
    return arm, fit.rate_rms * math.sqrt(float(np.trace(fit.cov)))


def motion_free_velocity_sigma(t_v, V, window, arm_b=None):
    """Horizontal GNSS velocity noise 1-sigma with the base's motion, as the IMU sees it, removed.

    The third differences of the fixes' velocities hold the receiver's noise and the
    base's jerk; at 1 Hz a ship in a seaway has plenty (seed 004's severe sea: 0.045 m/s
    horizontal, 0.23 m/s vertical, as much as the receiver's 0.05 m/s), and each
    outlier spoils four of them (5 % outliers: a fifth of the differences). The IMU sees
    the motion: its specific-force integral in the initial body frame ``u(t)`` (the
    coarse stage's, :func:`~sins_align_ros.nav.coarse.velocity_integral_b0`) differs
    from the ENU velocity by a constant rotation, gravity's integral (along the vertical,
    linear in time) and the bias and Earth-rate terms, smooth over a coarse window. The
    rotation's level part comes from that gravity integral; its heading is the weighted
    median of the angles between the horizontal third differences of ``u`` and of ``V``
    (weights ``|du|^2``: an outlier's rows are a few votes). The velocity less
    the rotated ``u`` is then the receiver's noise on a smooth curve, and the median of
    its second differences gives the noise (a line cancels in them; a running median
    instead read a car speeding up as no noise at all), taken again without those
    beyond 3 sigma and their neighbours (the three an outlier spoils).
    ``t_v`` (N,) stamps and ``V`` (N, 3) ENU velocities of the fixes; ``window`` the
    coarse window ``(t, dtheta, dv, dt)``; ``arm_b`` (3,) the GNSS lever arm (m, body
    axes): the antenna's velocity about the IMU, known from the gyros, is added to ``u``
    (as in :func:`~sins_align_ros.nav.coarse.inertial_frame`). Root mean over the east and
    north axes; NaN when fewer than 10 fixes lie in the window.
    """
    tt, dth, dvv, dts = window
    inside = (t_v >= tt[0]) & (t_v <= tt[-1])
    if np.count_nonzero(inside) < 10:
        return float('nan')
    C_bb0, u_b0 = velocity_integral_b0(dth, dvv)
    if arm_b is not None and np.any(arm_b):
        u_b0 = u_b0 + arm_velocity_b0(C_bb0, dth, dts, np.asarray(arm_b, dtype=float))
    t = t_v[inside]
    U = np.column_stack([np.interp(t, tt, u_b0[:, i]) for i in range(3)])
    U_h = (U @ levelling(U[-1] - U[0]).T)[:, :2]
    V_h = V[inside, :2]
    a = np.diff(U_h, n=DIFF_ORDER, axis=0)
    b = np.diff(V_h, n=DIFF_ORDER, axis=0)
    # the heading: the weighted median of the rows' angles from a to b (weights |a|^2, so
    # rows the IMU sees little motion in count little; an outlier row is one vote)
    ang = np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.sum(a * b, axis=1))
    order = np.argsort(ang)
    cw = np.cumsum(np.sum(a * a, axis=1)[order])
    psi = float(ang[order][np.searchsorted(cw, 0.5 * cw[-1])])
    c, s_ = math.cos(psi), math.sin(psi)
    e = V_h - U_h @ np.array([[c, s_], [-s_, c]])
    # what is left is the receiver's noise on a smooth curve: its second differences
    # (variance 6 sigma^2 for white noise; a line cancels, a smooth curve nearly); an
    # outlier makes three of them large: those beyond 3 sigma and their neighbours are
    # dropped and the median taken again
    d = np.diff(e, n=2, axis=0)
    s = np.median(np.abs(d), axis=0) / 0.6745
    big = np.any(np.abs(d) > 3.0 * s, axis=1)
    spoilt = big | np.r_[big[1:], False] | np.r_[False, big[:-1]]
    if np.count_nonzero(~spoilt) >= 10:
        s = np.median(np.abs(d[~spoilt]), axis=0) / 0.6745
    s = s / math.sqrt(6.0)
    return float(np.sqrt(np.mean(s * s)))


def _gnss_sigma(out, cfg, name, sigma, reported, unit):
    """Widen GNSS sigma ``name`` to ``sigma`` when the data show more than the model."""
    out.figures[name.replace('_sigma', '_noise')] = sigma
    use_reported = uses_reported_covariance(cfg) and len(reported) > 0
    model = gnss_sigma(cfg, name, reported)
    if not sigma > NOISE_RATIO * model:
        return
    out.widened[name] = sigma
    if use_reported:
        out.widened['use_reported_gnss_covariance'] = False
    out.findings.append(f'GNSS noise {sigma:.3g} {unit} in the fixes, {model:.3g} '
                        f'{"reported" if use_reported else "configured"}: {name} widened'
                        + (' and the reported covariances no longer used' if use_reported
                           else ''))


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
        if moving:
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


def _base_velocity(out, cfg, dth, dvv, dts):
    """Widen the zero-velocity sigmas to the velocity the base shows at rest.

    The horizontal RMS widens ``zero_velocity_sigma``; for ``stationary12``, which
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
        if v > NOISE_RATIO * model:
            out.widened[name] = v
            out.findings.append(f'the base moves {how} at {v:.3g} m/s RMS at rest (sway, heave '
                                f'or disturbance), {name} {model:.3g} m/s configured: widened')


def _class_value(table, gyro_noise_dpsh):
    """Return the value of ``table`` ((upper edge, value), ...) for a gyro noise (deg/sqrt(h))."""
    if not math.isfinite(gyro_noise_dpsh):
        return math.inf
    return next(v for edge, v in table if gyro_noise_dpsh <= edge)


def _model(out, cfg, name):
    """Return parameter ``name`` of the model as the check has widened it so far."""
    return out.widened.get(name, cfg[name])


def _gyro_bias_sigma(out, cfg):
    """Return the (widened) gyro bias 1-sigma, constant and varying parts, rad/s."""
    return math.hypot(_model(out, cfg, 'gyro_bias_dph'),
                      _model(out, cfg, 'gyro_bias_instability_dph')) * DPH


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


def _latitude_unknown(out, why):
    """Record that the latitude is unknown (not set, no fix, not estimated) and ``why``."""
    out.latitude_unknown = True
    out.findings.append(f'latitude unknown: initial_latitude_deg is not set and no GNSS fix '
                        f'came, and the gyros cannot estimate it ({why}): 0 deg used, heading '
                        'published as unknown; set initial_latitude_deg')


def estimate_latitude(w_b, f_b, T, gyro_sigma, arw, accel_sigma):
    """Latitude (rad) and its 1-sigma from the window means ``w_b``, ``f_b`` (3,) at rest.

    ``sin L = (w . f) / (|w| |f|)``, taken as ``atan2(w_up, w_h)``. The sigma: the gyro
    bias ``gyro_sigma`` and the mean noise ``arw / sqrt(T)`` (rad/s) move the rate by that
    much across its direction, and an accelerometer bias ``accel_sigma`` tilts the
    vertical by ``accel_sigma / g``.
    """
    f_norm = float(np.linalg.norm(f_b))
    u = f_b / f_norm
    w_up = float(w_b @ u)
    w_h = float(np.linalg.norm(w_b - w_up * u))
    lat = math.atan2(w_up, w_h)
    sigma = math.sqrt(gyro_sigma ** 2 + arw ** 2 / T) / earth.OMEGA_IE
    return lat, math.hypot(sigma, accel_sigma / f_norm)


def _raise(out, cfg, name, value, unit):
    """Raise bias sigma ``name`` to ``value`` for the grade the noise shows (if larger)."""
    if value > _model(out, cfg, name):
        out.findings.append(f'{name} raised from {_model(out, cfg, name):.3g} to {value:.3g} '
                            f'{unit}: the noise shows an IMU of a lower grade than configured, '
                            'whose biases are larger too')
        out.widened[name] = value


def _biases(out, w_b, f_b, T, lat, h, cfg, arw, vrw):
    """Bias bounds from the window means ``w_b``, ``f_b`` (3,) widen ``out``'s model.

    ``lat`` None: the latitude is not known; the gyro bound compares the rate's magnitude
    only, the latitude is estimated (:func:`estimate_latitude`) and, where the gyros see
    the Earth rate clearly, used; else it is unknown and the accelerometer bound
    compares with gravity's range over all latitudes. Returns the latitude used (rad).
    """
    f_norm = float(np.linalg.norm(f_b))
    u = f_b / f_norm
    w_up = float(w_b @ u)
    w_h = float(np.linalg.norm(w_b - w_up * u))
    gyro_sigma = _gyro_bias_sigma(out, cfg)
    tol_g = 2.0 * gyro_sigma + 3.0 * arw / math.sqrt(T) + RATE_TOL
    if lat is not None:
        bound = max(abs(w_up - earth.OMEGA_IE * math.sin(lat)),
                    abs(w_h - earth.OMEGA_IE * math.cos(lat)))
        what = f'mean rate at rest differs from Earth rate by {bound / DPH:.3g} deg/h'
    else:
        bound = abs(math.hypot(w_up, w_h) - earth.OMEGA_IE)
        what = (f'mean rate at rest is {math.hypot(w_up, w_h) / DPH:.3g} deg/h, Earth rate '
                f'{earth.OMEGA_IE / DPH:.4g} deg/h (its direction not compared: latitude not '
                'set)')
    widened = _bound(out, 'gyro_bias_dph', bound / DPH, tol_g / DPH, gyro_sigma / DPH,
                     f'{what}: a gyro bias of at least {bound / DPH:.3g} deg/h')
    accel_sigma = _model(out, cfg, 'accel_bias_ug') * UG
    if lat is None:
        lat = _latitude(out, w_b, f_b, T, _gyro_bias_sigma(out, cfg), arw, accel_sigma,
                        widened)
    if out.latitude_unknown:
        g_lo, g_hi = earth.gravity(0.0, h), earth.gravity(0.5 * math.pi, h)
        g = min(max(f_norm, g_lo), g_hi)
        against = f'gravity {g_lo:.5g}-{g_hi:.5g} (latitude unknown)'
    else:
        g = earth.gravity(lat, h)
        against = f'gravity {g:.5g}'
    accel_bound = abs(f_norm - g)
    tol_a = 2.0 * accel_sigma + 3.0 * vrw / math.sqrt(T) + GRAVITY_TOL
    _bound(out, 'accel_bias_ug', accel_bound / UG, tol_a / UG, accel_sigma / UG,
           f'specific force {f_norm:.5g} m/s^2 at rest against {against}: an '
           f'accelerometer bias of at least {accel_bound / UG:.0f} ug')
    return lat


def _latitude(out, w_b, f_b, T, gyro_sigma, arw, accel_sigma, rate_off):
    """Estimate the latitude not set; use it where clear (module docstring). Returns rad.

    ``rate_off``: the rate's magnitude contradicted the model (the gyro does not see the
    Earth rate as modelled): no estimate is used then.
    """
    lat, sigma = estimate_latitude(w_b, f_b, T, gyro_sigma, arw, accel_sigma)
    out.figures.update(latitude_estimate_deg=lat / DEG, latitude_sigma_deg=sigma / DEG)
    if rate_off or not sigma <= LATITUDE_MAX_SIGMA:
        why = ('its mean rate at rest is not the Earth rate' if rate_off else
               f'{sigma / DEG:.3g} deg 1-sigma from a gyro bias of {gyro_sigma / DPH:.3g} deg/h')
        _latitude_unknown(out, why)
        return 0.0
    out.latitude = (lat, sigma)
    out.findings.append(f'latitude not set (initial_latitude_deg) and no GNSS fix: '
                        f'{lat / DEG:.2f} +- {sigma / DEG:.2f} deg (1 sigma) estimated from the '
                        'angle between the mean rate (Earth rate) and the mean specific force '
                        'at rest, and used')
    return lat


def _bound(out, name, bound, tolerance, model, what):
    """Record a bias ``bound`` on parameter ``name``; widen to it beyond ``tolerance``.

    Returns True if it widened.
    """
    out.figures[name.replace('_ug', '_bound_ug').replace('_dph', '_bound_dph')] = bound
    if bound > tolerance:
        out.widened[name] = bound
        out.findings.append(f'{what}, {model:.3g} in the model: {name} widened')
        return True
    return False

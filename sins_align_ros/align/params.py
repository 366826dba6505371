"""Parameters shared by alignment_node and sins_align_replay (names, ranges, docs).

No ROS here: :class:`Param` is plain data; ``ros/params.py`` turns it into
rcl descriptors; :mod:`.param_text` reads YAML files and ``--set`` overrides into it
and writes the docs' tables.
"""
import difflib
import math
from dataclasses import dataclass

from .filter_table import AIDED, NAVIGATION, ROBUST, STILL, Names

#: the fine filters (views of the one table, :mod:`.filter_table`): all of them
FINE_FILTERS = AVAILABLE_FINE_FILTERS = Names()
#: the values of ``fine_filter``: a filter, or ``auto`` (chosen from what the data show)
FILTER_CHOICES = Names(head=('auto',))
#: seed 002's stationary filters; seed 004's robust ones; the integrated navigation
#: (seeds 001/003: they align and then go on navigating); every GNSS-aided one
STILL_FILTERS, ROBUST_FILTERS, NAV_FILTERS = Names(STILL), Names(ROBUST), Names(NAVIGATION)
MOVING_FILTERS = Names(*AIDED)
COARSE_METHODS = ('auto', 'analytic', 'inertial_frame')
PREPROCESS_WAVELETS = ('sym8', 'sym4', 'db4', 'db8', 'coif2')
#: the zero-velocity sigma (m/s) of a still-base filter whose sigma was left to the data
#: (``zero_velocity_sigma`` 0) and not read: no self-check, or no base velocity measured
#: (the default value until session 53)
ZERO_VELOCITY_UNREAD = 0.01


@dataclass(frozen=True)
class Param:
    """One parameter: name, default (its type is the parameter's type), doc and limits.

    ``choices`` restricts a string; ``lo``/``hi`` a number, or each element of a
    double array (a tuple default: its length is the array's; inclusive);
    ``read_only`` parameters can only be set at start-up; ``unset``: NaN (``.nan`` in
    YAML and on the command line) is accepted as "not set" beside the range (the default
    of such a parameter is NaN).
    """

    name: str
    default: object
    description: str
    lo: float = None
    hi: float = None
    choices: tuple = None
    read_only: bool = False
    unset: bool = False

    @property
    def is_array(self):
        """Tell whether the parameter is a double array (its default is a tuple)."""
        return isinstance(self.default, tuple)

    def normalise(self, value):
        """Return ``value`` in the parameter's own type (an array as a tuple of floats).

        Accepts what YAML, rclpy (``array.array``) and Python give; an int for a
        double becomes a float. Anything else is returned unchanged for :meth:`check`.
        """
        if self.is_array and not isinstance(value, (str, bytes, dict)):
            try:
                items = list(value)
            except TypeError:
                return value
            if all(type(v) in (int, float) for v in items):
                return tuple(float(v) for v in items)
            return value
        if isinstance(self.default, float) and type(value) is int:
            return float(value)
        return value

    def check(self, value):
        """Return an error message for ``value`` or None if it is acceptable."""
        if self.is_array:
            value = self.normalise(value)
            n = len(self.default)
            if type(value) is not tuple or len(value) != n:
                return f'{self.name}={value!r} is not an array of {n} numbers'
            if not all(math.isfinite(v) for v in value):
                return f'{self.name}={value!r} has a non-finite element'
            if self.lo is not None and not all(self.lo <= v <= self.hi for v in value):
                return f'{self.name}={value!r} has an element outside [{self.lo}, {self.hi}]'
            return None
        if type(value) is not type(self.default) and not (
                isinstance(self.default, float) and type(value) is int):
            return (f'{self.name}={value!r} has type {type(value).__name__}, '
                    f'expected {type(self.default).__name__}')
        if self.choices and value not in self.choices:
            return f'{self.name}={value!r} is not one of {", ".join(self.choices)}'
        if self.unset and isinstance(value, float) and math.isnan(value):
            return None
        if self.lo is not None and not (self.lo <= value <= self.hi):
            return f'{self.name}={value!r} is outside [{self.lo}, {self.hi}]'
        return None


ALIGNMENT_PARAMS = (
    Param('fine_filter', 'auto', 'fine-alignment filter; auto: auto_still_filter while GNSS '
          'shows the base at rest (or there is no GNSS), auto_moving_filter when it moves',
          choices=FILTER_CHOICES),
    Param('auto_still_filter', 'reduced7', 'auto: the filter for a base at rest',
          choices=STILL_FILTERS),
    Param('auto_moving_filter', 'kf', 'auto: the GNSS-aided filter for a moving base',
          choices=MOVING_FILTERS),
    Param('motion_speed_mps', 0.5, 'GNSS horizontal speed above which the base moves: auto '
          'picks the moving filter, a stationary filter refuses to start, the sensor '
          'self-check skips its bias bounds, m/s', 0.05, 50.0),
    Param('coarse_method', 'auto', 'coarse alignment: analytic (still base), inertial_frame '
          '(sway, disturbance) or auto (picks by detecting motion)', choices=COARSE_METHODS),
    Param('coarse_duration', 60.0, 'coarse alignment time, s (at most: see '
          'coarse_min_duration and coarse_motion_s; with fine_filter auto and no GNSS at all, '
          'at least 60 s: only over a minute can the IMU tell a drive from rest)', 1.0, 3600.0),
    Param('coarse_min_duration', 20.0, 'shortest coarse window, which the sensor self-check '
          'reads: a still base\'s window ends once it has lasted this long and its attitude, '
          'with the noise the samples show, is good enough for the fine filter '
          '(docs/coarse.md); a base GNSS shows moving ends it coarse_motion_s after the '
          'motion starts, not before this; at least coarse_duration: the window lasts '
          'coarse_duration, s',
          1.0, 3600.0),
    Param('coarse_reprocess', True, 'a still-base fine filter starts at the coarse window\'s '
          'first sample and runs over its stored samples before the live ones, with a prior '
          'that does not count them twice (docs/coarse.md); false: it starts at the '
          'window\'s end'),
    Param('coarse_reprocess_aided', True, 'with coarse_reprocess, a GNSS-aided fine filter '
          'also starts at the window\'s first sample and runs over its samples, fixes and '
          'external headings: aligned sooner (a navigation-grade ship under way 70 s instead '
          'of 136 s, a MEMS car 5 s after it starts to drive instead of 17 s); false: it '
          'starts at the window\'s end (docs/coarse.md)'),
    Param('coarse_motion_s', 5.0, 'the coarse window ends this long after GNSS shows the '
          'base start moving, but not before coarse_min_duration (a base moving from the '
          'start: after coarse_min_duration, unless its gyro cannot find north: a MEMS IMU '
          'keeps coarse_duration); the moving-base coarse alignment takes the heading from '
          'the motion; 0 = always coarse_duration, s', 0.0, 3600.0),
    Param('initial_latitude_deg', math.nan, 'latitude used without a GNSS fix, deg; .nan: not '
          'set: at rest the gyros estimate it where they see the Earth rate clearly (a '
          'navigation-grade IMU), else it is unknown, 0 is used and the heading is published '
          'as unknown (docs/parameters.md)', -89.0, 89.0, unset=True),
    Param('initial_longitude_deg', 0.0, 'longitude used without a GNSS fix, deg',
          -180.0, 180.0),
    Param('initial_height_m', 0.0, 'height used without a GNSS fix, m', -1000.0, 50000.0),
    Param('gnss_lever_arm_m', (0.0, 0.0, 0.0), 'GNSS antenna position relative to the IMU '
          'in the vehicle frame (FLU: forward, left, up), [x, y, z] m: every GNSS position and '
          'velocity is moved to the IMU (docs/installation.md)', -500.0, 500.0),
    Param('imu_mounting_rpy_deg', (0.0, 0.0, 0.0), 'rotation of the vehicle frame to the '
          'IMU frame (the base_link -> imu_link transform), [roll, pitch, yaw] deg, REP-103 '
          '(static_transform_publisher takes them as yaw, pitch, roll): the IMU data are '
          'turned into the vehicle frame at input and every output is the vehicle\'s '
          'attitude', -360.0, 360.0),
    Param('heading_offset_deg', 0.0, 'external heading (heading/in): the direction of the '
          'source\'s x axis (a GNSS compass\'s baseline) in the vehicle frame, deg '
          'counter-clockwise from forward; the vehicle\'s yaw is the source\'s minus this',
          -180.0, 180.0),
    Param('heading_sigma_deg', 0.5, 'external heading: 1-sigma used when a heading/in '
          'message reports no usable yaw variance, deg', 0.001, 90.0),
    Param('use_gnss_position', True, 'take latitude/height from a valid gnss/fix when one '
          'arrives before fine alignment starts'),
    Param('imu_noise_file', '', 'IMU noise file in SI units (Kalibr imu.yaml, OpenVINS '
          'kalibr_imu_chain.yaml, VINS-Fusion config): sets gyro_arw_dpsh, '
          'gyro_bias_instability_dph, accel_vrw_ug_rthz and accel_bias_ug where they are not '
          'given as parameters (docs/imu_noise_file.md); read at start-up', read_only=True),
    Param('gyro_bias_dph', 0.01, 'gyro constant bias, 1 sigma, deg/h (filter model)',
          0.0, 36000.0),
    Param('gyro_arw_dpsh', 0.001, 'gyro angle random walk, deg/sqrt(h) (filter model)',
          0.0, 100.0),
    Param('gyro_bias_instability_dph', 0.0, 'slowly varying part of the gyro bias (first-'
          'order Gauss-Markov), 1 sigma, deg/h: adds to the constant bias, and the moving-base '
          'filters let their drift states follow it (random walk 2 sigma^2 / tau)',
          0.0, 36000.0),
    Param('gyro_bias_tau_s', 300.0, 'correlation time of gyro_bias_instability_dph, s',
          1.0, 1e6),
    Param('gyro_scale_factor_ppm', 0.0, 'gyro scale-factor error, 1 sigma per axis, ppm '
          '(filter model: a heading/tilt error that grows with the angle turned; GNSS-aided '
          'filters; the self-check raises it to the class its gyro noise shows)', 0.0, 1e5),
    Param('gyro_misalignment_ppm', 0.0, 'gyro axis misalignment (non-orthogonality), 1 '
          'sigma per off-diagonal entry, ppm (filter model, as gyro_scale_factor_ppm: a turn '
          'about one axis leaks into the other two; its square is also added to the '
          'published tilt variance: the yaw rate leaking into the horizontal gyros makes a '
          'tilt no turn tells from an accelerometer bias)', 0.0, 1e5),
    Param('accel_bias_ug', 100.0, 'accelerometer constant bias, 1 sigma, micro-g', 0.0, 1e5),
    Param('accel_scale_factor_ppm', 0.0, 'accelerometer scale-factor error, 1 sigma per '
          'axis, ppm (filter model: a velocity error that grows with the velocity the vehicle '
          'gains, and under gravity a vertical bias; GNSS-aided filters; the self-check raises '
          'it to the class its gyro noise shows on a moving base)', 0.0, 1e5),
    Param('accel_misalignment_ppm', 0.0, 'accelerometer axis misalignment (non-'
          'orthogonality), 1 sigma per off-diagonal entry, ppm (filter model, as '
          'accel_scale_factor_ppm: an acceleration along one axis leaks into the other two, '
          'and gravity into the horizontal axes as a bias)', 0.0, 1e5),
    Param('accel_vrw_ug_rthz', 10.0, 'accelerometer white noise, micro-g/sqrt(Hz)', 0.0, 1e5),
    Param('zero_velocity_sigma', 0.0, 'zero-velocity measurement noise, m/s (still base); '
          '0 = read from the data: the self-check\'s base velocity at rest (its RMS in the '
          'coarse window, x1.5, at least 3e-4 m/s; 0.01 where it is not measured). A set '
          'value is a claim about the base, widened only where the data show more',
          0.0, 10.0),
    Param('zero_velocity_sigma_up', 0.0, 'vertical zero-velocity measurement noise, m/s '
          '(stationary12, which measures the vertical velocity: a moored ship heaves); '
          '0 = zero_velocity_sigma (read from the vertical base velocity where that is 0 too)',
          0.0, 10.0),
    Param('fine_update_hz', 10.0, 'fine-filter measurement rate, Hz', 0.1, 1000.0),
    Param('max_stages', 3, 'staged re-initialisations of the stationary filter after '
          'convergence (seed 002 sec. 4; 1 = none), made only after an initial misalignment '
          'large enough for the first stage\'s linear model to leave an error', 1, 10),
    Param('stage_min_duration', 30.0, 'minimum time of a stationary fine-alignment stage '
          'before it may be restaged (max_stages; aligned comes once the estimate has '
          'settled, whatever the stage), s', 5.0, 3600.0),
    Param('aligned_max_tilt_sigma_deg', 1.0, 'aligned once the roll and pitch 1-sigma are at '
          'most this, left when they exceed 1.2 times it, deg (tilt_ready in the '
          'diagnostics)', 0.001, 90.0),
    Param('aligned_max_heading_sigma_deg', 2.0, 'aligned once the heading 1-sigma is at most '
          'this, left when it exceeds 1.2 times it, deg (heading_ready in the diagnostics)',
          0.001, 180.0),
    Param('sensor_self_check', True, 'check the configured sensor model against the coarse '
          'window and widen it where the data contradict it (docs/checks.md)'),
    Param('mounting_check_max_tilt_deg', 45.0, 'self-check: a vehicle frame tilted more '
          'than this in the coarse window (its mean specific force) is taken for an IMU '
          'mounted rotated with imu_mounting_rpy_deg untold: the attitude is published as '
          'unknown and never aligned (docs/installation.md); 180 turns the '
          'check off, deg', 5.0, 180.0),
    Param('mounting_check_max_sideslip_deg', 45.0, 'self-check under way: a median angle of '
          'the GNSS velocity from the vehicle\'s forward axis beyond this (GNSS epochs above '
          '1 m/s, heading known) is taken for an IMU turned about the vertical '
          'with imu_mounting_rpy_deg untold: the attitude is published as unknown and never '
          'aligned; 180 turns the check off (a vehicle that moves sideways), deg', 5.0, 180.0),
    Param('slow_monitor_legs', 3, 'slow-error monitor of the GNSS-aided filters: this many '
          'consecutive straight legs whose GNSS course lies more than slow_monitor_sigmas from '
          'the published heading leave aligned and inflate the heading, tilt and bias '
          'covariance; as many agreeing legs end it (docs/checks.md); 0 turns it off',
          0, 100),
    Param('slow_monitor_sigmas', 3.0, 'slow-error monitor: a straight leg disagrees when its '
          'course minus the published heading exceeds this many combined sigmas (heading, '
          'course noise, sideslip)', 1.0, 20.0),
    Param('slow_monitor_sideslip_deg', 0.5, 'slow-error monitor: the sideslip (crab) 1-sigma '
          'a straight leg may show, deg: a car 0.5, a skid-steer robot a few, a boat in a '
          'current 20-30', 0.0, 90.0),
    Param('course_heading', True, 'GNSS-aided filters: while the published heading is less '
          'certain than the GNSS course of a straight leg (5-30 s), that course is given to '
          'the filter as a heading fix (the vehicle moves along its forward axis); not on legs '
          'with GNSS velocity above track_min_speed_mps (the track heading\'s); off for a '
          'vehicle that crabs or moves sideways (docs/checks.md)'),
    Param('turn_scale', True, 'GNSS-aided filters without GNSS velocity: measure the up '
          'gyro\'s scale factor from each turn between two straight legs (the gyro\'s '
          'rotation against the change of GNSS course), compensate it and model its measured '
          'sigma instead of the told one (docs/checks.md)'),
    Param('course_heading_sideslip_deg', 5.0, 'course heading aid: the sideslip (crab) '
          '1-sigma of a straight leg added to the course\'s own, deg: a car 1, a skid-steer '
          'robot a few; legs whose courses disagree beyond it turn the aid off', 0.0, 90.0),
    Param('gnss_pos_sigma_m', 1.0, 'GNSS horizontal position noise, 1 sigma, m (moving-base '
          'filters; used when a fix reports no covariance or reported covariance is off)',
          0.001, 1000.0),
    Param('gnss_vel_sigma_mps', 0.1, 'GNSS velocity noise, 1 sigma, m/s (gnss/vel)',
          0.001, 100.0),
    Param('gnss_position_markov_sigma_m', 0.0, 'GNSS position error correlated in time: '
          'first-order Gauss-Markov sigma per ENU axis beside the white noise (a consumer '
          'receiver: about 1.5), m; kf and ukf carry it as three states, the other moving-base '
          'filters add its white equivalent over the fix interval to each fix\'s position '
          'noise (docs/diagnostics.md); 0: '
          'none assumed, until the innovations show one over tens of seconds (then '
          'widened and said)', 0.0, 100.0),
    Param('gnss_position_markov_tau_s', 60.0, 'correlation time of that Gauss-Markov error '
          '(also when the innovations switch it on), s', 1.0, 1e5),
    Param('gnss_position_only_markov', True, 'a position-only receiver (no gnss/vel when '
          'the fine stage starts) with gnss_position_markov_sigma_m 0: take each fix\'s '
          'horizontal position sigma (reported, else gnss_pos_sigma_m; twice it in kf and '
          'ukf, which carry the error as states) as a Gauss-Markov '
          'error of gnss_position_markov_tau_s too, since a standalone receiver\'s error is '
          'mostly correlated over tens of seconds and its heading comes from position '
          'differences (said with a WARN); false: white until the innovations show otherwise'),
    Param('imu_velocity_jitter_mps', 0.0, 'the IMU\'s velocity error from vibration, bounded '
          '(it does not accumulate), 1 sigma per axis, m/s: the aided filters add its variance '
          'to the GNSS velocity noise; the self-check measures it (widened where it is at '
          'least the GNSS velocity sigma; a skid-steer robot on asphalt: about 0.05)',
          0.0, 10.0),
    Param('use_gnss_velocity', True, 'measure gnss/vel in the moving-base filters as well '
          'as the position (when gnss/vel messages arrive)'),
    Param('zero_rate_at_rest', True, 'while a GNSS velocity shows the base at rest (kf, ukf, '
          'vbakf, mvbakf, ckf, asckf), take the rate about the vertical as the Earth '
          'rate\'s plus the gyro drift: the vertical drift is then known when the vehicle '
          'drives off (docs/filters_navigation.md); false for a base that turns while its '
          'antenna stands still (a turntable, a ship swinging at anchor)'),
    Param('use_reported_gnss_covariance', True, 'take the east/north GNSS position and '
          'velocity noise from each message\'s covariance when it is known, instead of '
          'gnss_pos_sigma_m / gnss_vel_sigma_mps (ckf, asckf without adaptation, kf, ukf; the '
          'VB filters estimate R); the self-check and the consistency monitor widen it where '
          'the data show more, never narrow it'),
    Param('asckf_fading', True, 'asckf: multiple fading factors (seed 000 eq. 7-17)'),
    Param('asckf_adaptive', True, 'asckf: Sage-Husa measurement-noise estimation with the '
          'divergence test (seed 000 eq. 39, 20)'),
    Param('asckf_adapt_q', False, 'asckf: estimate the process noise Q as well (seed 000 '
          'eq. 39; off by default, see docs/filters_moving.md)'),
    Param('asckf_forgetting', 0.97, 'asckf: Sage-Husa forgetting factor b', 0.5, 0.9999),
    Param('vb_forgetting', 0.98, 'vbckf/vbch: forgetting factor rho of the variational-Bayes '
          'R estimate (memory about 1 / (1 - rho) GNSS epochs; seed 004 eq. 24)', 0.5, 1.0),
    Param('vb_iterations', 20, 'vbckf/vbch: variational-Bayes iterations per GNSS epoch '
          '(seed 004: N = 20)', 1, 100),
    Param('vbch_c', 100.0, 'vbch: constant C of the adaptive robust factor gamma (seed 004 '
          'eq. 15; the seed\'s 1.5 lets the heading variance grow every epoch, see '
          'docs/filters_severe_sea.md)',
          0.0, 1e6),
    Param('vb_outlier_dof', 5.0, 'vbckf/vbch: degrees of freedom of the Student-t scale that '
          'down-weights outlier epochs (0: off, the seed\'s plain inverse-Gamma R)',
          0.0, 1000.0),
    Param('continue_navigation', True, 'kf/vbakf/mvbakf/ukf: go on navigating after '
          'alignment: the node publishes ~/odom (nav_msgs/Odometry, ENU) at IMU rate and the '
          'replay CSV gets position/velocity columns'),
    Param('nav_forgetting', 0.95, 'vbakf/mvbakf: forgetting factor rho of the variational-'
          'Bayes R estimate (seed 001 sec. 3.2: 0.95)', 0.5, 0.9999),
    Param('nav_iterations', 5, 'vbakf/mvbakf: fixed-point iterations N per GNSS epoch (seed '
          '001: N = 5)', 1, 100),
    Param('mvbakf_tau', 6.0, 'mvbakf: tuning factor tau of the inverse-Wishart prior of '
          'P(k|k-1) (seed 001 eq. 9-10; its Fig. 2 uses 6)', 0.0, 1e6),
    Param('mvbakf_moment', 'mean', 'mvbakf: posterior moment of P(k|k-1) and R used in the '
          'update: mean (seed 001 eq. 24, 30 as printed) or inverse (E[P^-1]^-1, the '
          'variational derivation\'s; see docs/filters_navigation.md)',
          choices=('mean', 'inverse')),
    Param('nav_q_scale', 1.0, 'kf/vbakf/mvbakf/ukf: factor on the process noise Q the '
          'sensor parameters give (seed 001 runs its filters with 9)', 0.01, 1e4),
    Param('accel_bias_tau_s', 3600.0, 'kf/vbakf/mvbakf/ukf: correlation time of the '
          'first-order Markov accelerometer error (seed 001 eq. 2, seed 003 eq. 25), s',
          1.0, 1e7),
    Param('gnss_height_sigma_m', 2.0, 'GNSS height noise, 1 sigma, m (kf/vbakf/mvbakf/ukf '
          'measure the height)', 0.001, 1000.0),
    Param('preprocess', False, 'IMU pre-processing before alignment (seed 004 Fig. 1): '
          'resampling with the increments preserved, wavelet threshold denoising, delay '
          'compensated by keeping each sample\'s stamp (output latency about '
          'preprocess_window * 3/4 samples)'),
    Param('preprocess_factor', 10, 'pre-processing: resampling factor (seed 004: 10)', 2, 100),
    Param('preprocess_window', 64, 'pre-processing: IMU samples per denoising window (even; '
          'the window moves by a quarter of it)', 8, 4096),
    Param('preprocess_wavelet', 'sym8', 'pre-processing: wavelet (PyWavelets name)',
          choices=PREPROCESS_WAVELETS),
    Param('track_min_speed_mps', 2.0, 'coarse alignment on a moving base takes the heading '
          'from the GNSS track above this horizontal speed, m/s', 0.1, 1000.0),
    Param('track_heading_sigma_deg', 10.0, '1-sigma of the track heading (crab angle, '
          'sideslip, mounting), deg', 0.1, 180.0),
    Param('max_gap', 0.5, 'largest IMU stamp interval bridged (the rate is held over it), '
          's; a longer gap or a backward clock jump restarts the alignment', 0.001, 10.0),
    Param('gyro_range_dps', 2000.0, 'gyro measurement range, deg/s: a sample with a '
          'component at it is taken as saturated and skipped', 1.0, 1e5),
    Param('accel_range_mps2', 160.0, 'accelerometer measurement range, m/s^2: a sample with '
          'a component at it is taken as saturated and skipped', 1.0, 1e5),
    Param('gnss_gate_probability', 0.9999, 'moving-base filters: GNSS epochs whose normalised '
          'innovation squared exceeds the chi-square quantile of this probability are '
          'rejected as outliers (1.0: no gate)', 0.5, 1.0),
    Param('gnss_gate_max_rejects', 10, 'after this many GNSS epochs rejected in a row the next '
          'is accepted with widened position/velocity variances (re-anchoring after a jump)',
          1, 1000),
)

#: parameters of the alignment node only (its ROS interface); the shared presets in
#: config/ may set them, and the replay tool accepts and ignores them
NODE_PARAMS = (
    Param('imu_frame_id', '', 'expected frame_id of imu/data_raw (empty: accept any)'),
    Param('diagnostic_period', 1.0, 'period of /diagnostics, s', 0.05, 60.0),
    Param('imu_batch_period', 0.01, 'IMU messages wait until the first has waited this long '
          '(wall clock; or a GNSS message comes), then go through the checks and the '
          'filters together; imu/data is still published for every sample. Bounds the '
          'added latency; 0: each message at once, s', 0.0, 0.1, read_only=True),
    Param('base_frame_id', 'base_link', 'frame_id of imu/data and ~/euler, and child frame '
          'of ~/odom, when imu_mounting_rpy_deg is set (their rates are then the vehicle\'s); '
          'without a mounting rotation the IMU frame is the vehicle frame and the input '
          'frame_id is kept'),
    Param('odom_frame_id', 'odom', 'frame_id of ~/odom: ENU axes, origin where fine '
          'alignment started'),
)

_BY_NAME = {p.name: p for p in ALIGNMENT_PARAMS}
_NODE_BY_NAME = {p.name: p for p in NODE_PARAMS}


def closest(name, names):
    """Return the name in ``names`` closest to ``name`` (difflib), or None if none is close."""
    found = difflib.get_close_matches(name, list(names), n=1, cutoff=0.6)
    return found[0] if found else None


def unknown_message(name, params):
    """Say that ``name`` is not one of ``params``, with the closest declared name if any."""
    near = closest(name, [p.name for p in params])
    return f'unknown parameter {name!r}' + (f' (did you mean {near!r}?)' if near else '')


def declaration(name):
    """Return the declared :class:`Param` of ``name`` (alignment or node-only), or None."""
    return _BY_NAME.get(name) or _NODE_BY_NAME.get(name)


def is_unset(value):
    """Tell whether a float parameter ``value`` is NaN, "not set" (:attr:`Param.unset`)."""
    return isinstance(value, float) and math.isnan(value)


def defaults():
    """Return the default values of all alignment parameters, name -> value."""
    return {p.name: p.default for p in ALIGNMENT_PARAMS}


def validate(values):
    """Check a dict of parameter values; return it with ints promoted to float where due.

    Raises ``ValueError`` naming the first bad or unknown parameter.
    """
    out = {}
    for k, v in values.items():
        p = _BY_NAME.get(k)
        if p is None:
            raise ValueError(unknown_message(k, ALIGNMENT_PARAMS + NODE_PARAMS))
        err = p.check(v)
        if err:
            raise ValueError(err)
        out[k] = p.normalise(v)
    return out


def split_node_params(values):
    """Split ``values`` into (alignment parameters, node-only parameters), both checked.

    Raises ``ValueError`` for an unknown name or a bad node-only value; the
    alignment values are checked by :func:`validate`.
    """
    node = {}
    for k in [k for k in values if k in _NODE_BY_NAME]:
        p = _NODE_BY_NAME[k]
        err = p.check(values[k])
        if err:
            raise ValueError(err)
        node[k] = p.normalise(values[k])
    return validate({k: v for k, v in values.items() if k not in node}), node

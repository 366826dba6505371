"""The coarse stage: the attitude and its sigma from the coarse window's samples.

The window itself (its samples, its early end, the sigma bound) is :mod:`.coarse_window`'s.

Still base (the stationary filters): analytic (TRIAD) or inertial-frame coarse
alignment (``coarse_method``; ``auto`` picks by detecting motion in the window).
Moving base (the GNSS-aided filters): the inertial-frame method with the GNSS
velocity change removed, and the heading taken from the GNSS track when the
vehicle moves faster than ``track_min_speed_mps``.

The sigma handed to the fine filter is a conservative bound on what the coarse
method leaves (:func:`~.coarse_window.coarse_sigma`), so the fine filter starts honest.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from ...nav import coarse, earth
from ...nav.frames import dcm_to_euler, euler_to_dcm
from ...units import DEG, DPH
from .coarse_window import coarse_sigma


@dataclass
class CoarseResult:
    """What the coarse stage hands to the fine filter.

    ``C_b_n`` (3, 3) body FLU -> ENU; ``sigma`` (3,) rad; ``v_n`` (3,) ENU velocity at
    the end of the window (zero on a still base); ``position`` (3,) rad, rad, m;
    ``sigma_v`` m/s the velocity's sigma; ``info`` for diagnostics; ``warnings``;
    ``sigma_linear`` (3,) rad or None: the error the attitude may carry, without
    :func:`coarse_sigma`'s floors (0.5 deg of heading, 0.05 deg of tilt, which keep the
    fine filter's prior honest): what decides whether a still-base filter's restage
    helps (:func:`~..engines.stationary.restage_helps`; a marine-grade window of 20 s
    leaves arcminutes, whose nonlinear error is nothing, while the floor's 0.5 deg called
    for a restage, which widened a converged heading nine-fold). None: ``sigma``.
    ``v_n_start`` (3,) or None: the IMU's ENU velocity at the window's first sample (a
    GNSS-aided window a velocity covers: gnss/vel or the fixes' slope), where a
    reprocessing stage starts (:mod:`.reprocess`).
    """

    C_b_n: np.ndarray
    sigma: np.ndarray
    position: np.ndarray
    v_n: np.ndarray = field(default_factory=lambda: np.zeros(3))
    sigma_v: float = 0.01
    info: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    sigma_linear: np.ndarray = None
    v_n_start: np.ndarray = None


#: fits of the moving-base coarse alignment that move the GNSS velocity to the IMU with
#: the previous fit's attitude (a lever arm)
ARM_PASSES = 2
#: a gnss/vel message of the coarse window is an outlier when its difference from the
#: IMU's velocity change leaves the window's smooth trend by more than this many times
#: the larger of its sigma and the differences' robust scatter
OUTLIER_SIGMAS = 5.0
#: more outliers than this share of the window's messages: the differences are not
#: noise plus a few glitches (an unconfigured lever arm, a wrong model), none is dropped
MAX_OUTLIER_SHARE = 0.2
#: fewest gnss/vel messages in the window for the outlier test
MIN_EPOCHS_SCREENED = 8
#: the warning for a latitude not set, no fix, and no self-check to estimate it
LATITUDE_UNSET = ('latitude unknown: initial_latitude_deg is not set, no GNSS fix came and '
                  'sensor_self_check is off (which estimates it): 0 deg used, so the Earth '
                  'rate model and the heading sigma are the equator\'s; set '
                  'initial_latitude_deg')


def steady_velocity(V, v_sig):
    """Tell whether the horizontal velocity (N, 3) is constant within its noise ``v_sig``.

    Then the inertial-frame coarse alignment is better off assuming no velocity
    change than subtracting a noisy one: its heading signal after T seconds is only
    about g W cos(L) T^2 / 2 (1 m/s at 60 s), so 0.05 m/s of noise on the first
    velocity alone would turn the heading by degrees.
    """
    dev = V[:, :2] - V[:, :2].mean(axis=0)
    return bool(np.mean(np.sum(dev * dev, axis=1)) < 2.0 * (2.0 * v_sig * v_sig))


def degenerate(C):
    """Reason why a coarse attitude is unusable (non-finite), or None."""
    if np.all(np.isfinite(C)):
        return None
    return ('coarse alignment degenerate: no usable gravity or Earth-rate direction in the '
            'window (gyro or accelerometer output near zero?)')


def run(window, cfg, noise, position, gnss, t_now, aided, install=None):
    """Coarse alignment for the filter family: :func:`moving_base` or :func:`still_base`.

    ``aided``: the fine filter is GNSS-aided; ``install`` the
    :class:`~.installation.Installation` (its lever arm). Returns ``(CoarseResult or None,
    info, reason)``. With the latitude not set and no fix, the sensor self-check
    estimates it or says it is unknown; with the self-check off, a warning here says
    that 0 is used.
    """
    if aided:
        res, info, reason = moving_base(window, cfg, noise, position, gnss, t_now, install)
    else:
        res, info, reason = still_base(window, cfg, noise, position)
    if res is not None and not cfg['sensor_self_check'] and not gnss.latitude_known(cfg):
        res.warnings.append(LATITUDE_UNSET)
    return res, info, reason


def still_base(window, cfg, noise, position):
    """Coarse alignment for the stationary filters: (CoarseResult or None, info, reason)."""
    tt, dth, dvv, dts = window
    lat, _, h = position
    method = cfg['coarse_method']
    moving, rate_sc, tilt_sc = coarse.detect_motion(dth, dvv, dts, noise.gyro_arw,
                                                    noise.accel_vrw)
    if method == 'auto':
        method = 'inertial_frame' if moving else 'analytic'
    if method == 'analytic':
        C = coarse.analytic(dth, dvv, dts, lat)
    else:
        C = coarse.inertial_frame(dth, dvv, dts, lat, h)
    T = float(np.sum(dts))
    info = _info(method, moving, rate_sc, tilt_sc, T)
    reason = degenerate(C)
    if reason:
        return None, info, reason
    sigma, warning = coarse_sigma(noise, T, lat, moving)
    return CoarseResult(C, sigma, position, info=info, warnings=[warning] if warning else [],
                        sigma_linear=coarse_sigma(noise, T, lat, moving, floors=False)[0]), \
        info, None


def moving_base(window, cfg, noise, position, gnss, t_now, install=None):
    """Coarse alignment for the GNSS-aided filters: (CoarseResult or None, info, reason).

    ``gnss`` is the :class:`~.gnss_buffer.GnssBuffer`; ``t_now`` the last IMU stamp (the
    position is moved from the last fix's stamp to it). With a GNSS lever arm
    (``install``), the GNSS velocity is the antenna's: a first fit takes the arm's
    velocity on the specific-force side (:func:`~sins_align_ros.nav.coarse.inertial_frame`,
    ``arm_b``), needing no attitude; its attitude gives the arm's velocity at every IMU
    sample, which is taken off each GNSS velocity at its own stamp (:data:`ARM_PASSES`
    times, each with the last fit's attitude). The IMU's velocity, smoother than the
    antenna's sway, is then interpolated as without an arm (interpolating the antenna's
    1 Hz velocity over a 7 s sway left 0.1 m/s and 15' of tilt), and moves the position
    to the IMU too.
    """
    tt, dth, dvv, dts = window
    lat, lon, h = position
    moving, rate_sc, tilt_sc = coarse.detect_motion(dth, dvv, dts, noise.gyro_arw,
                                                    noise.accel_vrw)
    T = float(np.sum(dts))
    info = _info('inertial_frame', moving, rate_sc, tilt_sc, T)
    # weighed with the sigmas the filter will use (a receiver's reported covariance for
    # seed 000's family): a configured 0.1 m against reported, and real, 1 m fixes took
    # a still base's noisy fix velocities for motion and turned the heading by 6 deg
    sigmas = gnss.sigmas_over(tt, cfg)
    V, v_sig, v_src = gnss.velocity_over(tt, *sigmas)
    arm_b = None if install is None or install.no_arm else install.l_v
    drop = frozenset()
    if v_src == 'gnss_velocity':
        drop = velocity_outliers(window, lat, h, gnss, V, v_sig, arm_b)
        if drop:
            V = gnss.velocity_over(tt, *sigmas, drop=drop)[0]
    C_arm = None
    if V is not None and arm_b is not None:
        C_arm, V = _arm_to_imu(window, lat, h, gnss, sigmas, cfg, install, V, drop)
        reason = degenerate(C_arm)
        if reason:
            return None, info, reason
    steady = V is not None and steady_velocity(V, v_sig)
    dv_n = None if V is None or steady else V - V[0]
    if C_arm is not None and dv_n is not None:
        C = C_arm                          # the fit with the arm where it is exact
    else:
        C = coarse.inertial_frame(dth, dvv, dts, lat, h, dv_n=dv_n)
    reason = degenerate(C)
    if reason:
        return None, info, reason
    sigma, warning = coarse_sigma(noise, T, lat, moving, cap=90.0 * DEG)
    warnings = [warning] if warning else []
    if dv_n is not None:
        # the GNSS velocity noise enters the fit against the horizontal gravity
        # integral, which grows as g W cos(L) T^2 / 2 (about 1 m/s after 60 s)
        signal = earth.gravity(lat, h) * earth.OMEGA_IE * math.cos(lat) * T * T / 2.0
        sigma[2] = min(math.hypot(sigma[2], 3.0 * math.sqrt(2.0) * v_sig / signal), 90.0 * DEG)
    if V is None and moving:
        sigma[:2] *= 3.0
        warnings.append('the base moves and no GNSS velocity covers the coarse window: '
                        'tilt from specific force alone')
    v_end = np.zeros(3) if V is None else V[-1]
    s_carry = 0.0
    if drop:
        v_end, s_carry = _end_velocity(window, lat, h, gnss, C, V, drop, sigma,
                                       noise.accel_bias)
    speed = float(np.hypot(v_end[0], v_end[1]))
    head_src = 'inertial_frame'
    if V is not None and speed >= cfg['track_min_speed_mps']:
        eul = dcm_to_euler(C)
        eul[2] = math.atan2(v_end[1], v_end[0])
        C = euler_to_dcm(eul)
        sigma[2] = cfg['track_heading_sigma_deg'] * DEG
        head_src = 'gnss_track'
    last = gnss.last_fix_until(t_now)
    if last is not None and cfg['use_gnss_position']:
        t_f = last[0]
        R_M, R_N = earth.radii(lat)
        # the antenna's position at the fix, moved to now; then to the IMU
        arm_n = np.zeros(3) if install is None else C @ install.l_v
        lat += (v_end[1] * (t_now - t_f) - arm_n[1]) / (R_M + h)
        lon += (v_end[0] * (t_now - t_f) - arm_n[0]) / ((R_N + h) * math.cos(lat))
        h -= arm_n[2]
    info.update({'velocity_source': v_src, 'heading_source': head_src, 'speed_mps': speed,
                 'steady_velocity': bool(steady), 'gnss_velocity_outliers': len(drop)})
    if drop:
        warnings.append(f'{len(drop)} GNSS velocity message(s) of the coarse window left out: '
                        f'the IMU contradicts them by more than {OUTLIER_SIGMAS:g} sigma')
    s_v = 0.5 if v_sig is None else math.hypot(max(2.0 * v_sig, 0.02), s_carry)
    v_start = None if V is None else (V.mean(axis=0) if steady else V[0])
    return CoarseResult(C, sigma, np.array([lat, lon, h]), v_end, s_v, info, warnings,
                        v_n_start=v_start), info, None


def velocity_outliers(window, lat, h, gnss, V, v_sig, arm_b=None):
    """Stamps of the window's gnss/vel messages that the IMU contradicts (frozenset).

    A first inertial-frame fit with every message (``V`` (N, 3) the GNSS velocity at
    the window's samples) gives the attitude; with it the IMU's own velocity change
    (:func:`~sins_align_ros.nav.coarse.velocity_change_n`, of the antenna with
    ``arm_b``) is taken off each message. What is left is the start velocity plus a
    slow drift (the fit's tilt error, the sensor biases), the fit's heading error and
    the accelerometers' scale factors times that velocity change, plus the GNSS noise: a
    message whose difference leaves this trend (:func:`trend_outliers`, the IMU's
    horizontal velocity change as regressors) is an outlier. (Without the velocity
    change's terms a MEMS car starting to drive at the window's end left the quadratic
    by more than 5 x its RTK 0.02 m/s: 8-9 genuine messages of car_rtk's seeds 1 and 4
    were left out.) A receiver's glitch at the window's end
    would otherwise become the fine filter's initial velocity, which the GNSS gate then
    rejects epoch after epoch, or which turns the heading by tens of degrees (seed
    004's severe sea with 5 % outliers, bench/results/integrity.md).
    """
    tt, dth, dvv, dts = window
    tv, Vg = gnss.velocity_epochs(tt)
    if len(tv) < MIN_EPOCHS_SCREENED:
        return frozenset()
    C = coarse.inertial_frame(dth, dvv, dts, lat, h, dv_n=V - V[0], arm_b=arm_b)
    if degenerate(C):
        return frozenset()
    dv_imu = coarse.velocity_change_n(dth, dvv, dts, lat, h, C, arm_b)
    k = np.clip(np.searchsorted(tt, tv), 0, len(tt) - 1)
    out = trend_outliers(tv, Vg - dv_imu[k], v_sig, X=dv_imu[k][:, :2])
    if not out.any() or out.mean() > MAX_OUTLIER_SHARE:
        return frozenset()
    return frozenset(float(v) for v in tv[out])


def trend_outliers(t, r, sigma, k=OUTLIER_SIGMAS, degree=2, passes=5, X=None):
    """Rows of ``r`` (M, 3) off a smooth trend in ``t`` (M,): (M,) bool.

    Per axis a polynomial of ``degree`` in ``t``, plus the columns of ``X`` (M, p) when
    given (regressors every axis shares), is fitted by least squares to the rows not yet
    judged outliers; a row is an outlier when it leaves the fit by more than ``k`` times
    the larger of ``sigma`` and the robust scatter (1.4826 x the median absolute
    residual) of the kept rows, on any axis. Repeated until nothing changes.
    """
    x = (t - t.mean()) / max(float(np.ptp(t)), 1e-9)
    A = np.vander(x, degree + 1)
    if X is not None:
        X = np.asarray(X, dtype=float)
        A = np.column_stack([A, X / np.maximum(np.abs(X).max(axis=0), 1e-9)])
    out = np.zeros(len(t), dtype=bool)
    for _ in range(passes):
        coef = np.linalg.lstsq(A[~out], r[~out], rcond=None)[0]
        res = r - A @ coef
        scatter = 1.4826 * np.median(np.abs(res[~out]), axis=0)
        new = np.any(np.abs(res) > k * np.maximum(sigma, scatter), axis=1)
        if np.array_equal(new, out) or new.mean() > 0.5:
            break
        out = new
    return out


def _end_velocity(window, lat, h, gnss, C, V, drop, sigma, accel_bias):
    """IMU velocity at the window's end (3,) when outliers were left out near it, and its sigma.

    The last kept message at or before the end, carried to the end by the IMU's
    velocity change (attitude ``C`` at the end): interpolating across a dropped message
    at the window's end would hold a value up to a GNSS interval old (1.4 m/s of heave
    change in 1 s on seed 004's sea). ``V`` (N, 3): the (kept, IMU's) velocity at the
    window's samples. Returns ``(v_end, s_carry)``: ``s_carry`` (m/s, per axis) what the
    carry over the ``dt`` seconds since that message may have added, with the fit's
    attitude sigma ``sigma`` (3,) rad and the accelerometer bias (m/s^2): the heading
    error turns the horizontal velocity change ``dv`` by up to ``|dv| min(sigma_psi,
    1)``, a tilt error adds ``g sigma_tilt dt`` and the bias ``b dt`` (summed: their
    signs are unknown). 0 where nothing was carried. (A MEMS car starting to drive,
    RTK velocities of 0.02 m/s: messages at the window's end left out, 0.77 m/s carried
    under a claimed 0.04 m/s; the fine filter's gate refused the next fixes, then took
    one by force and turned 7 deg of pitch, 6 sigma.)
    """
    tt, dth, dvv, dts = window
    kept = [s for s in gnss.velocity_stamps(tt, drop) if s <= tt[-1]]
    if not kept or max(drop) <= kept[-1]:
        return V[-1], 0.0
    k = int(min(np.searchsorted(tt, kept[-1]), len(tt) - 1))
    dv_imu = coarse.velocity_change_n(dth, dvv, dts, lat, h, C)
    dv = dv_imu[-1] - dv_imu[k]
    dt = float(tt[-1] - tt[k])
    s_carry = (math.hypot(dv[0], dv[1]) * min(float(sigma[2]), 1.0)
               + (earth.gravity(lat, h) * float(max(sigma[0], sigma[1])) + accel_bias) * dt)
    return V[k] + dv, s_carry


def _arm_to_imu(window, lat, h, gnss, sigmas, cfg, install, V, drop=frozenset()):
    """Coarse attitude with a GNSS lever arm, and the IMU's velocity at stamps ``tt`` (N, 3).

    The fit (:func:`~sins_align_ros.nav.coarse.inertial_frame` with ``arm_b``) at the
    samples of the GNSS velocity stamps, where the antenna's velocity is measured rather
    than interpolated across its sway. Its attitude, with the heading of the IMU's track
    when the base moves fast enough (the fit's own heading is weak on a moving base),
    gives the arm's velocity at every sample; that is taken off each GNSS velocity at
    its own stamp before the velocity is interpolated to the samples
    (:data:`ARM_PASSES` times). Returns ``(C_b_n, V)``.
    """
    tt, dth, dvv, dts = window
    stamps = gnss.velocity_stamps(tt, drop)
    e = np.unique(np.clip(np.searchsorted(tt, stamps - 1e-6), 0, len(tt) - 1))
    e = e[e >= len(tt) // 10]
    if len(e) < 3:
        e = None
    C = coarse.inertial_frame(dth, dvv, dts, lat, h, dv_n=V - V[0], arm_b=install.l_v,
                              epochs=e)
    if degenerate(C):
        return C, V
    C_head = C
    for _ in range(ARM_PASSES):
        arm_n = install.window_arm_velocity_n(C_head, dth, dts)

        def to_imu(t_v, V_v, arm_n=arm_n):
            return V_v - np.column_stack([np.interp(t_v, tt, arm_n[:, i]) for i in range(3)])

        V = gnss.velocity_over(tt, *sigmas, correct=to_imu, drop=drop)[0]
        if math.hypot(V[-1, 0], V[-1, 1]) >= cfg['track_min_speed_mps']:
            eul = dcm_to_euler(C)
            eul[2] = math.atan2(V[-1, 1], V[-1, 0])
            C_head = euler_to_dcm(eul)
    return C, V


def _info(method, moving, rate_sc, tilt_sc, T):
    return {'method': method, 'motion_detected': moving, 'rate_scatter_dph': rate_sc / DPH,
            'tilt_scatter_urad': tilt_sc * 1e6, 'duration_s': T}

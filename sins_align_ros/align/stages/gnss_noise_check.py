"""The GNSS noise model against the fixes of the coarse window (part of :mod:`.self_check`).

* **GNSS noise**: the third differences of the fixes in the coarse window (horizontal
  position, height, and the GNSS velocity when it comes) show the receiver's noise the same
  way (a vehicle's jerk hardly enters them at 1-10 Hz); a robust (median) estimate
  ignores the few epochs where a manoeuvre starts. Where it is more than
  :data:`~.noise_estimates.NOISE_RATIO` times the configured (or the receiver's
  reported) sigma, the sigma is widened to it (and reported covariances, then shown to
  be too small, are no longer used). On a still base and on a moving one alike.
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
"""
import math

import numpy as np

from ...nav import earth
from ...nav.coarse import arm_velocity_b0, velocity_integral_b0
from .arm_check import fit_lever_arm, levelling
from ..inputs.gnss_fix import gnss_sigma, uses_reported_covariance
from .noise_estimates import DIFF_ORDER, NOISE_RATIO, robust_difference_sigma

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
#: a lever arm fit beyond this chi-square (3 degrees of freedom, about 6 sigma; no-arm
#: ships, USVs and cars with the arm right give 1-5) replaces the configured arm
ARM_CHI2 = 50.0


def velocity_jitter(dth, dvv, dts, chunk_s=JITTER_CHUNK_S):
    """1-sigma (m/s per horizontal axis) of the velocity jitter of IMU samples; module docstring.

    ``dth``, ``dvv`` (N, 3) increments, ``dts`` (N,) intervals. The specific force
    integrated in the initial body frame (:func:`~sins_align_ros.nav.coarse.velocity_integral_b0`),
    levelled by its own gravity integral, less its best quadratic over each ``chunk_s``
    seconds; the median over the pieces of their horizontal mean square (a piece with a
    manoeuvre's jerk is one of many), divided by the share of a jitter's variance the fit
    leaves: the white ``m - 3`` where the residuals are white, more where they are
    correlated (a Gauss-Markov jitter whose ``phi`` gives the residuals' median lag-1
    autocorrelation, :func:`kept_share`: a vibration correlated over 0.3 s loses a third
    of its variance to a 2-s quadratic, and read as white it hid a 0.109 m/s jitter as
    0.07). White accelerometer noise of density ``q`` leaves about ``0.2 q sqrt(chunk_s)``.
    NaN with fewer than 5 pieces.
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
    lag0 = np.sum(horiz * horiz, axis=(1, 2))
    lag1 = np.sum(horiz[:, 1:] * horiz[:, :-1], axis=(1, 2))
    rho = float(np.median(lag1[lag0 > 0] / lag0[lag0 > 0])) if np.any(lag0 > 0) else 0.0
    kept = kept_share(np.linalg.qr(A)[0], rho, math.exp(-1.0 / (JITTER_TAU_MAX_SHARE * m)))
    return math.sqrt(float(np.median(lag0)) / (2.0 * kept))


#: the longest correlation time :func:`velocity_jitter` reads as a jitter, as a share of its
#: pieces (2 s: 1 s); smoother residuals are read as before, as white (:func:`kept_share`)
JITTER_TAU_MAX_SHARE = 0.5


def gm_shares(phi, Q):
    """Return the expected sums of a unit Gauss-Markov residual after a least-squares fit.

    ``phi`` the correlation from one sample to the next, ``Q`` (m, p) an orthonormal
    basis of the fitted columns (the residual is ``(I - Q Q^T) x``). Returns
    ``(trace, lag1)``: ``E[sum r_i^2]`` and ``E[sum r_i r_i+1]``, i.e. ``tr(A C A)`` and
    the sum of its first superdiagonal, ``A = I - Q Q^T``, ``C_ij = phi^|i - j|``, from
    ``C Q`` alone (``tr = m - tr(Q^T C Q)``). White noise (``phi`` 0): ``(m - p, ...)``.
    """
    m = len(Q)
    if not phi > 0.0:
        return float(m - Q.shape[1]), float(-np.sum(Q[:-1] * Q[1:]))
    G = ar1_product(phi, Q)
    M = Q.T @ G
    lag1 = ((m - 1) * phi - float(np.sum(Q[:-1] * G[1:])) - float(np.sum(G[:-1] * Q[1:]))
            + float(np.sum((Q[:-1] @ M) * Q[1:])))
    return m - float(np.trace(M)), lag1


def ar1_product(phi, Q):
    """Return ``C Q`` (m, p) for ``C_ij = phi^|i - j|`` without forming C (m, m).

    ``C q`` is a forward and a backward first-order recursion less the diagonal counted
    twice: ``f_i = q_i + phi f_(i-1)``, ``b_i = q_i + phi b_(i+1)``, ``(C q)_i = f_i + b_i -
    q_i``; each recursion as a doubling scan (:func:`_ar1_scan`, numpy only: a replay
    imports no scipy). O(m p log m) instead of O(m^2 p): a 2-s piece at 1 kHz is m = 2000,
    whose C took 0.09 s a bisection step, and :func:`kept_share`'s 45 steps held a live
    node's catch-up for 4 s (test_velocity_jitter holds it equal to the dense product).
    """
    Q = np.asarray(Q, dtype=float)
    return _ar1_scan(phi, Q) + _ar1_scan(phi, Q[::-1])[::-1] - Q


def _ar1_scan(phi, x):
    """Return ``f`` (m, p) with ``f_i = x_i + phi f_(i-1)``, ``f_0 = x_0``, by doubling.

    After the step of span ``s`` each ``f_i`` holds ``sum_(j<2s) phi^j x_(i-j)``; the spans
    double until they cover the rows (Hillis-Steele prefix scan, about log2(m) steps).
    """
    f, s, c = x.copy(), 1, float(phi)
    while s < len(f) and c != 0.0:
        g = f.copy()
        g[s:] += c * f[:-s]
        f, s, c = g, 2 * s, c * c
    return f


def kept_share(Q, rho, phi_max):
    """Return ``E[sum r^2] / sigma^2`` of the Gauss-Markov jitter whose residual shows ``rho``.

    ``rho``: the residuals' lag-1 autocorrelation (measured); the jitter's ``phi`` is the
    one whose expected ratio ``lag1 / trace`` (:func:`gm_shares`) equals it, by bisection
    (the ratio grows with ``phi``). White residuals (``rho`` at or below the white ratio)
    keep the white share ``m - p`` exactly, and so do residuals smoother than a jitter
    correlated over ``phi_max``: a velocity random walk (white accelerometer noise, which
    the filters model as such) or a manoeuvre the quadratic does not follow, which are no
    vibration to correct for (the cars' and ships' pieces: their readings unchanged).
    """
    tr0, lag0 = gm_shares(0.0, Q)
    if not rho > lag0 / tr0:
        return tr0
    tr_hi, lag_hi = gm_shares(phi_max, Q)
    if rho >= lag_hi / tr_hi:
        return tr0
    lo, hi = 0.0, phi_max
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        tr, lag = gm_shares(mid, Q)
        lo, hi = (mid, hi) if lag / tr < rho else (lo, mid)
    return gm_shares(0.5 * (lo + hi), Q)[0]


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
    takes (as the check has left it) and more than :data:`~.noise_estimates.NOISE_RATIO` times the
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

"""Report figure of a replay: roll, pitch, yaw (or their error against truth) with +/-3 sigma."""
import numpy as np

from ..nav.frames import euler_error, quat_to_euler

#: truth is not interpolated across an interval longer than this many times its median
MAX_TRUTH_GAP = 5.0


def truth_euler_at(t, t_truth, q_truth):
    """Truth Euler angles (N, 3) rad at stamps ``t`` (N,), interpolated between the samples.

    ``t_truth`` (M,) stamps and ``q_truth`` (M, 4) quaternions (x, y, z, w) of the truth
    (the simulator's 10 Hz ``sim/truth``). The attitude at each stamp comes from a cubic
    rotation spline through the truth samples (scipy's ``RotationSpline``: continuous
    angular rate, no Euler wrap or gimbal issue). Taking the last earlier sample instead
    put a 100 Hz row up to 0.1 s of a swaying ship's motion off (its roll error swung past
    4'); a slerp between neighbours still leaves the sway's curvature, A w^2 dt^2 / 8
    (0.5' on a 4 deg / 5 s roll at 10 Hz). Stamps outside the truth's span, or inside an
    interval longer than :data:`MAX_TRUTH_GAP` times the median one, get NaN.
    """
    from scipy.spatial.transform import Rotation, RotationSpline

    t = np.asarray(t, dtype=float)
    tt = np.asarray(t_truth, dtype=float)
    qq = np.asarray(q_truth, dtype=float).reshape(-1, 4)
    out = np.full((len(t), 3), np.nan)
    keep = np.r_[True, np.diff(tt) > 0.0] if len(tt) else np.zeros(0, bool)
    tt, qq = tt[keep], qq[keep]
    if len(tt) < 2:
        at = np.abs(t - tt[0]) <= 1e-9 if len(tt) else np.zeros(len(t), bool)
        out[at] = quat_to_euler(qq[0]) if len(tt) else np.nan
        return out
    k = np.clip(np.searchsorted(tt, t, side='right') - 1, 0, len(tt) - 2)
    gap = MAX_TRUTH_GAP * float(np.median(np.diff(tt)))
    ok = (t >= tt[0]) & (t <= tt[-1]) & (tt[k + 1] - tt[k] <= gap)
    if np.any(ok):
        q = RotationSpline(tt, Rotation.from_quat(qq))(t[ok]).as_quat()
        out[ok] = quat_to_euler(q)
    return out


def plot_report(path, out, truth_euler=None, title=''):
    """Write a PNG with one panel per angle.

    ``out`` is a pipeline Output; ``truth_euler`` (N, 3) rad at the output stamps
    (:func:`truth_euler_at`; NaN where unknown), when given, turns the
    panels into the error against truth with the +/-3 sigma band around zero;
    otherwise each panel shows the estimate with its +/-3 sigma band.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    ok = np.isfinite(out.q[:, 0])
    t = out.t - out.t[0]
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    names = ('roll', 'pitch', 'yaw')
    for k, ax in enumerate(axes):
        sig3 = 3.0 * np.degrees(out.sigma[ok, k])
        if truth_euler is not None:
            e = np.degrees(euler_error(out.euler[ok, k], truth_euler[ok, k])) * 60.0
            ax.plot(t[ok], e, lw=0.8, label=f'{names[k]} error')
            ax.fill_between(t[ok], -sig3 * 60, sig3 * 60, alpha=0.25, label='+/-3 sigma')
            ax.set_ylabel(f'{names[k]} error (arcmin)')
            lim = np.nanpercentile(np.abs(sig3[len(sig3) // 10:]) * 60, 95) * 2 if len(sig3) else 1
            ax.set_ylim(-max(lim, 1e-3), max(lim, 1e-3))
        else:
            v = np.degrees(out.euler[ok, k])
            ax.plot(t[ok], v, lw=0.8, label=names[k])
            ax.fill_between(t[ok], v - sig3, v + sig3, alpha=0.25, label='+/-3 sigma')
            ax.set_ylabel(f'{names[k]} (deg)')
            if len(v):
                c = v[-1]
                span = max(3 * np.median(sig3[len(sig3) // 2:]) if len(sig3) else 1.0, 0.01)
                ax.set_ylim(c - 4 * span, c + 4 * span)
        ax.grid(True, alpha=0.3)
        ax.legend(loc='upper right', fontsize=8)
    phases = out.phase
    for k in range(1, len(phases)):
        if phases[k] != phases[k - 1]:
            for ax in axes:
                ax.axvline(t[k], color='k', lw=0.6, ls=':')
            axes[0].annotate(str(phases[k]), (t[k], 1.0), xycoords=('data', 'axes fraction'),
                             fontsize=8, va='bottom')
    axes[-1].set_xlabel('time since start (s)')
    fig.suptitle(title or 'sins_align_ros replay')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)

"""Report figure of a replay: roll, pitch, yaw (or their error against truth) with +/-3 sigma."""
import numpy as np

from ..nav.frames import euler_error


def plot_report(path, out, truth_euler=None, title=''):
    """Write a PNG with one panel per angle.

    ``out`` is a pipeline Output; ``truth_euler`` (N, 3) rad, when given, turns the
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

"""One alignment session: the only place that turns sensor input into pipeline calls.

The alignment node (one message at a time), the replay tool (a recording), the
benchmarks and the tests all drive an :class:`AlignmentSession`, so the rules
below are written once:

* every IMU sample passes :class:`~.imu_input.ImuInput` (bad values, stamps,
  gaps, bridges); its first sample starts the pipeline's clock (START), a gap or
  a clock jump back restarts the alignment from that sample (RESET), a bridged
  interval widens the fine filter's covariance by what the bridge may leave;
* every GNSS fix and velocity passes :class:`~.gnss_input.GnssInput` and goes to
  the pipeline only when accepted;
* a restart (reset, new parameters, an input RESET) builds a new pipeline that
  inherits the GNSS position history of the old one.

Samples can be given one at a time (``block=1``: each call returns the rows of
what it processed, the live node's path) or buffered (``block > 1``: accepted
samples are fed to the pipeline in blocks of that size, and the buffer is fed
before anything that must happen between two samples: a GNSS message, a bridge,
a restart). Either way every call returns an :class:`~.output.Output` (possibly
empty) with the rows it produced.
"""
import math
from dataclasses import dataclass

import numpy as np

from . import params as prm
from .inputs.gnss_input import GnssInput
from .inputs.imu_input import OK, RESET, SKIP, ImuInput
from .output import Output
from .pipeline import AlignmentPipeline
from ..units import DEG


@dataclass
class ImuVerdict:
    """What the input checks made of the last IMU sample: ``accepted`` (used), ``action``."""

    action: int = SKIP

    @property
    def accepted(self):
        return self.action == OK


class AlignmentSession:
    """Input checks + pipeline; see the module docstring.

    Parameters
    ----------
    values : dict
        Alignment parameters by name (validated; missing ones take defaults).
    block : int
        1: feed each accepted IMU sample at once; N > 1: buffer N samples.
    """

    def __init__(self, values=None, block=1):
        self.values = prm.validate(values or {})
        full = prm.defaults()
        full.update(self.values)
        self.block = int(block)
        self.pipeline = AlignmentPipeline(self.values)
        self.imu_input = ImuInput.from_params(full)
        self.gnss_input = GnssInput()
        #: restarts since the last :meth:`pop_events`: ``(level, text)``
        self.events = []
        self.last = ImuVerdict()
        #: buffered accepted samples: ``(t, dtheta, dv)`` of one sample or of a run
        self._buf = []
        self._n_buf = 0

    # -- parameters and restarts -------------------------------------------------------
    def restart(self, reason, level='info', values=None, restart_clock=True):
        """Start a new pipeline (with new parameter ``values`` if given), keeping GNSS history.

        Returns the rows of samples still buffered, processed by the old pipeline.
        """
        out = self._drain()
        if values is not None:
            self.values = prm.validate(values)
            full = prm.defaults()
            full.update(self.values)
            self.imu_input.set_params(full)
        old = self.pipeline
        self.pipeline = AlignmentPipeline(self.values)
        self.pipeline.inherit_gnss(old)
        if restart_clock:
            self.imu_input.restart()
        self.events.append((level, f'alignment restarted: {reason}'))
        return out

    def pop_events(self):
        """Return and clear the restarts recorded since the last call."""
        out, self.events = self.events, []
        return out

    def notices(self):
        """Return and clear the input notices as ``(source, key, text)``, source imu or gnss."""
        if not (self.imu_input.notices or self.gnss_input.notices):
            return []                     # the usual call: nothing new
        return ([('imu', k, s) for k, s in self.imu_input.pop_notices()]
                + [('gnss', k, s) for k, s in self.gnss_input.pop_notices()])

    # -- input ---------------------------------------------------------------------------
    def imu(self, t, w_b, f_b):
        """Take one IMU sample: stamp (s), rate (3,) rad/s, specific force (3,) m/s^2."""
        action, dtheta, dv = self.imu_input.push(t, w_b, f_b)
        self.last = ImuVerdict(action)
        if action == OK:
            before = None
            if self.imu_input.bridge is not None:
                before = self._drain()
                self.pipeline.widen(*self.imu_input.bridge)
            out = self._buffer((t, dtheta, dv), 1)
            return out if before is None else Output.concat([before, out])
        if action == SKIP:
            return Output.empty()
        out = self._drain()
        if action == RESET:
            out = Output.concat([out, self.restart(self.imu_input.last_reason, 'warn',
                                                   restart_clock=False)])
        self.pipeline.start_clock(t)
        return out

    def imu_block(self, t, w_b, f_b, missing=None):
        """Take N IMU samples at once: the same as :meth:`imu` on each, in order.

        ``t`` (N,), ``w_b``, ``f_b`` (N, 3); ``missing`` (N,) bool or None: samples the
        message marked as not provided (counted as :meth:`reject_missing_field`). Runs of
        plain samples pass the checks vectorised (``ImuInput.push_run``); anything else
        goes through :meth:`imu`. Returns the rows produced.
        """
        n = len(t)
        missing = np.zeros(0, bool) if missing is None else np.asarray(missing, dtype=bool)
        holes = np.flatnonzero(missing).tolist() if missing.any() else []
        outs, k, h = [], 0, 0
        while k < n:
            while h < len(holes) and holes[h] < k:
                h += 1
            end = holes[h] if h < len(holes) else n
            if end == k:
                outs.append(self.reject_missing_field())
                k += 1
                continue
            m, dtheta, dv = self.imu_input.push_run(t[k:end], w_b[k:end], f_b[k:end])
            if m:
                self.last = ImuVerdict(OK)
                outs.append(self._buffer((t[k:k + m], dtheta, dv), m))
                k += m
            else:
                outs.append(self.imu(t[k], w_b[k], f_b[k]))
                k += 1
        return Output.concat(outs)

    def reject_imu(self, key, text):
        """Count an IMU message the caller found unusable (wrong frame, missing field)."""
        self.last = ImuVerdict(SKIP)
        self.imu_input.reject(key, text)
        return Output.empty()

    def reject_missing_field(self):
        """Count an IMU message whose rates or accelerations are marked not provided."""
        self.last = ImuVerdict(SKIP)
        self.imu_input.reject_missing_field()
        return Output.empty()

    def fix(self, t, status, lat_deg, lon_deg, h, pos_var=None):
        """Take one GNSS position: NavSatFix status, deg, deg, m; ``pos_var`` (2,) or None."""
        var = self.gnss_input.fix(t, status, lat_deg, lon_deg, h, pos_var)
        if var is False:
            return Output.empty()
        out = self._drain()
        self.pipeline.position_fix(t, lat_deg, lon_deg, h, pos_var=var)
        return out

    def velocity(self, t, v_n, vel_var=None):
        """Take one GNSS ENU velocity: (3,) m/s with ``vel_var`` (2,) or None."""
        var = self.gnss_input.velocity(t, v_n, vel_var)
        if var is False:
            return Output.empty()
        out = self._drain()
        self.pipeline.velocity_fix(t, v_n, vel_var=var)
        return out

    def heading(self, t, yaw, yaw_var=None, has_orientation=True):
        """Take one external heading: the source's REP-103 yaw (rad) and its variance (rad^2).

        ``yaw_var`` None (or implausible): ``heading_sigma_deg`` is used.
        """
        var = self.gnss_input.heading(t, yaw, yaw_var, has_orientation)
        if var is False:
            return Output.empty()
        if var is None:
            var = math.radians(self.pipeline.cfg['heading_sigma_deg']) ** 2
        out = self._drain()
        self.pipeline.heading_fix(t, yaw, var)
        return out

    def finish(self):
        """Process what is buffered and what the pre-processing stage holds (end of input)."""
        return Output.concat([self._drain(), self.pipeline.flush()])

    def _buffer(self, entry, n):
        """Buffer ``n`` accepted samples; feed the buffer once it holds ``block``."""
        self._buf.append(entry)
        self._n_buf += n
        return self._drain() if self._n_buf >= self.block else Output.empty()

    def _drain(self):
        """Feed the buffered samples to the pipeline; returns their rows."""
        if not self._buf:
            return Output.empty()
        if len(self._buf) == 1 and np.ndim(self._buf[0][0]) == 0:
            t, dtheta, dv = self._buf[0]
        else:
            t = np.concatenate([np.atleast_1d(b[0]) for b in self._buf])
            dtheta = np.concatenate([np.reshape(b[1], (-1, 3)) for b in self._buf])
            dv = np.concatenate([np.reshape(b[2], (-1, 3)) for b in self._buf])
        self._buf.clear()
        self._n_buf = 0
        return self.pipeline.feed(t, dtheta, dv)

    # -- read-outs ------------------------------------------------------------------------
    def input_counts(self):
        """Input fault and acceptance counts by source, for diagnostics and summaries."""
        return dict(self.imu_input.counts), dict(self.gnss_input.counts)


def feed_arrays(p, imu, gnss, use_velocity=True, block=100, callback=None, heading=None):
    """Feed whole simulated or recorded increments to pipeline ``p`` in time order.

    ``imu`` has ``t``, ``dtheta``, ``dv`` (N, ...) (increments: they bypass the input
    checks of :class:`AlignmentSession`, which take rates); ``gnss`` has ``t``,
    ``lat``, ``lon`` (rad), ``h``, ``v_n`` (M, 3), ``fix`` (M,) bool and
    ``pos_cov``/``vel_cov`` (ENU variances), or is None. GNSS epochs are given before
    the IMU block that passes their stamps, as a live node would receive them.
    ``callback(p)``, if given, is called after each block (e.g. to record filter
    internals). ``heading``: an external heading's ``t``, ``yaw`` (rad, the source's),
    ``var`` (M,) (``sim.gnss.heading_measurements``), given the same way, or None.
    Returns the :class:`~.output.Output`.
    """
    outs, gi, hi = [], 0, 0
    n_h = 0 if heading is None else len(heading.t)
    n = len(imu.t)
    m = 0 if gnss is None else len(gnss.t)
    for i in range(0, n, block):
        j = min(n, i + block)
        while gi < m and gnss.t[gi] <= imu.t[j - 1] + 1e-9:
            if gnss.fix[gi]:
                p.position_fix(gnss.t[gi], gnss.lat[gi] / DEG, gnss.lon[gi] / DEG, gnss.h[gi],
                               pos_var=np.asarray(gnss.pos_cov)[:2])
                if use_velocity and gnss.v_n is not None:      # None: a position-only receiver
                    p.velocity_fix(gnss.t[gi], gnss.v_n[gi],
                                   vel_var=np.asarray(gnss.vel_cov)[:2])
            gi += 1
        while hi < n_h and heading.t[hi] <= imu.t[j - 1] + 1e-9:
            p.heading_fix(heading.t[hi], heading.yaw[hi], heading.var[hi])
            hi += 1
        outs.append(p.feed(imu.t[i:j], imu.dtheta[i:j], imu.dv[i:j]))
        if callback is not None:
            callback(p)
    outs.append(p.flush())
    return Output.concat(outs)

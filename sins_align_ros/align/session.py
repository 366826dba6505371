"""One alignment session: the only place that turns sensor input into pipeline calls.

The alignment node (one message at a time), the replay tool (a recording), the
benchmarks and the tests (``eval.feed.feed_arrays``) all drive an :class:`AlignmentSession`,
so the rules below are written once:

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

IMU increments that are already integrated (a simulation, a PSINS log) go in through
:meth:`AlignmentSession.increments` as they are, after :meth:`~AlignmentSession.start_clock`:
they bypass the rate checks, since a round trip through rates would change their floats.

What the node shows of a session it reads through the read-outs at the end of the class
(the phase, the status and notes, the input counts, the mounting rotation,
:meth:`~AlignmentSession.navigation`), never through the pipeline's parts.
"""
import math
from dataclasses import dataclass

import numpy as np

from . import params as prm
from .inputs.gnss_input import GnssInput
from .inputs.imu_input import OK, RESET, SKIP, ImuInput
from .output import Output
from .pipeline import AlignmentPipeline


@dataclass
class ImuVerdict:
    """What the input checks made of the last IMU sample: ``accepted`` (used), ``action``."""

    action: int = SKIP

    @property
    def accepted(self):
        return self.action == OK


@dataclass(frozen=True)
class NavReadout:
    """The navigation filter's figures that ``~/odom`` carries beside the output rows.

    ``P_nav`` (9, 9): position, velocity and misalignment error covariance (None: the
    engine does not navigate); ``gyro_bias`` (3,) rad/s: the filter's current estimate;
    ``rate_var``: the gyro white-noise variance per sample, (rad/s)^2 (ARW^2 over the
    nominal IMU interval; 0.01 s until the input checks know that interval).
    """

    P_nav: object
    gyro_bias: object
    rate_var: float


class AlignmentSession:
    """Input checks + pipeline; see the module docstring.

    Parameters
    ----------
    values : dict
        Alignment parameters by name (validated; missing ones take defaults).
    block : int
        1: feed each accepted IMU sample at once; N > 1: buffer N samples.
    pipeline : AlignmentPipeline or None
        Drive this pipeline, one the caller built (and inspects), instead of a new one;
        its parameters are the session's (``values`` is then ignored).
    """

    def __init__(self, values=None, block=1, pipeline=None):
        if pipeline is not None:
            values = pipeline.configured
        self.values = prm.validate(values or {})
        full = prm.defaults()
        full.update(self.values)
        self.block = int(block)
        self.pipeline = AlignmentPipeline(self.values) if pipeline is None else pipeline
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

    def start_clock(self, t0):
        """Set the stamp (s) the first of :meth:`increments` starts from.

        The rate entries (:meth:`imu`, :meth:`imu_block`) start the clock at their first
        sample themselves.
        """
        self.pipeline.start_clock(t0)

    def increments(self, t, dtheta, dv):
        """Take IMU increments as they are: ``t`` (N,) s, ``dtheta`` (N, 3) rad, ``dv`` (N, 3) m/s.

        For data that come integrated (a simulation, a PSINS log): they bypass the rate
        checks of :class:`~.imu_input.ImuInput` (which take rates; a round trip through
        rates would change the floats). Returns the rows produced.
        """
        before = self._drain()
        out = self.pipeline.feed(t, dtheta, dv)
        return out if not len(before) else Output.concat([before, out])

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

    # -- read-outs: what the node shows of the session -----------------------------------
    @property
    def phase(self):
        """One of ``PHASES``: the current pipeline's phase."""
        return self.pipeline.phase

    def status(self):
        """Return the pipeline's key figures for diagnostics (plain Python types)."""
        return self.pipeline.status()

    @property
    def warnings(self):
        """The pipeline's notes so far: its own list (a restart's pipeline starts a new one)."""
        return self.pipeline.warnings

    def conditions(self):
        """Return the new degraded conditions: ``[(level, text)]``, 1 warn, 2 error."""
        return self.pipeline.conditions()

    @property
    def C_s_v(self):
        """The IMU mounting rotation (3, 3), sensor to vehicle frame; None when not told."""
        return self.pipeline.install.C_s_v

    @property
    def imu_accepted(self):
        """IMU samples the input checks accepted since the session started."""
        return self.imu_input.counts['accepted']

    @property
    def imu_rejected(self):
        """IMU samples the input checks (or the caller, :meth:`reject_imu`) skipped."""
        return self.imu_input.rejected

    @property
    def gnss_rejected(self):
        """GNSS messages (fixes, velocities, headings) the input checks skipped."""
        return self.gnss_input.rejected

    def input_counts(self):
        """Input fault and acceptance counts by source, for diagnostics and summaries."""
        return dict(self.imu_input.counts), dict(self.gnss_input.counts)

    def navigation(self):
        """Return the navigation filter's :class:`NavReadout` (rows with ``nav`` only)."""
        pipe = self.pipeline
        dt = self.imu_input.dt_nominal or 0.01
        return NavReadout(pipe.nav_cov(), pipe.engine.gyro_bias, pipe.noise.gyro_arw ** 2 / dt)

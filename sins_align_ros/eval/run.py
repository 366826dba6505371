"""One data set through the alignment pipeline: the output, its truth and its errors.

The recipe every benchmark and accuracy test follows: simulate a named scenario for
a seed (or take a recording), feed it to an
:class:`~sins_align_ros.align.session.AlignmentSession` with
:func:`~.feed.feed_arrays` (the IMU as increments, GNSS epochs before the IMU block
that passes their stamps), and compare the output rows with the truth.
"""
import time
from dataclasses import dataclass
from functools import cached_property
from types import SimpleNamespace

import numpy as np

from ..align import AlignmentPipeline, AlignmentSession, Output
from ..sim.gnss import heading_measurements
from ..sim.presets import alignment_params
from .cache import simulate_cached
from .errors import attitude_errors, final_error, truth_rows
from .feed import feed_arrays
from .scenarios import named, simulate


@dataclass
class Run:
    """A finished pass of the pipeline over ``data``.

    ``out``: the :class:`~sins_align_ros.align.output.Output` (a row per IMU sample);
    ``data``: ``imu`` (t, dtheta, dv and, for simulated data, the truth ``euler``,
    ``v_n``, ``pos`` per sample) and ``gnss``; ``pipeline``: the pipeline after the
    run; ``wall``: seconds spent feeding; ``scenario``: the scenario, when simulated.
    """

    out: object
    data: object
    pipeline: AlignmentPipeline
    wall: float
    scenario: object = None

    @property
    def span(self):
        """Seconds of IMU data."""
        t = self.data.imu.t
        return float(t[-1] - t[0])

    @property
    def speed(self):
        """Speed of the pipeline on these data, times real time."""
        return self.span / self.wall

    @cached_property
    def rows(self):
        """Index of the truth sample (``data.imu``) of each output row."""
        return truth_rows(self.data.imu.t, self.out.t)

    @cached_property
    def truth_euler(self):
        """Truth roll, pitch, yaw (N, 3) at each output row, rad."""
        return self.data.imu.euler[self.rows]

    @cached_property
    def final(self):
        """:class:`~.errors.FinalError` of the last row."""
        return final_error(self.out, self.truth_euler[-1])

    def phi(self, rows):
        """ENU misalignment (len(rows), 3) of output rows ``rows``, NaN where unknown."""
        return attitude_errors(self.out, self.truth_euler, rows)

    @property
    def restarts(self):
        """Times the output went from fine/aligned back to waiting/coarse."""
        ph = self.out.phase
        return int(np.sum(np.isin(ph[1:], ('waiting', 'coarse'))
                          & np.isin(ph[:-1], ('fine', 'aligned'))))

    @property
    def t_fine(self):
        """Stamp of the first fine/aligned row (NaN if none), s."""
        fine = np.flatnonzero(np.isin(self.out.phase, ('fine', 'aligned')))
        return float(self.out.t[fine[0]]) if len(fine) else float('nan')


def run_pipeline(params, data, use_velocity=True, block=100, callback=None, t0=0.0,
                 heading=None):
    """Feed ``data`` to a new ``AlignmentSession(params)`` whose clock starts at ``t0``.

    ``data``: ``imu`` (t, dtheta, dv, ...) and ``gnss`` (epochs or None), as a
    simulation or :func:`~.recordings.fog_data`. ``use_velocity``, ``block`` and
    ``callback`` go to :func:`~.feed.feed_arrays`; ``block`` None feeds the IMU in one
    call (no GNSS allowed); ``heading``: an external heading's epochs (``feed_arrays``).
    Returns a :class:`Run` (its ``pipeline``: the session's at the end).
    """
    session = AlignmentSession(params)
    session.start_clock(t0)
    imu = data.imu
    w0 = time.perf_counter()
    if block is None:
        if data.gnss is not None or heading is not None:
            raise ValueError('block=None feeds the IMU alone: give data without GNSS')
        out = session.increments(imu.t, imu.dtheta, imu.dv)
        rest = session.finish()
        if len(rest.t):
            out = Output.concat([out, rest])
    else:
        out = feed_arrays(session, imu, data.gnss, use_velocity=use_velocity, block=block,
                          callback=callback, heading=heading)
    return Run(out, data, session.pipeline, time.perf_counter() - w0)


def run_scenario(sc, seed, fine_filter, duration=None, cached=False, use_velocity=True,
                 block=100, callback=None, heading_sigma_deg=None, **overrides):
    """Simulate scenario ``sc`` for ``seed`` and run the pipeline on it.

    ``sc``: a :class:`~sins_align_ros.sim.presets.Scenario` or a name for
    :func:`~.scenarios.named` (with ``duration``). The pipeline gets the parameters
    that describe the scenario's sensors (``sim.presets.alignment_params``) with
    ``fine_filter`` and ``overrides``. ``cached``: simulate through
    :func:`~.cache.simulate_cached`. Returns a :class:`Run` (``run.final`` is the
    final error against truth). ``heading_sigma_deg``: add an external heading at 1 Hz
    with that white noise (``sim.gnss.heading_measurements``, its own seeded stream).
    """
    if isinstance(sc, str):
        sc = named(sc, duration)
    elif duration is not None:
        raise ValueError('duration applies to a scenario name only')
    data = simulate_cached(sc, seed) if cached else simulate(sc, seed)
    heading = None
    if heading_sigma_deg is not None:
        rng = np.random.default_rng(np.random.SeedSequence([seed, 23]))
        heading = heading_measurements(data.imu.t, data.imu.euler[:, 2],
                                       np.radians(heading_sigma_deg), 1.0, rng)
    run = run_pipeline(alignment_params(sc, fine_filter, **overrides), data,
                       use_velocity=use_velocity, block=block, callback=callback,
                       heading=heading)
    run.scenario = sc
    return run


def replay_rate(params, data, repeats=3, span=None, **feed):
    """Median x real time of the pipeline on ``data`` over ``repeats`` runs.

    ``span``: seconds the data cover (default: the IMU stamps' span); ``feed``:
    :func:`run_pipeline` keywords (``block``, ``use_velocity``, ``t0``).
    """
    rates = []
    for _ in range(repeats):
        run = run_pipeline(params, data, **feed)
        rates.append((run.span if span is None else span) / run.wall)
    return float(np.median(rates))


def without_gnss(data):
    """Return the IMU part of ``data`` alone (a still-base run that ignores the receiver)."""
    return SimpleNamespace(imu=data.imu, gnss=None)

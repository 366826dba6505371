"""Store and reprocess: the fine stage starts at the coarse window's first sample.

Issue 46. The coarse window's samples used to be thrown away once the coarse attitude was
found: the fine filter began at the window's end and had to gather the same information
again, so a still navigation-grade base that the data had aligned in 20 s waited for the
filter's own 20 s and more. Here the fine stage starts where the window began and runs
over the window's stored samples (:meth:`~.coarse_window.CoarseWindow.arrays`) before it
goes on with the live ones; at the window's end it holds what a filter started at the
first sample would hold. As PSINS's ``CAlignsv`` does with its inertial-frame coarse
alignment (there two samples per incoming sample until it catches up; here at once, the
still-base engine mechanizes whole blocks between its epochs: 60 s at 1 kHz in well
under a second, bench/results/time_to_align.md).

**The prior does not count the samples twice.** The coarse attitude, found from these
samples, is only the point the filter linearises about (moved to the window's start,
:func:`start_of_window`). The filter's initial covariance is :func:`~.coarse_stage.
coarse_sigma` for :data:`PRIOR_SHARE` of the window: three times the 1-sigma that share
of the samples would give, so it claims at most ``PRIOR_SHARE / 9`` of the white-noise
information the filter then takes from the window itself, and often nothing (its floors,
0.5 deg of heading and 0.05 deg of tilt, are far wider than a navigation-grade window
leaves). A test runs the same window with a prior ten times wider: the sigma at the
window's end differs by the prior's share, a few per cent.

**The window's heading is a measurement.** The still-base filter finds the heading from
the tilt drift it causes (``phi_E' = -W cos L phi_U``), read through the accelerometers'
noise: from 20 s of a navigation-grade IMU at 35 deg N that route gives about 22'
(1 sigma), while the window's averaged gyros give the analytic coarse heading to
``ARW / (W cos L sqrt(T))``, 3.7'. Issue 46 holds a still base to the analytic limit for
the data seen, so the stage takes that heading as a measurement at the window's start
(:func:`window_heading`: the filter's attitude there is the analytic one, so the
innovation is zero and only the covariance changes; the biases the heading cannot be told
from at rest are in the measurement row), and the live samples after the window in
segments (:mod:`~..engines.gyrocompass`, which says why no sample is counted twice and
for how long this is done: about 60 s of data at navigation grade, none at tactical).
The variance is the white noise only, with the densities the samples show where they
exceed the configured ones. Where we differ from seed 002: its fine filter starts from
the coarse attitude and has no such measurement. It assumes a base that does not rotate
beyond its gyro noise: a tilt creep the accelerometers cannot see, about 0.8 arcsec a
minute for a navigation-grade gyro at 35 deg N, moves the heading by its 1 sigma over
20 s; a window that shows motion (sway, knocks) takes the inertial-frame fit and gets no
such measurement. test_reprocess holds the heading sigma above the analytic limit of all
the data seen at every aligned row, and its error in sigmas to a chi-square bound.

**What is published is causal.** The rows of the reprocessed samples are not published
again (they went out as ``coarse`` when the samples came); the stage's first published row
is the window's last sample, and a stage that reached ``aligned`` inside the window is
taken as aligned from that row (:attr:`~.fine_stage.FineStage.t_aligned`).

**A long window is caught up over several calls** (:class:`CatchUp`): at most
:data:`CATCH_UP_SAMPLES` stored samples a call, so a live node at 1 kHz is not held for
the whole window (0.7-0.9 s for 60 s, before). The samples that come meanwhile are queued
behind the window and published as ``coarse`` with an unknown attitude (as the window's
were); the pipeline says ``coarse`` and its status ``catching_up``. Once the queue is run
over, the stage's rows are the live ones again. A call that brings more samples than the
window (a replay's block) catches up at once, as before.

**GNSS-aided filters** (:func:`aided_start`, with ``coarse_reprocess_aided``, on by default
since session 47: below) start there too: the moving-base fit turned
back to the window's start, the window's first GNSS velocity and the fix nearest the start
moved to it (antenna to IMU); the pipeline queues the window's fixes again
(:meth:`~..inputs.gnss_buffer.GnssBuffer.requeue`), and the filter takes them as the
stored samples pass their stamps, as it takes live ones. The prior is the coarse sigma,
three times the window's own 1-sigma in each term (the share rule above would put a MEMS
heading from the GNSS track at its 30-deg cap). Measured (bench/results/time_to_align.md,
session 45): the navigation-grade ship under way is `aligned` at 70 s instead of 136 s,
its heading inside 1 deg for good from 81 s instead of 184 s; the MEMS car with RTK 5.4 s
after it starts to drive instead of 17 s. Not where no velocity covers the window (neither
gnss/vel messages nor the seven fixes a slope needs,
:meth:`~..inputs.gnss_buffer.GnssBuffer.velocity_over`) or with ``use_gnss_position``
off: that stage starts at the window's end as before.
**Why it was off by default until session 47**
(bench/results/integrity_aided_reprocess.md, session 45): over the integrity matrix's
GNSS-aided cells (told right and the defaults), 10 cells of 168 that passed failed with
it: seed 003's car at tactical grade (kf, ukf, auto, vbakf, mvbakf; the heading 13-29 % of
rows outside 3 sigma in seeds 1002 and 1008) and at navigation grade
(mvbakf), and mvbakf on the tactical flight (east tilt, 7 %). On the car the heading error
after the drive's manoeuvres is the same with or without it (-0.4 deg at 170 s, seed 1002,
3.4 sigma with it, 2.7 sigma without): the window's information narrows a heading sigma
that was already as narrow as the model allows, so a model error the matrix had only
grazed shows. Two seed-004 USV cells that failed pass with it. Over 100 seeds per cell
(bench/results/reprocess_consistency.md) the two flows fail as often: the ten seeds had
two unlucky ones. The two behaviours found when it was turned on are fixed (a compass
stopped the reprocessing; the mounting check under way judged stale angles,
:mod:`.sideslip`).

Where it applies (:func:`applies`): ``coarse_reprocess``, and ``coarse_reprocess_aided``
for a GNSS-aided filter.

**External headings in the window** (a GNSS compass): the window's heading messages are
queued again (:meth:`~..inputs.heading.HeadingBuffer.requeue`) and taken as the stored
samples pass their stamps, as the fixes are. The coarse heading the last of them set
(turned back to the window's start with the rest of the attitude) only linearises: its
1-sigma is made three times the message's (:data:`HEADING_PRIOR_FACTOR`), so the prior
claims a ninth of the one message it came from, which the filter then takes again.
Before, a compass made the stage start at the window's end: a MEMS car with a 0.2-deg
compass was `aligned` later than without it (59 s against 37 s, session 46).
"""
from dataclasses import replace

import numpy as np

from ...models.stationary import sees_earth_rate
from ...nav import coarse, earth
from ..engines import gyrocompass
from ..inputs.heading import LINEAR_MAX, yaw_of
from .coarse_window import coarse_sigma, seen_noise

#: the prior claims the white-noise information of this share of the window, at 3 sigma
PRIOR_SHARE = 0.1
#: a reprocessing stage's prior heading 1-sigma over the external heading's that set it
HEADING_PRIOR_FACTOR = 3.0


def applies(cfg, aided):
    """Tell whether the fine stage reprocesses the window (module docstring).

    ``cfg``: the parameters (``coarse_reprocess``, and for a GNSS-aided filter, ``aided``,
    ``coarse_reprocess_aided``). A GNSS-aided stage also needs its start
    (:func:`aided_start`).
    """
    return bool(cfg['coarse_reprocess'] and (not aided or cfg['coarse_reprocess_aided']))


def measured_heading_prior(res, measured_sigma):
    """Return the coarse result ``res`` (moved to the window's start) with its heading prior.

    ``measured_sigma`` rad: the 1-sigma of the external heading that set the coarse
    heading. The window's headings are queued again by the pipeline, as its fixes are.
    The module docstring says why (:data:`HEADING_PRIOR_FACTOR`).
    """
    sigma = np.array(res.sigma, dtype=float)
    sigma[2] = HEADING_PRIOR_FACTOR * measured_sigma
    return replace(res, sigma=sigma)


def prior_sigma(noise, T, lat, moving, sigma):
    """Return the reprocessing prior (3,) rad of a window of ``T`` s (module docstring).

    :func:`~.coarse_window.coarse_sigma` for :data:`PRIOR_SHARE` of the window (``noise``
    the sensor model, ``lat`` rad, ``moving`` the window showed motion), never narrower
    than the coarse result's own ``sigma`` (3,).
    """
    return np.maximum(coarse_sigma(noise, PRIOR_SHARE * T, lat, moving)[0], sigma)


def start_of_window(res, window, noise, method):
    """Return the coarse result ``res`` moved to the window's start, with the prior's sigma.

    ``window``: the coarse window's arrays; ``noise`` the sensor model (NoiseSpec);
    ``method``: the coarse method that ran. The analytic (TRIAD) attitude is the
    window's mean on a base that does not turn, the same at its start; the inertial-frame
    one is the fit at the window's end, turned back by the gyros and the Earth
    (:func:`~sins_align_ros.nav.coarse.attitude_at_start`). Returns a new
    :class:`~.coarse_stage.CoarseResult`.
    """
    tt, dth, dvv, dts = window
    lat = float(res.position[0])
    C = res.C_b_n
    if method != 'analytic':
        C = coarse.attitude_at_start(C, dth, dts, lat)
    moving = bool(res.info.get('motion_detected', False))
    return replace(res, C_b_n=C,
                   sigma=prior_sigma(noise, float(np.sum(dts)), lat, moving, res.sigma))


def aided_start(res, window, gnss, cfg, install=None):
    """Return the moving-base coarse result ``res`` moved to the window's start, or None.

    ``window``: the coarse window's arrays; ``gnss`` the pipeline's
    :class:`~..inputs.gnss_buffer.GnssBuffer`; ``install`` the
    :class:`~.installation.Installation` (its lever arm). The attitude is the fit turned
    back by the gyros, the Earth and the frame's turn over the ground
    (:func:`~sins_align_ros.nav.coarse.attitude_at_start`, the transport rate of the mean
    of the start and end velocities: 3.4' of tilt per axis over 60 s at 150 m/s, which
    put seed 001's tactical flight 3 sigma off in east tilt); the velocity the window's GNSS
    velocity at its first sample (``res.v_n_start``); the position the fix nearest the
    start, moved to it with that velocity and from the antenna to the IMU. The prior is
    the coarse sigma, which is three times the 1-sigma the window's data give in each of
    its terms (:func:`~.coarse_window.coarse_sigma`, the GNSS velocity's term of
    :func:`~.coarse_stage.moving_base`), so it claims at most a ninth of the information
    the filter then takes from the same samples (the module docstring); a heading from
    the GNSS track keeps the track's sigma (``track_heading_sigma_deg``: the course, not
    the IMU's samples; :func:`prior_sigma`'s share of the window would put a MEMS heading
    at its 30-deg cap, and the real fog_mems car's asckf heading sigma ended at 16 deg
    instead of 6). None (the stage starts at the window's end): no velocity (gnss/vel or
    from the fixes) covered the window, no fix, or ``use_gnss_position`` off.
    """
    if res.v_n_start is None or not cfg['use_gnss_position']:
        return None
    tt, dth, dvv, dts = window
    t0 = float(tt[0] - dts[0])
    fix = gnss.fix_nearest(t0)
    if fix is None:
        return None
    t_f, lat, lon, h = fix
    v0 = np.asarray(res.v_n_start, dtype=float)
    w_en = earth.w_en_n(lat, h, 0.5 * (v0 + np.asarray(res.v_n, dtype=float)))
    C = coarse.attitude_at_start(res.C_b_n, dth, dts, lat, w_en)
    arm_n = np.zeros(3) if install is None or install.no_arm else C @ install.l_v
    # the ENU offset (m) from the fix to the IMU at the start, as a geodetic change
    position = np.array([lat, lon, h]) + earth.position_rate(lat, h, v0 * (t0 - t_f) - arm_n)
    return replace(res, C_b_n=C, v_n=v0, position=position)


def gyrocompass_plan(noise, lat, T, moving=False):
    """Return ``(var, rate_var, span)`` of a window's gyrocompass heading, or None.

    ``noise``: the sensor model with the densities the samples show
    (:func:`~.coarse_window.seen_noise`); ``lat`` rad; ``T`` s the window; ``moving``: it
    showed motion. ``var`` rad^2: the heading's white-noise variance
    (:func:`~..engines.gyrocompass.heading_variance_rate` over ``T``); ``span`` s: the
    data over which such headings may be taken (:func:`~..engines.gyrocompass.gyro_span`).
    None: a window that moved (a turning base's averaged gyros are no heading), a gyro that
    cannot see Earth rate, a window longer than the span (the filter's own route to the
    heading is the better one there: tactical grade), or a heading beyond the linear model
    (:data:`~..inputs.heading.LINEAR_MAX`).
    """
    if moving or not sees_earth_rate(lat, noise):
        return None
    rate_var = gyrocompass.heading_variance_rate(noise, lat)
    span = gyrocompass.gyro_span(noise, lat)
    var = rate_var / T
    if var > LINEAR_MAX ** 2 or T > span:
        return None
    return var, rate_var, span


def window_plan(window, noise, lat, method, moving):
    """Return :func:`gyrocompass_plan` of the coarse ``window`` (see :func:`window_heading`).

    ``noise`` the sensor model, ``lat`` rad, ``method`` the coarse method that ran,
    ``moving`` its window showed motion. None where no gyrocompass heading is taken: an
    inertial-frame fit, or the plan says no.
    """
    if method != 'analytic':
        return None
    return gyrocompass_plan(seen_noise(window, noise), lat, float(np.sum(window[3])), moving)


def window_heading(fine, C_b_n, window, plan, lat):
    """Give a still-base stage the window's gyrocompass heading and live segments.

    ``fine``: the stage at the window's start; ``C_b_n`` (3, 3): the analytic coarse
    attitude of the window (the gyros and accelerometers averaged); ``plan``: the window's
    :func:`window_plan` (not None), with the noises the samples show where they exceed the
    configured ones (:func:`~.coarse_window.seen_noise`); ``lat`` rad. The heading is one
    measurement (:meth:`~..engines.stationary.StationaryEngine.gyrocompass_update`, the
    biases in its row). The live samples after the window (``skip`` the window's samples,
    which :class:`CatchUp` runs next) give more such headings in segments
    (:class:`~..engines.gyrocompass.GyroSegments`). Returns the heading's 1-sigma (rad).
    """
    T = float(np.sum(window[3]))
    var, rate_var, span = plan
    fine.engine.gyrocompass_update(yaw_of(C_b_n), var)
    fine.engine.gyro_segments = gyrocompass.GyroSegments(rate_var, lat, span - T, skip=T)
    return float(np.sqrt(var))


#: most stored samples the stage runs over in one call of the pipeline (unless the call
#: itself brings more): 20 s of a 1 kHz IMU, about 0.13 s of work (0.38 s for 60 s in
#: process, bench/results/node_catch_up.md), so a live node's IMU callback is never held
#: longer; no window at 100 Hz or below is split
CATCH_UP_SAMPLES = 20000


class CatchUp:
    """The stored samples a reprocessing stage has still to run over (module docstring).

    ``window``: the coarse window's arrays; the live samples that come while it catches up
    are appended (:meth:`add`) and published as ``coarse``, unknown attitude, as the
    window's own were: the stage's estimate is not the current one until it has caught up.
    """

    def __init__(self, window):
        tt, dth, dvv, _ = window
        #: the samples not yet run over, in parts (stored, then live ones as they come)
        self._parts = [(tt, dth, dvv)]

    def add(self, t, dtheta, dv):
        """Queue live samples ``t`` (N,), ``dtheta``, ``dv`` (N, 3) behind the stored ones."""
        if len(t):
            self._parts.append((t, dtheta, dv))

    @property
    def t_last(self):
        """Stamp of the last queued sample (s)."""
        return float(self._parts[-1][0][-1])

    @property
    def left_s(self):
        """Seconds of queued samples not yet run over."""
        return float(self._parts[-1][0][-1] - self._parts[0][0][0])

    def run(self, fine, gnss, budget=CATCH_UP_SAMPLES):
        """Run ``fine`` over at most ``budget`` queued samples: ``(done, diverged reason)``.

        ``gnss``: the pipeline's GNSS history (the rest watch reads its last fix). Rows are
        dropped; a stage that reached ``aligned`` while catching up counts from the last
        sample run over when it has caught up (the first row it publishes).
        """
        parts = self._parts
        tt, dth, dvv = parts[0] if len(parts) == 1 else (np.concatenate(a) for a in zip(*parts))
        end, i = min(len(tt), int(budget)), 0
        while i < end:
            _, i, reason = fine.run(tt[:end], dth[:end], dvv[:end], i, gnss)
            if reason is not None:
                return True, reason
        # what is left, stored then live samples, as one part (the samples run over dropped)
        self._parts = [(tt[i:], dth[i:], dvv[i:])]
        done = i >= len(tt)
        if done and fine.t_aligned is not None:
            fine.t_aligned = max(fine.t_aligned, float(tt[-1]))
        return done, None

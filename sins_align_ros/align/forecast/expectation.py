"""What to expect: the 1-sigma per axis when ``aligned`` comes, and when it comes.

Users ask before they start how long alignment will take and how good it will be. The
answer is a forecast of the attitude covariance under the pipeline's own rules
(:class:`~.convergence.ConvergenceMonitor`, the ``aligned_max_*_sigma_deg`` bounds), made in
one of two ways, by what that covariance depends on:

* **Still base** (the stationary filters). Zero-velocity measurements of a base at rest
  make the filter's covariance independent of the data, so a *shadow run* forecasts it
  exactly: a copy of the fine stage (before fine alignment: a new one, started from the
  coarse sigma the configured model leaves, :func:`~.coarse_window.coarse_sigma`) fed with
  the increments of a perfectly still IMU at the latitude, with the same convergence rule,
  restaging and bounds. The shadow's filter epochs come every ``1 / SHADOW_HZ`` s (or at the
  filter's own period if slower) with the zero-velocity variance scaled by the ratio of the
  periods, which keeps the measurements' information per second (the continuous-time
  limit); after convergence the steps lengthen to :data:`LATE_STEP_S`. An external heading
  seen recently is replayed at its rate and median variance, the steps kept short (one
  lumped epoch claims more than the epochs it stands for, with the drift between them);
  a stage that reprocesses the window takes the window's headings from its start
  (:func:`_new_stage`), and the sigma forecast is the shadow's at the stage's first row.
* **Moving base, linear filters** (``kf`` and the navigation family: ``forecast_model`` of
  the engine). A linear filter's covariance does not depend on the measured values, only
  on its model: the forecast runs the filter's covariance on, epoch after epoch, with the
  transition, process noise and measurement of its last epoch
  (:func:`~.variance.covariance_shadow`), i.e. as if the motion of the last GNSS interval
  went on. A ship accelerating steadily gains heading information faster and faster (its
  heading variance halves every ~10 s late in the manoeuvre), which the variance's own
  trend below cannot foresee and the model's covariance does: ship_underway forecast
  137-140 s from 10 s into fine alignment, actual 136 s (bench/results/expectation.md). A
  change of motion (a car that starts to drive, a turn) changes the forecast when it comes.
* **Moving base, other filters** (the cubature and variational filters on the
  large-azimuth model). The covariance depends on the manoeuvres, which
  no model of the sensors knows in advance: the forecast extrapolates the filter's own
  variance history (:class:`~.sigma_history.SigmaHistory`, the last
  :data:`~.sigma_history.TREND_S` seconds) per axis as a scalar Riccati equation
  ``dP/dt = q - r P^2`` above the sensors' limit: ``q`` the gyro's
  angle random walk and bias drift (configured, self-checked), ``r`` the information rate
  the motion has given lately (fitted), the limit ``P_min`` that of a heading found from
  Earth rate (``eps / (W cos L)``, seed 002 eq. 15) where the gyro can see Earth rate. The
  forecast is that the motion goes on giving what it gave: a vehicle that stops turning
  delays it, more manoeuvres bring it forward; it is updated as the filter runs. Before the
  filter has :data:`TREND_MIN_S` s of history there is no forecast (``unknown``) and the note
  says so.

Both yield an :class:`Expectation`: the expected time (seconds of data from the first
sample) to ``aligned`` and to a ready tilt, and the misalignment 1-sigma (E, N, U) expected
when ``aligned`` comes; or, where the bounds will not be met (a heading limit above
``aligned_max_heading_sigma_deg``, a gyro that cannot see Earth rate at rest), ``inf`` with
the reason and the best 1-sigma expected. This module gathers what a forecast needs from
the pipeline and makes it; the arithmetic on variance curves (the closed forms, the
covariance run on, the pipeline's rules applied to a curve) is :mod:`.variance`.
"""
import copy
import math
from dataclasses import dataclass

import numpy as np

from ...nav import earth
from ...nav.frames import dcm_to_euler, euler_cov_from_phi_cov
from ..stages import coarse_stage, coarse_window
from ..stages.aligned_gate import SETTLE_S
from ..engines.factory import is_aided
from ..engines.gyrocompass import GyroSegments
from ..stages.fine_stage import Clock
from ..stages.handover import fine_stage_for
from ..stages import reprocess
from ..stages.reprocess import prior_sigma
from ..inputs.motion import choose_filter, gnss_motion
from .variance import covariance_shadow, first_aligned, heading_limit_var, process_noise, riccati

#: shadow filter epochs per second (still base)
SHADOW_HZ = 1.0
#: shadow step once the stage has converged (the monitor no longer looks), s
LATE_STEP_S = 10.0
#: how far ahead a forecast looks, s
HORIZON_S = 3600.0
#: a still-base forecast is made again after this much data (a widening, a heading source)
REFRESH_S = 30.0
#: the moving-base trend needs at least this much variance history, s
TREND_MIN_S = 8.0
#: what a forecast is based on
STILL, TREND, DONE = 'still-base covariance forecast', 'trend of the filter sigma', 'aligned'
MOTION = 'filter covariance run on with the last interval\'s motion'
#: a moving-base forecast is made again after this much data, s
MOTION_REFRESH_S = 5.0


@dataclass
class Expectation:
    """A forecast: times in seconds of data from the first sample; ``sigma`` (3,) rad E, N, U.

    ``t_aligned`` / ``t_tilt``: when ``aligned`` / a ready tilt are expected (``inf``: not
    within :data:`HORIZON_S`, ``nan``: no forecast yet); ``sigma``: the misalignment 1-sigma
    expected when ``aligned`` comes, or the best expected when it does not (NaN unknown);
    ``basis`` how it was made, ``note`` what limits it ('' when nothing does).
    """

    t_aligned: float
    t_tilt: float
    sigma: np.ndarray
    basis: str
    note: str = ''


class Forecaster:
    """The pipeline's forecast, kept between calls (a still-base shadow run is not free)."""

    def __init__(self):
        self._cached = None
        self._key = None
        self._t_made = -math.inf

    def expect(self, p):
        """Return the :class:`Expectation` of pipeline ``p`` (an ``AlignmentPipeline``) now."""
        fine = p.fine
        if fine is not None and fine.mounting_doubt:
            return Expectation(math.inf, math.inf, np.sqrt(np.diag(fine.attitude_cov())),
                               TREND if p.aided else STILL,
                               'never aligned: the vehicle frame is far from level '
                               '(imu_mounting_rpy_deg untold? the self-check\'s warning)')
        if fine is not None and fine.phase == 'aligned':
            return Expectation(_t_first_aligned(fine, p), _t_first_aligned(fine, p),
                               np.sqrt(np.diag(fine.attitude_cov())), DONE)
        still = (not p.aided if fine is not None else not _moving(p))
        if not still:
            return self._made(p, ('moving', id(fine), p.n_restarts), MOTION_REFRESH_S,
                              self._trend)
        key = (id(fine), None if fine is None else fine.stage, None if fine is None
               else fine.heading_known, p.n_restarts)
        return self._made(p, key, REFRESH_S, _still)

    def _made(self, p, key, every, make):
        """Return the forecast ``make(p)`` made for ``key`` within ``every`` s of data."""
        t = p.elapsed
        if key != self._key or t - self._t_made >= every or self._cached is None:
            self._cached = make(p)
            self._key, self._t_made = key, t
        return self._cached

    def _trend(self, p):
        """Forecast of a GNSS-aided filter: its model's covariance, else its variance history."""
        fine = p.fine
        nan3 = np.full(3, np.nan)
        if fine is None:
            return Expectation(math.nan, math.nan, nan3, TREND,
                               'moving base: forecast once the GNSS-aided filter has run '
                               f'{TREND_MIN_S:.0f} s (it depends on the manoeuvres)')
        make = getattr(fine.engine, 'forecast_model', None)
        model = make() if make is not None else None
        if model is not None:
            tau, Pa = covariance_shadow(model, HORIZON_S)
            e = _apply_rules(p, fine, fine.clock.t_last + tau, Pa + fine.floor)
            e.basis = MOTION
            if not fine.heading_known:
                e.t_aligned = math.inf
                e.note = ('heading unobservable at rest: it needs motion with GNSS, or an '
                          'external heading')
            elif not math.isfinite(e.t_aligned):
                e.note = (f'{e.note}; forecast for the motion of the last GNSS interval: '
                          'turns and accelerations with GNSS bring it forward')
            return e
        t, P = fine.history.arrays()
        if len(t) < 3 or t[-1] - t[0] < TREND_MIN_S:
            return Expectation(math.nan, math.nan, nan3, TREND,
                               f'forecast after {TREND_MIN_S:.0f} s of the fine filter')
        lat = p.position[0]
        q = process_noise(p.noise, p.cfg)
        P_min = np.array([0.0, 0.0, heading_limit_var(lat, p.noise)])
        P_now = P[-1]
        P_min = np.where(P_now > 1.5 * P_min, P_min, 0.0)     # the motion beat the limit
        Pr = np.maximum(P - P_min, 1e-30)
        # information rate over the window: d(1/P)/dt = r - q / P^2, the slope of a
        # least-squares line through 1/P (exact for q = 0, where 1/P is linear in time)
        slope = np.polyfit(t - t[-1], 1.0 / Pr, 1)[0]
        r = np.maximum(slope + q / np.mean(Pr, axis=0) ** 2, 0.0)
        tau = np.arange(0.0, HORIZON_S + 1.0, 1.0)
        Pf = P_min + riccati(Pr[-1], q, r, tau)
        e = _apply_rules(p, fine, t[-1] + tau, Pf)
        note = e.note
        if r[2] <= 0.0 and fine.heading_known:
            note = ('the heading sigma is not shrinking: the heading needs manoeuvres '
                    '(turns, accelerations) with GNSS, or an external heading')
        elif not fine.heading_known:
            note = ('heading unobservable at rest: it needs motion with GNSS, or an external '
                    'heading')
            e.t_aligned = math.inf
        e.basis, e.note = TREND, note
        return e


def _apply_rules(p, fine, t_abs, Pf):
    """Return the :class:`Expectation` of ``fine``'s forecast ``Pf`` (M, 3) at ``t_abs`` (M,)."""
    cfg = p.cfg
    max_tilt = math.radians(cfg['aligned_max_tilt_sigma_deg'])
    max_head = math.radians(cfg['aligned_max_heading_sigma_deg'])
    heading_known = fine.heading_known
    if not heading_known:
        max_head = -1.0
    i_al, i_tilt = first_aligned(t_abs, Pf, fine.stepping.settle.t0, fine.converged,
                                 2.0 * SETTLE_S, max_tilt, max_head)
    to_elapsed = t_abs - _t_first(p)
    sig = np.sqrt(np.maximum(Pf[-1 if i_al is None else i_al], 0.0))
    note = ''
    if i_al is None:
        note = _why_never(sig, max_tilt, max_head, heading_known)
    return Expectation(math.inf if i_al is None else float(to_elapsed[i_al]),
                       math.inf if i_tilt is None else float(to_elapsed[i_tilt]), sig, '',
                       note)


def _why_never(sig, max_tilt, max_head, heading_known):
    """Say why the bounds are not expected to be met within the horizon."""
    if not heading_known:
        return ('heading unobservable: the gyro cannot see Earth rate; it needs motion with '
                'GNSS aiding, or an external heading')
    if sig[2] > max_head:
        return (f'heading 1-sigma expected to stay near {math.degrees(sig[2]):.3g} deg, above '
                f'aligned_max_heading_sigma_deg {math.degrees(max_head):g}: it needs motion '
                'with GNSS aiding, an external heading or a better gyro')
    if max(sig[0], sig[1]) > max_tilt:
        return (f'tilt 1-sigma expected to stay near {math.degrees(max(sig[:2])):.3g} deg, '
                f'above aligned_max_tilt_sigma_deg {math.degrees(max_tilt):g}')
    return f'not within {HORIZON_S:.0f} s'


def _t_first(p):
    """Stamp of the pipeline's first sample (0 before any)."""
    return p.clock.t_first if p.clock.t_first is not None else 0.0


def _t_first_aligned(fine, p):
    """Seconds of data from the first sample to the first ``aligned`` of this fine stage."""
    if fine.t_aligned is None:
        return math.nan
    return fine.t_aligned - _t_first(p)


def _moving(p):
    """Tell whether GNSS shows the base moving before fine alignment (then ``auto`` aids)."""
    if p.cfg['fine_filter'] != 'auto':
        return is_aided(p.cfg['fine_filter'])
    t = p.t_last
    if t is None:
        return False
    moving, _ = gnss_motion(p.gnss, p.cfg, np.array([t - 3.0, t]))
    return is_aided(choose_filter(p.cfg, moving))


def _still(p):
    """Forecast by a still-base shadow run of pipeline ``p``: its fine stage, or a new one."""
    fine = p.fine
    t_ready = -math.inf                 # no row of the stage before this stamp
    if fine is None:
        fine, t0, t_ready = _new_stage(p)
    else:
        fine, t0 = copy.deepcopy(fine), p.t_last
    eng = fine.engine
    period = max(eng.period, 1.0 / SHADOW_HZ)
    lat = eng.lat
    C = eng.mech.C_b_n
    w_ie_n = np.array([0.0, earth.OMEGA_IE * math.cos(lat), earth.OMEGA_IE * math.sin(lat)])
    f_n = np.array([0.0, 0.0, eng.g])
    heading = _heading_source(p)
    fine.clock.t_last = t0
    ts, Ps = [t0], [np.diag(fine.attitude_cov()).copy()]
    t = t0
    while t < t0 + HORIZON_S:
        # an external heading keeps the steps short: one epoch with the information of
        # LATE_STEP_S s claims more than that many epochs with the drift between them
        # (a still MEMS IMU with a 0.2-deg compass: 0.060 deg forecast, 0.098 published)
        dt = LATE_STEP_S if fine.converged and heading is None else period
        eng.R = eng.R * (eng.period / dt)
        eng.period, eng.since_update = dt, 0.0
        t += dt
        C = eng.mech.C_b_n
        if heading is not None:          # one epoch a step, with the information of dt s
            var, period_h = heading
            fine.headings.add(t, dcm_to_euler(C)[2] + fine.headings.offset,
                              var * period_h / dt, t - dt, queue=True)
        fine.step(t, C.T @ w_ie_n * dt, C.T @ f_n * dt, None)
        ts.append(t)
        Ps.append(np.diag(fine.attitude_cov()).copy())
        if fine.phase == 'aligned' and t >= t_ready:   # the sigma of its first row
            break
    ts, Ps = np.array(ts), np.array(Ps)
    e = _apply_rules(p, fine, ts, Ps)
    e.basis = STILL
    if fine.phase == 'aligned':
        e.t_aligned = ts[-1] - _t_first(p)
        e.sigma, e.note = np.sqrt(Ps[-1]), ''
    # a stage that reprocesses the window publishes its first row at the window's end
    e.t_aligned = max(e.t_aligned, t_ready - _t_first(p))
    e.t_tilt = max(e.t_tilt, t_ready - _t_first(p))
    if heading is not None and eng.model.name == 'reduced7' and e.note:
        e.note += ('; reduced7 keeps its gyro-bias heading limit with an external heading: '
                   'stationary12 (fine_filter or auto_still_filter) uses it fully')
    return e


def _heading_source(p):
    """Return the last minute's external headings: ``(median variance rad^2, period s)``."""
    if p.t_last is None:
        return None
    h = [f for f in p.headings.history if f.t > p.t_last - 60.0]
    if not h:
        return None
    period = float(np.median(np.diff([f.t for f in h]))) if len(h) > 1 else 1.0
    return float(np.median([f.var for f in h])), max(period, 1e-3)


def _new_stage(p):
    """Return a fine stage as the pipeline would start it after coarse, and its stamps.

    The stamps: where the stage starts, and its first row (the window's end).
    The window lasts what the configured model gives (:func:`~.coarse_stage.
    expected_duration`), or the minute it is held to while ``auto`` waits for a drive to
    show without GNSS (:meth:`~.coarse_window.CoarseWindow.hold_for_drive_test`); the stage
    starts at its first sample with the reprocessing prior
    (:mod:`~..stages.reprocess`) and the window's gyrocompass heading where it applies
    (:func:`~..stages.reprocess.gyrocompass_plan`, with the configured noise), unless
    ``coarse_reprocess`` is off (then at the window's end, from the coarse sigma). An
    external heading sets the coarse heading: its sigma, or, reprocessing, the prior
    :func:`~..stages.reprocess.measured_heading_prior` gives it (the shadow's epochs then
    begin at the window's start, as the stage takes the window's headings again).
    """
    cfg = dict(p.cfg)
    cfg['fine_filter'] = choose_filter(cfg, False)
    position = p.position if p.position is not None else p.gnss.position(cfg, False)[0]
    lat = position[0]
    T = coarse_window.expected_duration(p.noise, lat, cfg)
    if p.window.duration > cfg['coarse_duration']:    # held for the drive test (no GNSS)
        T = p.window.duration
    sigma, _ = coarse_window.coarse_sigma(p.noise, T, lat, False)
    heading = _heading_source(p)
    replay = cfg['coarse_reprocess']
    if replay:
        sigma = prior_sigma(p.noise, T, lat, False, sigma)
    if heading is not None:          # the coarse stage takes the external heading
        sigma[2] = math.sqrt(heading[0])
        if replay:
            sigma = reprocess.measured_heading_prior(
                coarse_stage.CoarseResult(np.eye(3), sigma, np.zeros(3)), sigma[2]).sigma
    start = coarse_stage.CoarseResult(np.eye(3), sigma, np.asarray(position, float))
    known = (heading_limit_var(lat, p.noise) > 0.0 or p.noise.gyro_bias == 0.0
             or heading is not None)
    clock = Clock()
    t_end = _t_first(p) + T
    t0 = _t_first(p) if replay else t_end
    clock.t_first = clock.t_last = t0
    fine, _ = fine_stage_for(start, cfg, p.noise, False, known, heading is not None, clock,
                             None, copy.deepcopy(p.headings))
    plan = reprocess.gyrocompass_plan(p.noise, lat, T) if replay and known else None
    if plan is not None:                # the window's gyrocompass heading, then segments
        var, rate_var, span = plan
        fine.engine.gyrocompass_update(0.0, var)
        fine.engine.gyro_segments = GyroSegments(rate_var, lat, span - T, skip=T)
    return fine, t0, t_end


def figures(e, C_b_n=None):
    """Diagnostics figures of :class:`Expectation` ``e`` (plain Python types).

    The 1-sigma as roll, pitch, yaw through the attitude ``C_b_n`` (level if None).
    """
    euler = np.zeros(3) if C_b_n is None else dcm_to_euler(C_b_n)
    sig = np.asarray(e.sigma, dtype=float)
    s = {}
    if np.all(np.isfinite(sig)):
        P_e = euler_cov_from_phi_cov(euler, np.diag(sig ** 2))
        for k, name in enumerate(('roll', 'pitch', 'yaw')):
            s[f'expected_sigma_{name}_deg'] = math.degrees(math.sqrt(max(P_e[k, k], 0.0)))
    s['expected_aligned_at_s'] = _when(e.t_aligned)
    s['expected_tilt_ready_at_s'] = _when(e.t_tilt)
    s['expectation_basis'] = e.basis
    s['expectation_note'] = e.note
    return s


def _when(t):
    """Return a time for the diagnostics: seconds, ``never`` (beyond the horizon), ``unknown``."""
    if math.isnan(t):
        return 'unknown'
    return 'never' if math.isinf(t) else float(t)

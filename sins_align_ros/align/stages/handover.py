"""The hand-over from coarse to fine alignment: from a full coarse window to a fine stage.

One job: when the coarse window is full, decide from the data and the configuration
what runs next, without changing the pipeline:

1. the fine filter (``auto`` resolved by :mod:`.motion` from what GNSS shows), or why
   none can start (a moving base without GNSS, ...);
2. the position (:class:`~.gnss_buffer.GnssBuffer`, a fix may have come in meanwhile);
3. the sensor self-check (:mod:`.self_check`): it may widen the configured model, and
   says whether the gyros can find north;
4. the coarse attitude (:mod:`.coarse_stage`), its heading replaced by a recent external
   one (:mod:`.heading`);
5. the engine and the fine stage (:mod:`.factory`, :mod:`.fine_stage`);
6. the stage starts at the window's first sample, to run over its samples (a GNSS-aided
   one only with ``coarse_reprocess_aided``, and over the fixes too, which the pipeline
   queues again) (:mod:`.reprocess`; the pipeline runs the :class:`~.reprocess.CatchUp`).

:class:`~.pipeline.AlignmentPipeline` applies the :class:`FineStart` it returns, or
restarts from coarse with the reason.
"""
from dataclasses import dataclass

import numpy as np

from ...models.stationary import unobservable_variance
from .. import params as prm
from . import coarse_stage, reprocess, self_check
from ..inputs import motion
from ..engines.factory import is_aided, make_engine, noise_spec
from .fine_stage import FineStage
from ..inputs.heading import coarse_heading


@dataclass
class FineStart:
    """What the hand-over decided (every field replaces the pipeline's of that name).

    ``cfg``: the parameters as the hand-over left them (``fine_filter`` resolved, the
    sensor model widened by the self-check); ``noise`` their sensor model in SI units;
    ``aided``: the fine filter is GNSS-aided; ``position`` ``(lat, lon, h)`` and its
    ``position_source``; ``check``: the self-check's result or None; ``coarse_info``:
    the coarse stage's diagnostics; ``heading_measured``: an external heading set the
    coarse heading; ``warnings``: what the user should be told; ``fine``: the running
    :class:`~.fine_stage.FineStage`; ``install``: the
    :class:`~.installation.Installation`, its lever arm the self-check's where it found one;
    ``catch_up``: the :class:`~.reprocess.CatchUp` of a stage that starts at the window's
    first sample (it has yet to run over the window), or None.
    """

    cfg: dict
    noise: object
    aided: bool
    position: tuple
    position_source: str
    check: object
    coarse_info: dict
    heading_measured: bool
    warnings: list
    fine: FineStage
    install: object
    catch_up: object = None


def hand_over(window, cfg, noise, clock, gnss, headings, install):
    """Return ``(FineStart, None)``, or ``(None, reason)`` when fine alignment cannot start.

    ``window``: the coarse window's arrays (``CoarseWindow.arrays``); ``cfg`` and
    ``noise``: the parameters and sensor model as configured (not changed here);
    ``clock``: the pipeline's :class:`~.fine_stage.Clock` (at the window's end; a
    reprocessing stage moves it to the window's start, its :class:`~.reprocess.CatchUp`
    back to the end);
    ``gnss``, ``headings``, ``install``: the pipeline's GNSS history, external headings
    and installation (read only).
    """
    cfg = dict(cfg)
    m = motion.judge(gnss, cfg, window, install)
    cfg['fine_filter'] = motion.choose_filter(cfg, m.moving)
    aided = is_aided(cfg['fine_filter'])
    reason = motion.cannot_start(cfg['fine_filter'], aided, m)
    if reason is not None:
        return None, reason
    position, position_source = gnss.position(cfg, aided, clock.t_last)
    warnings, check = [], None
    if cfg['sensor_self_check']:
        # biases only where the base is known to be at rest: GNSS says so, or (a
        # stationary filter, chosen by the user or by auto) there is no GNSS
        at_rest = not m.moving and (m.speed is not None or not aided)
        check = self_check.check(window, position, cfg, at_rest, gnss)
        if check is not None and check.latitude is not None:
            position_source = 'gyro_latitude'      # the self-check's estimate (in place)
        if check.widened:
            # what the user configured, for the motion check (it narrows its own widenings
            # back as its data grow, never below the configured figure)
            cfg['configured'] = {k: cfg[k] for k in check.widened if k in cfg}
            cfg.update(check.widened)
            noise = noise_spec(cfg)
        if 'gnss_lever_arm_m' in check.widened:
            install = install.with_lever_arm(cfg['gnss_lever_arm_m'])
        warnings.extend(check.findings)
        warning = self_check.heading_warning(check, at_rest, aided)
        if warning and not headings.latest(clock.t_last):
            warnings.append(warning)
    res, coarse_info, reason = coarse_stage.run(window, cfg, noise, position, gnss,
                                                clock.t_last, aided, install)
    if reason is not None:
        return None, reason
    heading_measured = _take_heading(res, window, headings, clock.t_last, coarse_info)
    no_heading = check is not None and not check.heading_observable and not heading_measured
    # the self-check's finding replaces the coarse stage's own warning about the gyro
    warnings.extend(w for w in res.warnings if not (no_heading and w.startswith('gyro bias')))
    heading_known = (check is None or check.heading_observable
                     or (aided and not check.at_rest) or heading_measured)
    replay = reprocess.applies(cfg, aided)
    C_window, sigma_window = res.C_b_n, res.sigma
    if replay:                      # the stage starts where the window began
        if aided:
            res0 = reprocess.aided_start(res, window, gnss, cfg, install)
            replay = res0 is not None
            res = res if res0 is None else res0
        else:
            res = reprocess.start_of_window(res, window, noise, coarse_info['method'])
    if replay:
        if heading_measured:
            res = reprocess.measured_heading_prior(res, float(sigma_window[2]))
        clock.t_last = clock.t_first
    plan = reprocess.window_plan(window, noise, position[0], coarse_info['method'],
                                 coarse_info['motion_detected']) if (
        replay and heading_known and not aided) else None
    if check is not None and check.read:
        _read_zero_velocity(cfg, check, plan is not None)
    fine, engine_warnings = fine_stage_for(res, cfg, noise, bool(gnss.vels), heading_known,
                                           heading_measured, clock, install, headings)
    warnings.extend(engine_warnings)
    if check is not None:
        fine.mounting_doubt = check.mounting_doubt
    if plan is not None:
        sigma = reprocess.window_heading(fine, C_window, window, plan, position[0])
        coarse_info['window_heading_sigma_deg'] = float(np.degrees(sigma))
    if replay:
        coarse_info['reprocessed_s'] = float(window[0][-1] - window[0][0] + window[3][0])
    return FineStart(cfg, noise, aided, position, position_source, check, coarse_info,
                     heading_measured, warnings, fine, install,
                     reprocess.CatchUp(window) if replay else None), None


def _read_zero_velocity(cfg, check, takes_heading):
    """Take the zero-velocity sigmas the self-check read (``check.read``) into ``cfg``.

    Not where the stage takes the window's gyrocompass heading (``takes_heading``): those
    headings are measurements on the premise that the filter's own route to the heading,
    the tilt drift read through the zero-velocity rows, holds little of the gyros'
    information (``engines/gyrocompass.py``). A sigma at the data's level (0.3 mm/s on a
    still navigation-grade base, against the unread 0.01 m/s) makes that route
    gyro-limited within a minute and a half, and the window's samples then count twice
    (test_reprocess: the heading error's mean square in sigmas 2.8 at 89 s over 12 seeds,
    1.8 with the unread sigma, against a 2.0 bound; over 40 seeds and 300 s it peaks at
    1.48 at 120 s with the read sigma, at 1.17 with the unread). The stage keeps
    ``params.ZERO_VELOCITY_UNREAD`` there, widened as a configured one would be
    (``check.unread``).
    """
    if not takes_heading:
        cfg.update(check.read)
        return
    check.note = '; '.join((check.note, 'the read zero-velocity sigma is not used: the '
                            'window\'s gyrocompass heading is taken (the filter keeps '
                            f'{prm.ZERO_VELOCITY_UNREAD:g} m/s unless the base moves more, '
                            'so the window\'s gyro samples do not count twice)'))
    cfg.update(check.unread)


def fine_stage_for(start, cfg, noise, with_velocity, heading_known, heading_measured, clock,
                   install, headings):
    """Return ``(FineStage, warnings)``: ``cfg['fine_filter']``'s engine started from ``start``.

    ``start``: a :class:`~.coarse_stage.CoarseResult`; ``with_velocity``: GNSS velocity
    has been seen; ``heading_known``: the heading is observable (else published as
    unknown); ``heading_measured``: an external heading set the coarse heading. The
    pipeline's hand-over, :meth:`~.pipeline.AlignmentPipeline.start_fine` and the
    forecast (:mod:`.expectation`) all start fine stages here.
    """
    engine, floor, warnings = make_engine(cfg, noise, start, with_velocity, heading_known)
    if heading_measured:
        engine.heading_measured()
    fine = FineStage(engine, floor, clock, cfg, heading_known,
                     unobservable_variance(start.position[0], noise)[0], install, noise,
                     headings)
    return fine, warnings


def _take_heading(res, window, headings, t_end, coarse_info):
    """Give the coarse result ``res`` the last external heading if one is recent.

    Its yaw is carried to the window's end with the gyros' up rate (a turning car).
    Returns True if it did (``coarse_info['coarse_heading_source']`` says so).
    """
    fix = headings.latest(t_end)
    if fix is None:
        return False
    tt, dth = window[0], window[1]
    turned = float(res.C_b_n[2] @ dth[tt > fix.t].sum(axis=0))
    res.C_b_n, res.sigma = coarse_heading(res.C_b_n, res.sigma, fix.yaw + turned, fix.var)
    coarse_info['coarse_heading_source'] = 'external'
    return True

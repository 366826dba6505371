"""What the pipeline tells its user: the status record and the degraded conditions.

:func:`pipeline_status` gathers the key figures for diagnostics (phase, elapsed
time, 1-sigma Euler angles, the engine's internals, the GNSS and coarse figures);
:class:`ConditionReport` turns the counts that grew since its last call into
warnings, so each rejection is reported once.
"""
import re

import numpy as np

from ...nav.frames import dcm_to_euler, euler_cov_from_phi_cov
from . import expectation
from ...units import DEG
from ..inputs.gnss_buffer import MAX_LEAD_S, QUEUE

#: the GNSS-aided filters say they run unaided after this long without a GNSS epoch, s
OUTAGE_WARN_S = 5.0
#: a number in a condition's text (its kind is the text without them)
_NUMBER = re.compile(r'[-+]?\d+(?:\.\d+)?')


def pipeline_status(p):
    """Key figures of pipeline ``p`` for diagnostics (plain Python types)."""
    # a stage still catching up with the stored samples has no current estimate yet
    fine = p.fine if p.catch_up is None else None
    s = {'phase': p.phase, 'elapsed_s': p.elapsed, 'fine_filter': p.cfg['fine_filter'],
         'position_source': p.position_source or 'none',
         'stage': 0 if fine is None else fine.stage, 'filter_updates': 0,
         'catching_up': p.catch_up is not None}
    if p.catch_up is not None:
        s['catch_up_left_s'] = p.catch_up.left_s
    if p.fine is None:          # the coarse window's length (coarse_duration, or held)
        s['coarse_window_s'] = p.window.duration
    if p.position is not None:
        s['latitude_deg'] = p.position[0] / DEG
    if fine is not None:
        P_e = euler_cov_from_phi_cov(dcm_to_euler(fine.mech.C_b_n), fine.attitude_cov())
        for k, name in enumerate(('roll', 'pitch', 'yaw')):
            s[f'sigma_{name}_deg'] = float(np.sqrt(max(P_e[k, k], 0.0)) / DEG)
        tilt, heading = fine.readiness()
        s.update(tilt_ready=tilt, heading_ready=heading, heading_observable=fine.heading_known,
                 not_aligned_reason=fine.why_not_aligned())
        s.update(fine.engine.status())
        if p.aided and getattr(fine.engine, 'gnss_markov', None) is not None:
            s.update(fine.engine.gnss_markov.status())      # the GNSS Gauss-Markov model
        if p.aided:
            s.update(fine.consistency.status())
            s.update(fine.monitor_status())
            s.update({f'gnss_{k}': v for k, v in p.gnss.counts.items()})
    s.update({f'coarse_{k}': v for k, v in p.coarse_info.items()})
    if p.check is not None:
        s['self_check_still'] = p.check.still
        s['self_check_note'] = p.check.note
        s['self_check_widened'] = ' '.join(
            f'{k}={v}' if isinstance(v, bool) else
            f'{k}=[{", ".join(f"{x:.4g}" for x in v)}]' if isinstance(v, tuple) else
            f'{k}={v:.4g}' for k, v in p.check.widened.items())
        s.update({f'self_check_{k}': float(v) for k, v in p.check.figures.items()})
    s.update(expectation.figures(p.expectation(), None if fine is None else fine.mech.C_b_n))
    return s


class ConditionReport:
    """Counts already reported, so that each degraded condition is said once.

    :attr:`said`: the last text of each kind of condition reported so far (a run's
    summary; what one call returns depends on how often the caller asks).
    """

    def __init__(self):
        self._reported = {'rejected': 0, 'forced': 0, 'ahead_of_imu': 0, 'queue_full': 0}
        self._mounting = ''
        self._moving = ''
        self._said = {}       # kind (the text, numbers blanked) -> its last text

    @property
    def said(self):
        """Return the last text of each kind of condition reported, in order of first report.

        Bounded by the kinds, not the run's length: a text that changes with every call
        (an outage's length, a count) keeps one entry.
        """
        return list(self._said.values())

    def conditions(self, p):
        """Degraded conditions of pipeline ``p`` as ``[(level, text)]`` (1 warn, 2 error).

        GNSS epochs rejected by the innovation gate, re-anchoring after a run of
        rejections, fixes stamped ahead of the IMU clock, epochs dropped from a full
        queue, a GNSS-aided filter running without GNSS, the under-way mounting
        check's finding (:mod:`.sideslip`), and a still-base filter's base found moving
        or at rest again (:mod:`.still_watch`).
        """
        out = []
        gate = getattr(p.engine, 'gate', None)
        if gate is not None:
            n = self._since('rejected', gate.n_rejected)
            if n > 0:
                t_r, nis, thr = gate.last_rejection
                out.append((1, f'{n} GNSS epoch(s) rejected by the innovation gate (last at '
                               f't={t_r:.1f} s: NIS {nis:.1f} > {thr:.1f}, chi-square '
                               f'{gate.probability})'))
            if self._since('forced', gate.n_forced) > 0:
                out.append((1, f'GNSS accepted again after {gate.max_rejects} rejected '
                               'epochs, with widened position/velocity variance '
                               '(re-anchored: position jump or filter lag)'))
            t_ref = p.gnss.t_used if p.gnss.t_used is not None else p.fine.t0
            if t_ref is not None and p.t_last - t_ref > OUTAGE_WARN_S:
                out.append((1, f'no GNSS epoch used for {p.t_last - t_ref:.1f} s: '
                               'moving-base filter running unaided (attitude sigma growing)'))
        if p.fine is not None and p.aided:     # the long-horizon test's widenings
            out.extend((1, text) for text in p.fine.consistency.pop_notes())
        doubt = p.fine.mounting_doubt if p.fine is not None else ''
        if doubt and doubt != self._mounting:
            self._mounting = doubt
            if p.check is None or doubt != p.check.mounting_doubt:   # (said at hand-over)
                out.append((1, doubt))
        moving = p.fine.moving if p.fine is not None else ''
        if moving != self._moving:
            if moving:
                out.append((1, moving + '; attitude from the gyros alone, its sigma growing'))
            else:
                out.append((1, 'the IMU has shown rest for a whole coarse window: '
                               'zero-velocity alignment resumed'))
            self._moving = moving
        if p.fine is not None:
            out.extend((1, text) for text in p.fine.monitor_findings())
        n = self._since('queue_full', p.gnss.counts['queue_full'])
        if n > 0:
            out.append((1, f'{n} GNSS epoch(s) dropped: more than {QUEUE} '
                           'waiting for the IMU stream to reach their stamps'))
        n = self._since('ahead_of_imu', p.gnss.counts['ahead_of_imu'])
        if n > 0:
            out.append((1, f'{n} GNSS message(s) stamped more than {MAX_LEAD_S:.0f} s '
                           'ahead of the IMU clock: skipped (clocks disagree)'))
        for _, text in out:
            self._said[_NUMBER.sub('#', text)] = text
        return out

    def _since(self, key, count):
        """Return how much ``count`` grew since the last call for ``key``."""
        n = count - self._reported[key]
        self._reported[key] = count
        return n

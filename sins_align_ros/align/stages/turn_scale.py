"""The up gyro's scale factor measured from the turns against the GNSS course (issue 44).

A gyro scale-factor error ``s`` turns every rotation ``A`` about the vertical into a
heading error ``s A``. Without GNSS velocity (a position-only receiver) the engines carry
it as process noise (:mod:`..engines.rotation_error`), at the told or presumed 1-sigma:
the self-check presumes 2 % for a MEMS triad nobody calibrated
(:data:`~.grade_check.SCALE_BY_GYRO_NOISE`), so every 90 deg junction turn adds 1.8 deg of
heading sigma, whether the triad has that error or not, and the positions need tens of
seconds to find the heading again. (With GNSS velocity the scale factors become filter
states once the heading is known, :mod:`..engines.gyro_scale`; positions alone were
measured too weak for those states, which then claimed a heading 2-3 deg off under 0.6.)

The turns themselves measure it, outside the filter. The gyro heading ``psi`` is the
rotation about the local vertical summed from the increments (``C_b_n[2] . dtheta``, the
vertical row of the attitude: it depends on the tilt only, not on the heading), less the
drift estimate the increments still carry and the navigation frame's own rate about up
(``Omega sin L + v_E tan L / (R_N + h)``), with the scale compensation undone: it never
sees a GNSS correction. The straight legs of :mod:`.slow_monitor` (5-30 s, yaw rate under
3 deg/s) each give their GNSS course against the mean ``psi`` over them, ``D_i`` with its
1-sigma ``sigma_i`` from the positions (:func:`~.course_heading.fitted_course`, the
correlated position errors included; a velocity a fix may carry is not what the engine
measures here, so it is not used).
Between two consecutive legs the gyro turned ``A = psi_2 - psi_1`` while the vehicle
turned by the change of course, so

    ``z = -(D_2 - D_1) = s A + e``,
    ``R = sigma_1^2 + sigma_2^2 + var(eps_U) dt^2 + 2 sigma_s^2``

``var(eps_U)`` the filter's variance of the vertical drift (``dt`` between the legs'
mean stamps) and ``sigma_s`` the sideslip a straight leg may have
(``slow_monitor_sideslip_deg``; a constant crab, an IMU mounted turned, cancels in the
difference). A pair is used when the gyro turned at least :data:`MIN_TURN`.

The estimate is the weighted least-squares one with the told (or presumed) 1-sigma as
its prior, ``P = 1 / (1 / P0 + sum A^2 / (k R))``, ``s = P sum A z / (k R)``, ``k`` the
residuals' mean square per degree of freedom where above 1 (from :data:`MIN_FOR_K`
pairs on: a vehicle whose courses scatter more than the model says widens its own
estimate). From :data:`MIN_TURNS` pairs on the engine compensates ``s`` and carries
``sqrt(P)`` instead of the told 1-sigma in its noise about the body's z axis
(``engine.set_turn_scale``). A pair whose innovation ``z - s A`` lies beyond the gate
(chi-square, :data:`GATE_PROBABILITY`) is not used; :data:`MAX_REJECTED` such pairs in a
row (a vehicle reversing, skidding or crabbing by a varying angle) turn the measurement
off for the stage, give the engine its told model back and say so (a WARN).

Not in the seeds (their gyros are calibrated).
"""
import math

import numpy as np

from ...filters.chi2 import chi2_quantile
from ...nav import earth
from ..engines.base import AidedEngine, Engine
from ..inputs.gnss_fix import epoch_var, uses_reported_covariance
from ..inputs.heading import wrap
from .course_heading import fitted_course
from .finding import OnceFinding
from .slow_monitor import (MAX_LEG_S, MAX_YAW_RATE, MIN_EPOCHS, MIN_LEG_S, MIN_SPEED,
                           RATE_SPAN, STRAIGHT, Leg, YawRate)

#: smallest rotation (rad) between two legs that measures the scale factor
MIN_TURN = math.radians(20.0)
#: legs further apart than this (s, between their mean stamps) make no pair
MAX_PAIR_S = 120.0
#: pairs before the engine gets the estimate
MIN_TURNS = 2
#: pairs before their residuals scale the noise (``k``)
MIN_FOR_K = 4
#: gate probability of a pair's innovation
GATE_PROBABILITY = 0.9999
#: rejected pairs in a row that turn the measurement off
MAX_REJECTED = 3


class TurnScale(OnceFinding):
    """The up gyro's scale factor from turns between straight legs (module docstring).

    ``sideslip_deg``: a straight leg's sideslip 1-sigma; ``pos_sigma``: the configured
    GNSS position sigma (m); ``use_reported``: a fix's reported variances replace
    them (:func:`~..inputs.gnss_fix.epoch_var`); ``markov_sigma`` (m), ``markov_tau`` (s):
    the configured Gauss-Markov position error; ``markov_from_fixes``: without one, the
    fixes' own sigma is taken as one (:meth:`_markov_var`).
    """

    def __init__(self, sideslip_deg=0.5, pos_sigma=1.0, markov_sigma=0.0, markov_tau=60.0,
                 use_reported=False, markov_from_fixes=False):
        self.var_s = math.radians(sideslip_deg) ** 2
        self.pos_var = float(pos_sigma) ** 2
        self.markov_var = float(markov_sigma) ** 2
        self.markov_tau = float(markov_tau)
        self.use_reported = bool(use_reported)
        self.markov_from_fixes = bool(markov_from_fixes)
        #: the gyro heading (rad, unwrapped) and its stamp
        self.psi = 0.0
        self.t = None
        self.scale = 0.0              # the compensation in effect (-)
        self.leg = None
        self._rate = YawRate(RATE_SPAN)
        #: the last judged leg: (mean stamp, mean psi, D, var_c)
        self._prev = None
        #: used pairs: rotation A (rad), z (rad), R (rad^2)
        self.pairs = []
        self.estimate = None          # (s, sigma) given to the engine
        self.off = False
        self.n_rejected = self._run = 0

    def add(self, t, engine: AidedEngine, fix):
        """Take an accepted GNSS epoch at ``t``; give the engine a new estimate when due."""
        turn = engine.take_turn()
        if self.off:
            return
        if turn is None:                  # the engine does not take it (now): start afresh
            self.t, self.leg, self._prev = None, None, None
            return
        A, eps_up, var_eps, prior_var = turn
        m = engine.mech
        if self.t is not None:
            T = t - self.t
            R_M, R_N = earth.radii(m.lat)
            w_up = (earth.OMEGA_IE * math.sin(m.lat)
                    + m.v_n[0] * math.tan(m.lat) / (R_N + m.h))
            self.psi += (A - eps_up * T) * (1.0 + self.scale) - w_up * T
        self.t = t
        rate = self._rate.add(t, self.psi)
        straight = rate <= MAX_YAW_RATE and math.hypot(m.v_n[0], m.v_n[1]) >= MIN_SPEED
        leg = self.leg
        if leg is not None and (not straight or abs(self.psi - leg.yaw0) > STRAIGHT
                                or t - leg.t0 > MAX_LEG_S):
            self.leg = None
            self._judge(leg, var_eps, prior_var, engine)
        if straight:
            self._join(t, fix)

    def _join(self, t, fix):
        if self.leg is None:
            self.leg = Leg(t, self.psi)
        leg = self.leg
        leg.t.append(t)
        leg.yaw.append(self.psi)
        leg.var_h.append(0.0)
        leg.pos.append((fix.lat, fix.lon, fix.h))
        leg.pos_var.append(epoch_var(self.pos_var, fix.pos_var, self.use_reported))

    def _judge(self, leg, var_eps, prior_var, engine):
        """Judge a finished leg; pair it with the last one; estimate when a pair is new."""
        if len(leg.t) < MIN_EPOCHS or leg.duration < MIN_LEG_S:
            return
        res = fitted_course(leg, self._markov_var(leg), self.markov_tau)
        if res is None:
            return
        D, sig_c = res
        cur = (float(np.mean(leg.t)), float(np.mean(leg.yaw)), D, sig_c * sig_c)
        prev, self._prev = self._prev, cur
        if prev is None or cur[0] - prev[0] > MAX_PAIR_S:
            return
        A = cur[1] - prev[1]
        if abs(A) < MIN_TURN:
            return
        dt = cur[0] - prev[0]
        z = -wrap(cur[2] - prev[2])
        R = prev[3] + cur[3] + var_eps * dt * dt + 2.0 * self.var_s
        s, P, k = self._solve(prior_var)
        nu = z - s * A
        if nu * nu > chi2_quantile(GATE_PROBABILITY, 1) * (A * A * P + k * R):
            self.n_rejected += 1
            self._run += 1
            if self._run >= MAX_REJECTED:
                self._turn_off(engine, nu, A)
            return
        self._run = 0
        self.pairs.append((A, z, R))
        if len(self.pairs) >= MIN_TURNS:
            s, P, _ = self._solve(prior_var)
            self.estimate = (s, math.sqrt(P))
            self.scale = s
            engine.set_turn_scale(s, math.sqrt(P))

    def _markov_var(self, leg):
        """Return the Gauss-Markov position variance of a positions-only leg (m^2).

        The configured one; without it (``gnss_position_only_markov``) four times the
        leg's mean fix variance, as the engine's Gauss-Markov states take it
        (:mod:`..engines.factory`).
        """
        if self.markov_var > 0.0 or not self.markov_from_fixes:
            return self.markov_var
        return 4.0 * float(np.mean(leg.pos_var))

    def _solve(self, prior_var):
        """``(s, P, k)`` of the pairs so far with prior variance ``prior_var`` (docstring)."""
        if not self.pairs:
            return 0.0, prior_var, 1.0
        A, z, R = (np.array(c) for c in zip(*self.pairs))
        k = 1.0
        for _ in range(2):
            info = 1.0 / prior_var + float(np.sum(A * A / (k * R)))
            s = float(np.sum(A * z / (k * R))) / info
            if len(A) < MIN_FOR_K:
                break
            k = max(1.0, float(np.sum((z - s * A) ** 2 / R)) / (len(A) - 1))
        return s, 1.0 / info, k

    def _turn_off(self, engine, nu, A):
        self.off = True
        self.scale = 0.0
        self.estimate = None
        engine.set_turn_scale(0.0, None)
        self.finding = (f'{self._run} turns in a row left the gyro heading '
                        f'{math.degrees(nu):+.1f} deg from the GNSS course change over '
                        f'{math.degrees(A):+.0f} deg, beyond what a scale factor and the '
                        'courses\' noise allow (the vehicle reverses, skids or crabs): the '
                        'up gyro\'s scale factor is no longer measured from turns; the told '
                        'one is modelled')

    def status(self):
        """Figures for diagnostics."""
        s = {'turn_scale_on': not self.off, 'turn_scale_turns': len(self.pairs),
             'turn_scale_rejected': self.n_rejected}
        if self.estimate is not None:
            s.update(turn_scale_ppm=self.estimate[0] * 1e6,
                     turn_scale_sigma_ppm=self.estimate[1] * 1e6)
        return s


def for_stage(engine: Engine, cfg):
    """Return the measurement of a fine stage running ``engine`` with ``cfg``, or None.

    None for the still-base engines and with ``turn_scale`` off.
    """
    if engine.restages or not cfg['turn_scale']:
        return None
    return TurnScale(cfg['slow_monitor_sideslip_deg'], cfg['gnss_pos_sigma_m'],
                     cfg['gnss_position_markov_sigma_m'],
                     cfg['gnss_position_markov_tau_s'], uses_reported_covariance(cfg),
                     bool(cfg['gnss_position_only_markov']))

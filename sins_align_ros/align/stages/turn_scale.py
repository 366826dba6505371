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

The turns themselves measure it, outside the filter's heading. The gyro heading ``psi``
is the rotation about the local vertical summed from the increments (``C_b_n[2] .
dtheta``, the vertical row of the attitude: it depends on the tilt only, not on the
heading), less the navigation frame's own rate about up (``Omega sin L + v_E tan L / (R_N
+ h)``), with the engine's compensations undone (its scale factor, and its drift
estimate, which changes with every GNSS epoch): the GNSS never enters it. A chain of legs
takes off one drift, the engine's estimate at the chain's start; what is left of the
drift is a state here, its prior the engine's variance of it then. The straight legs of
:mod:`.slow_monitor` (5-30 s, yaw rate under 3 deg/s, the first epochs of the turn that
ends one trimmed off) each give their GNSS course from the positions
(:func:`~.course_heading.fitted_course`, the correlated position errors included; a
velocity a fix may carry is not what the engine measures here) against the mean ``psi``
over the leg, ``D_i``, of variance ``r_i = sigma_c^2 + sigma_s^2`` (``sigma_s`` the
sideslip a straight leg may have, ``slow_monitor_sideslip_deg``). Over a chain of legs

    ``D_i = b(t_i) - s psi_i + e_i``,    ``b' = -d``,    ``d' = w``

``b`` the offset between the gyro heading and the course (free: a constant crab, an IMU
mounted turned, goes there too), ``d`` the residual of the filter's vertical drift
estimate (prior: the filter's variance of it; a random walk of the filter's drift density
``q``). A 3-state Kalman filter over the chain's legs gives ``s`` and its variance, the
told (or presumed) 1-sigma its prior; each leg's error is its own, so two pairs of legs
that share one are not counted as independent. The legs' noise is scaled by ``k``, the
mean NIS of the chain's innovations where above 1 (from :data:`MIN_FOR_K` of them on: a
vehicle whose courses scatter more than the model says widens its own estimate). Once the
legs have shown :data:`MIN_TURNS` turns of at least :data:`MIN_TURN` the engine
compensates ``s`` and carries its sigma instead of the told one about the body's z axis
(``engine.set_turn_scale``). A leg whose innovation lies beyond the gate (chi-square,
:data:`GATE_PROBABILITY`) is not used; :data:`MAX_REJECTED` such legs in a row (a vehicle
reversing, skidding or crabbing by a varying angle) turn the measurement off for the stage,
give the engine its told model back and say so (a WARN). A chain ends where the engine
stops giving the rotation (a GNSS velocity measured, the scale factors become states) or
after :data:`MAX_CHAIN` legs; the next starts from the last estimate.

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

#: smallest rotation (rad) between two consecutive legs that counts as a turn
MIN_TURN = math.radians(20.0)
#: turns before the engine gets the estimate
MIN_TURNS = 2
#: innovations before their mean NIS scales the legs' noise (``k``)
MIN_FOR_K = 4
#: gate probability of a leg's innovation
GATE_PROBABILITY = 0.9999
#: rejected legs in a row that turn the measurement off
MAX_REJECTED = 3
#: legs of a chain before the next starts from its estimate
MAX_CHAIN = 40
#: prior variance of the offset ``b`` (rad^2): free
OFFSET_VAR = 100.0


class TurnScale(OnceFinding):
    """The up gyro's scale factor from the legs between turns (module docstring).

    ``sideslip_deg``: a straight leg's sideslip 1-sigma; ``pos_sigma``: the configured
    GNSS position sigma (m); ``use_reported``: a fix's reported variances replace
    it (:func:`~..inputs.gnss_fix.epoch_var`); ``markov_sigma`` (m), ``markov_tau`` (s):
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
        #: the chain's legs: (stamp s, psi rad, D rad, r rad^2), its priors and drift density
        self.chain = []
        self._prior = None            # (s, var) the chain starts from; None: the told one
        #: the vertical drift (rad/s) the chain takes off the gyro: the engine's estimate at
        #: the chain's start; ``_eps``: (its variance then, the drift's density q)
        self.eps_ref = 0.0
        self._eps = (0.0, 0.0)
        self._eps_now = None
        self.n_turns = 0
        self.estimate = None          # (s, sigma) given to the engine
        self.off = False
        self.n_legs = self.n_rejected = self._run = 0

    def add(self, t, engine: AidedEngine, fix):
        """Take an accepted GNSS epoch at ``t``; give the engine a new estimate when due."""
        turn = engine.take_turn()
        if self.off:
            return
        if turn is None:                  # the engine does not take it (now): a new chain
            self.t, self.leg = None, None
            self._new_chain()
            return
        A, eps_applied, eps, var_eps, q_eps, prior_var = turn
        m = engine.mech
        if self.t is not None:
            T = t - self.t
            w_up = float(earth.w_ie_n(m.lat)[2] + earth.w_en_n(m.lat, m.h, m.v_n)[2])
            # the gyro's own rotation (compensations undone), less the chain's drift
            self.psi += (A * (1.0 + self.scale) + (eps_applied - self.eps_ref) * T
                         - w_up * T)
        self.t = t
        self._eps_now = (eps, var_eps, q_eps)
        if not self.chain and self.leg is None:      # a chain's drift: the estimate now
            self.eps_ref, self._eps = eps, (var_eps, q_eps)
        rate = self._rate.add(t, self.psi)
        straight = rate <= MAX_YAW_RATE and math.hypot(m.v_n[0], m.v_n[1]) >= MIN_SPEED
        leg = self.leg
        if leg is not None and (not straight or abs(self.psi - leg.yaw0) > STRAIGHT
                                or t - leg.t0 > MAX_LEG_S):
            self.leg = None
            if math.isfinite(rate) and rate > MAX_YAW_RATE:   # ends on a turn: its first epochs
                leg.trim(self._rate.since())
            self._judge(leg, prior_var, engine)
        if straight:
            self._join(t, fix)

    def _join(self, t, fix):
        if self.leg is None:
            self.leg = Leg(t, self.psi)
        self.leg.add(t, self.psi, 0.0, fix,
                     epoch_var(self.pos_var, fix.pos_var, self.use_reported))

    def _markov_var(self, leg):
        """Return the Gauss-Markov position variance of a positions-only leg (m^2).

        The configured one; without it (``gnss_position_only_markov``) four times the
        leg's mean fix variance, as the engine's Gauss-Markov states take it
        (:mod:`..engines.factory`).
        """
        if self.markov_var > 0.0 or not self.markov_from_fixes:
            return self.markov_var
        return 4.0 * float(np.mean(leg.pos_var))

    def _judge(self, leg, prior_var, engine):
        """Judge a finished leg; add it to the chain through the gate; estimate."""
        if len(leg.t) < MIN_EPOCHS or leg.duration < MIN_LEG_S:
            return
        res = fitted_course(leg, self._markov_var(leg), self.markov_tau)
        if res is None:
            return
        D, sig_c = res
        new = [float(np.mean(leg.t)), float(np.mean(leg.yaw)), D, sig_c * sig_c + self.var_s]
        prior = self._prior or (0.0, prior_var)
        if self.chain:
            new[2] = self.chain[0][2] + wrap(D - self.chain[0][2])   # unwrapped along it
            k = self._k(prior)
            (nu, S), = self._run_chain(prior, k, [new])[2][-1:]
            if nu * nu > chi2_quantile(GATE_PROBABILITY, 1) * S:
                self.n_rejected += 1
                self._run += 1
                if self._run >= MAX_REJECTED:
                    self._turn_off(engine, nu)
                return
            if abs(new[1] - self.chain[-1][1]) >= MIN_TURN:
                self.n_turns += 1
        self._run = 0
        self.chain.append(tuple(new))
        self.n_legs += 1
        if self.n_turns < MIN_TURNS:
            return
        x, P, _ = self._run_chain(prior, self._k(prior))
        s, sigma = float(x[1]), math.sqrt(float(P[1, 1]))
        if not engine.set_turn_scale(s, sigma):       # the states carry it now
            self.off, self.estimate = True, None
            return
        self.estimate = (s, sigma)
        self.scale = s
        if len(self.chain) >= MAX_CHAIN:
            self._new_chain()

    def _k(self, prior):
        """Return the legs' noise scale: the chain's mean NIS where above 1 (module docstring)."""
        nis = [nu * nu / S for nu, S in self._run_chain(prior, 1.0)[2][1:]]
        return max(1.0, float(np.mean(nis))) if len(nis) >= MIN_FOR_K else 1.0

    def _run_chain(self, prior, k, extra=()):
        """Kalman filter ``(b, s, d)`` over the chain's legs (and ``extra``): ``(x, P, innov)``.

        ``innov``: ``(nu, S)`` per leg, the legs' noise scaled by ``k``.
        """
        var_d, q = self._eps
        x = np.array([0.0, prior[0], 0.0])
        P = np.diag([OFFSET_VAR, prior[1], var_d])
        innov, t_prev = [], None
        for t, psi, D, r in list(self.chain) + list(extra):
            if t_prev is not None:
                dt = t - t_prev
                F = np.array([[1.0, 0.0, -dt], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
                Q = q * np.array([[dt ** 3 / 3.0, 0.0, -dt * dt / 2.0], [0.0, 0.0, 0.0],
                                  [-dt * dt / 2.0, 0.0, dt]])
                x, P = F @ x, F @ P @ F.T + Q
            t_prev = t
            h = np.array([1.0, -(psi - self.chain[0][1] if self.chain else 0.0), 0.0])
            nu = D - float(h @ x)
            S = float(h @ P @ h) + k * r
            innov.append((nu, S))
            K = P @ h / S
            x = x + K * nu
            P = P - np.outer(K, h @ P)
            P = 0.5 * (P + P.T)
        return x, P, innov

    def _new_chain(self):
        """Start a new chain from the last estimate (its prior), if any, and the drift now."""
        if self.chain and self.estimate is not None:
            self._prior = (self.estimate[0], self.estimate[1] ** 2)
        self.chain = []
        if self._eps_now is not None:
            self.eps_ref, var_eps, q_eps = self._eps_now
            self._eps = (var_eps, q_eps)

    def _turn_off(self, engine, nu):
        self.off = True
        self.scale = 0.0
        self.estimate = None
        engine.set_turn_scale(0.0, None)
        self.finding = (f'{self._run} straight legs in a row had a GNSS course '
                        f'{math.degrees(nu):+.1f} deg off what the gyro heading and a scale '
                        'factor allow, beyond the courses\' noise (the vehicle reverses, '
                        'skids or crabs): the up gyro\'s scale factor is no longer measured '
                        'from turns; the told one is modelled')

    def status(self):
        """Figures for diagnostics."""
        s = {'turn_scale_on': not self.off, 'turn_scale_turns': self.n_turns,
             'turn_scale_legs': self.n_legs, 'turn_scale_rejected': self.n_rejected}
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

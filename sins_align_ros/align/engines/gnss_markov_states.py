"""The receiver's Gauss-Markov position error as three filter states (issue 44).

:mod:`.gnss_markov` decorrelates a consumer receiver's slow position error without new
states: the ``measurement`` form gives each fix the white-equivalent of the error,
``sigma^2 (1 + rho) / (1 - rho)`` (1.5 m over 60 s at 2.5 Hz: a 26 m sigma per fix), so
the short-lag differences of the positions, where a position-only robot's tilt and
heading come from, count as little as the long-lag ones. Here the error is what the
textbooks give for coloured measurement noise: a state per ENU axis, appended to the
navigation filters' model once the model is active (Brown & Hwang, *Introduction to
Random Signals and Applied Kalman Filtering*, 4th ed., 2012, the first-order
Gauss-Markov process and state augmentation for coloured measurement noise)::

    x = [... seed model ... | b_E b_N b_U]  (the gyro scale factors may follow them)
    b' = -b / tau + w,    E[w w^T] = 2 sigma^2 / tau  I,    b(0) ~ N(0, sigma^2 I)
    z_p = p_INS - p_GNSS = dp - b - v           (position rows; velocity rows unchanged)

The states are not navigation errors: the feedback leaves them in the state (every other
state returns to zero after an epoch) and the transition decays them by
``exp(-T / tau)``. The unscented filter propagates its sigma points' nonlinear part
without them and decays them alongside. Their prior is taken independent of the
position error: the filter's position came from a fix that carried the same ``b``, so the
difference ``dp - b`` is in truth smaller than the filter assumes at first
(conservative). When the model's sigma grows (each fix's own sigma taken as the
error's on a position-only receiver, the long-horizon test's widening,
:meth:`~.gnss_markov.GnssMarkov.widen`), the states' variance grows by the difference and
their drive follows.

A position-only receiver whose error nobody told (``gnss_position_only_markov``,
:mod:`.gnss_markov`) has it assumed at :data:`ASSUMED_FACTOR` times each fix's own
horizontal sigma: a standalone receiver's slow error is larger than the sigma it reports
(issue 44's receivers: 1.5 m under a reported 0.9 m), and here an optimistic guess costs
integrity where a conservative one costs little. Measured (car:posonly, plain MEMS,
seed 1002, ``kf`` with node defaults; robot:posonly, seed 1000), factor 1 / 1.5 / 2:
heading rows outside 3 sigma 5.9 % / 0 / 0 with its sigma at the end 2.02 / 2.12 / 2.22
deg; the robot's tilt sigma 25.1' / 25.1' / 25.4'. (The ``measurement`` form keeps the
fix's own sigma: its white equivalent is conservative by far already.)

Which filters: those whose R the engine sets (``kf``, ``ukf``); the filters that estimate
R themselves keep :mod:`.gnss_markov`'s ``process`` form, as does seed 000's engine
(:mod:`.moving`). Not in the seeds (their receivers are RTK or modelled white).
"""
import math

import numpy as np

from ...filters.cubature import batched

#: the states, one per ENU axis
N_MARKOV = 3
#: a position-only receiver's error is assumed correlated at this many times each fix's
#: own horizontal sigma (module docstring)
ASSUMED_FACTOR = 2.0


class GnssMarkovStates:
    """Mixin of the navigation engines: the receiver's Gauss-Markov error as states.

    Uses the engine's ``kf``, ``n``, ``rows``, ``MEAS_ENU``, ``_append_states`` and
    ``_raise_Qc`` (:class:`~.process_noise.ProcessNoise`),
    ``gnss_markov`` (:class:`~.gnss_markov.GnssMarkov`, method ``state``) and
    ``_fix_sigma_h``. The engine calls :meth:`_before_epoch` before each GNSS epoch's
    transition, builds its measurement function with :meth:`_hx`, pads its ``F`` with
    :meth:`_markov_columns` and keeps the states through its feedback
    (:meth:`_kept_state`).
    """

    #: the engine can carry the states (``set_gnss_markov`` then picks the ``state`` form)
    markov_states = True
    #: slice of the states in the state vector; None: not there
    i_gm = None
    #: the sigma (m) the states' variance and drive were last given
    gm_sigma = 0.0

    def _before_epoch(self, fix):
        """Append the states once the model is active; widen them when its sigma grew."""
        gm = self.gnss_markov
        if gm is None or gm.method != 'state':
            return
        if gm.from_fixes:
            gm.assume(ASSUMED_FACTOR * self._fix_sigma_h(fix))
        if not gm.active or gm.sigma <= self.gm_sigma:
            return
        q = 2.0 * gm.sigma ** 2 / gm.tau
        if self.i_gm is None:
            self.i_gm = self._append_states(np.full(N_MARKOV, gm.sigma ** 2),
                                            np.full(N_MARKOV, q))
        else:
            k = np.arange(self.n)[self.i_gm]
            P = self.kf.P.copy()
            P[k, k] += gm.sigma ** 2 - self.gm_sigma ** 2
            self.kf.P = P
            self._raise_Qc(k, q)
        self.gm_sigma = gm.sigma

    def _markov_in_R(self):
        """Tell whether the error goes into R (as well as into the states): heading unknown.

        While the heading is lost or published as unknown, the direction of every
        horizontal force is, and with it the model's position: the error's white
        equivalent (:mod:`.gnss_markov`'s ``measurement`` form) is added to R on top of the
        states, so the positions do not pull the tilt toward a force put in the wrong
        direction. Measured (robot:posonly, plain MEMS, seed 1000, the course heading off so
        the heading stays lost all run): the states alone had 15 % of the tilt rows outside
        3 sigma (240' off under 54'), with this none.
        """
        if self.gnss_markov.method != 'state':
            return super()._markov_in_R()
        return bool(self.heading_lost or not self.heading_claimed)

    def _markov_columns(self, F):
        """Put ``-1 / tau`` on the states' diagonal of ``F`` (n, n; padded already), in place."""
        if self.i_gm is not None:
            k = np.arange(self.n)[self.i_gm]
            F[k, k] = -1.0 / self.gnss_markov.tau

    def _markov_decayed(self, fx, T):
        """Return ``fx`` (batched, the states without these) run beside their decay over ``T`` s.

        For a propagation that knows the seed model only (the unscented filter's
        nonlinear one): the states are taken out, decayed by ``exp(-T / tau)``, put back.
        """
        if self.i_gm is None:
            return fx
        k = np.arange(self.n)[self.i_gm]
        rest = np.setdiff1d(np.arange(self.n), k)
        decay = math.exp(-T / self.gnss_markov.tau)

        def f(X):
            out = np.empty_like(X, dtype=float)
            out[rest] = fx(X[rest])
            out[k] = decay * X[k]
            return out
        return batched(f)

    def _hx(self, idx):
        """Return the measurement function (batched) of full-vector rows ``idx``: ``dp - b``."""
        if self.i_gm is None:
            return super()._hx(idx)
        rows = self.rows[idx]
        axes = np.asarray(self.MEAS_ENU)[idx]
        pos = axes < 3
        b = np.arange(self.n)[self.i_gm][axes[pos]]

        def h(X):
            Y = X[rows]                     # (a copy: fancy indexing)
            Y[pos] -= X[b]
            return Y
        return batched(h)

    def _kept_state(self, x):
        """Return the state after the feedback: zero, but for these states (kept)."""
        out = np.zeros(self.n)
        if self.i_gm is not None:
            out[self.i_gm] = x[self.i_gm]
        return out

    def markov_status(self):
        """Diagnostics figures: the receiver error estimated and its 1-sigma (m, E N U)."""
        if self.i_gm is None:
            return {}
        sd = np.sqrt(np.diag(self.kf.P)[self.i_gm])
        return {'gnss_markov_estimate_m': [float(v) for v in self.kf.x[self.i_gm]],
                'gnss_markov_sigma_m': [float(v) for v in sd]}

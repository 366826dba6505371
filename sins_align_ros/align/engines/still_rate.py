"""The vertical gyro drift measured while a GNSS-aided base stands still (zero rate).

A car at a traffic light, a robot waiting for its mission: GNSS says the base is not
moving, so the body does not turn either (a vehicle at rest does not spin in place). Its
gyros then measure the Earth rate and their drift alone. The Earth rate's vertical part,
``Omega sin L``, does not depend on the heading, so the rate about the local vertical
measures the vertical gyro drift to ``ARW / sqrt(T)`` after ``T`` s at rest, whatever the
heading is. Without this measurement the drift is unobservable at rest (it only turns an
unmeasured heading), and a MEMS vehicle that stood still for half a minute starts to
drive with its turn-on drift whole: 200 deg/h turned the heading of the simulated MEMS
car with RTK by a degree in the 15 s after it drove off (``car_rtk``, issue 46).

The measurement, at every GNSS epoch whose fix shows the base at rest (the engine's
``_at_rest``: a velocity within 3 of its sigmas and :data:`REST_SPEED_MAX`): the
interval's mean body rate ``w_b`` (compensated as the mechanization used it), taken about
the local vertical, minus the Earth rate's vertical part::

    z = (C_b_n w_b)_U - Omega sin L = (C_b_n eps)_U - Omega cos L phi_E + noise

(``C_b_n`` the estimate, ``C_true = (I + [phi x]) C_b_n``; ``eps`` the drift states). Its
variance is the larger of the model's ``ARW^2 / T`` (its current Qc, widened by the
monitors) and the scatter of the interval's own rate samples over their number, so a
vibrating or rocking base is not taken for a quiet one. The body must look still on the
epoch and on the one before (:data:`STILL_EPOCHS`): the vertical innovation inside the
GNSS gate's probability, and the horizontal rate inside the drift's and the Earth rate's
reach (:meth:`StillRate._turning`). A base that turns while its antenna stands (a robot
spinning in place) is refused, and so is a moored ship, which rolls and pitches at the
instants its yaw rate passes zero; a refused epoch is not a GNSS rejection.

The navigation filters (:mod:`.navigation`: drift in body axes, fed back into the
compensation) and seed 000's (:mod:`.moving`: drift resolved in the computed frame, kept
in the state, so the row is that state's vertical component) take it; seed 004's
(:mod:`.robust`, a ship's or USV's) does not.

Not from a seed: the seeds' moving-base filters take GNSS position and velocity alone.
Zero-angular-rate updates are common practice in pedestrian and land INS (e.g. Groves,
*Principles of GNSS, Inertial and Multisensor Integrated Navigation*, 2nd ed., sec.
15.3.3); the horizontal rows only test for rest and are not measured, because their
Earth-rate term carries the heading, which may still be far outside the linear model when
the base rests.
"""
import math

import numpy as np

from ...nav import earth
from ..inputs.heading import heading_update
from ...filters.chi2 import chi2_quantile
from .gnss_gate import FilterDiverged

#: the fastest fix (m/s) a base is taken at rest at: 3 sigmas of the velocity noise, at
#: most this (an engine whose velocity noise was widened must not take a drive for rest)
REST_SPEED_MAX = 0.5
#: epochs in a row the body must look still (:meth:`StillRate._turning`) before its rate
#: is taken: the first epoch of a stop, and a swaying base's lucky instant, are not
STILL_EPOCHS = 2
#: the gate's probability when the GNSS gate is off: a turning base is refused anyway
GATE_PROBABILITY = 0.9999


class StillRate:
    """Zero-rate epochs of a base at rest; a mixin of the GNSS-aided engines.

    Uses the engine's ``kf``, ``mech``, ``Qc``, ``gate``, ``i_phi``, ``_eps_slices``,
    ``gyro_bias`` and ``_feedback``; the engine calls :meth:`_count_still_rate` with each
    block of compensated increments and :meth:`_still_rate_epoch` after each GNSS epoch.
    """

    #: zero-rate epochs used, refused
    n_still_rate = n_still_rate_refused = 0
    #: epochs in a row the body has looked still
    _still_run = 0
    #: the interval's rate sums (:meth:`_still_rate_start`); None before the first sample
    _sr_sum = None
    _sr_n, _sr_T = 0, 0.0

    def _still_rate_start(self):
        """Start a new interval of rate sums (at every GNSS epoch)."""
        self._sr_sum = np.zeros(3)
        self._sr_sq = np.zeros(3)
        self._sr_n = 0
        self._sr_T = 0.0
        self._sr_eps = np.array(self._rate_compensation(), dtype=float)

    def _count_still_rate(self, dtheta, dt):
        """Add compensated increments ``dtheta`` ((3,) or (N, 3), rad) over ``dt`` s."""
        if self._sr_sum is None:
            self._still_rate_start()
        d = np.asarray(dtheta, dtype=float)
        if d.ndim == 1:                 # one sample (the live node's path)
            r = d / dt
            self._sr_sum += d
            self._sr_sq += r * r
            self._sr_n += 1
            self._sr_T += float(dt)
            return
        w = np.asarray(dt, dtype=float).reshape(-1)
        r = d / w[:, None]
        self._sr_sum += np.add.reduce(d, axis=0)
        self._sr_sq += np.add.reduce(r * r, axis=0)
        self._sr_n += len(d)
        self._sr_T += float(np.add.reduce(w))

    def _still_rate_epoch(self, at_rest):
        """Update with the zero rate of the interval just ended when ``at_rest``.

        The body must look still on this epoch and the one before it
        (:data:`STILL_EPOCHS`): its vertical rate inside the gate (the GNSS gate's
        probability) and its horizontal rate too (:meth:`_turning`). Returns True (used),
        False (refused: turning) or None (not at rest, or the first still epoch).
        """
        T, n = self._sr_T, self._sr_n
        if not at_rest or T <= 0.0 or n < 2:
            self._still_rate_start()
            self._still_run = 0
            return None
        w_b = self._sr_sum / T - (self._rate_compensation() - self._sr_eps)
        scatter = np.maximum(self._sr_sq / n - (self._sr_sum / T) ** 2, 0.0)
        self._still_rate_start()
        m, kf = self.mech, self.kf
        C = m.C_b_n
        k = np.arange(len(kf.x))
        q_arw = float(self.Qc[k[self.i_phi][2]])
        # the measurement noise about each ENU axis: the model's ARW over T, or the
        # interval's own scatter where larger
        R = np.maximum(q_arw / T, (C ** 2 @ scatter) / n)
        w_n = C @ w_b
        p = self.gate.probability or GATE_PROBABILITY
        H = self._zero_rate_row(C, m.lat)
        y = float(w_n[2]) - earth.OMEGA_IE * math.sin(m.lat) - float(H @ kf.x)
        S = float(H @ kf.P @ H) + float(R[2])
        if y * y / S > chi2_quantile(p, 1) or self._turning(w_n, R, C, m.lat, p):
            self._still_run = 0
            self.n_still_rate_refused += 1
            return False
        self._still_run += 1
        if self._still_run < STILL_EPOCHS:
            return None
        x, P, y, S, ok = heading_update(kf.x, kf.P, H, y, float(R[2]))
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
            raise FilterDiverged('filter diverged in a zero-rate update')
        kf.x, kf.P = x, P
        self.n_still_rate += 1
        self._feedback(None)
        return True

    def _turning(self, w_n, R, C, lat, p):
        """Tell whether the interval's mean rate ``w_n`` (3,) ENU shows the body turning.

        Its horizontal part against the Earth rate's, ``(0, Omega cos L)``, with the
        drift's variance about each axis, the noise ``R`` (3,) and a heading error's share
        of the Earth rate (up to ``2 Omega cos L``, conservatively); the test is the
        chi-square quantile of ``p`` with 2 degrees of freedom. A swaying ship rolls and
        pitches as it yaws: at the instants its yaw rate passes zero, its roll or pitch rate
        does not, and the epoch is not taken for rest.
        """
        wc = earth.OMEGA_IE * math.cos(lat)
        r = w_n[:2] - np.array([0.0, wc])
        P = self.kf.P
        nis = 0.0
        for a in (0, 1):
            h = np.zeros(len(self.kf.x))
            self._drift_row(h, C, a)
            var = float(h @ P @ h) + float(R[a]) + (2.0 * wc) ** 2
            nis += r[a] ** 2 / var
        return nis > chi2_quantile(p, 2)

    def _rate_compensation(self):
        """Return the drift (3,) rad/s the increments are compensated by (none here)."""
        return np.zeros(3)

    def _zero_rate_row(self, C, lat):
        """Return the measurement row (n,) of the vertical rate's error.

        ``-Omega cos L phi_E`` (the tilt turns the horizontal Earth rate into the
        vertical), plus the drift's vertical component (:meth:`_drift_row`); ``C`` (3, 3)
        the attitude, ``lat`` rad.
        """
        n = len(self.kf.x)
        H = np.zeros(n)
        H[np.arange(n)[self.i_phi][0]] = -earth.OMEGA_IE * math.cos(lat)
        self._drift_row(H, C)
        return H

    def _drift_row(self, H, C, axis=2):
        """Put the drift's row about ENU ``axis`` into ``H`` (n,): body-axis states, ``C eps``."""
        k = np.arange(len(H))
        for sl in self._eps_slices():
            H[k[sl]] = C[axis]

    def _eps_slices(self):
        """Return the slices of the gyro-drift states (their sum is the drift)."""
        return (self.i_eps,)

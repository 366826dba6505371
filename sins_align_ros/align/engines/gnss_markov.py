"""A GNSS receiver's time-correlated position error, and how the aided filters take it.

A consumer receiver's position error is about 1 m of white noise plus a first-order
Gauss-Markov (GM) error of about 1.5 m with a correlation time of about a minute
(multipath, atmosphere, orbit and clock: the simulator's ``GnssSpec.pos_markov_*``),
while the covariance it reports describes the white part. A filter that takes the
fixes as white believes it can average the GM error away: at 5 Hz it takes 60 s of
positions for 300 independent ones, where they are worth about one, and the velocity
the positions imply (where a position-only robot's heading comes from) for several
times better than it is.

The GM error per ENU axis (Brown & Hwang, *Introduction to Random Signals and Applied
Kalman Filtering*, 4th ed., 2012: the first-order Gauss-Markov process, its
autocorrelation and its discrete model; Gelb (ed.), *Applied Optimal Estimation*, 1974,
ch. 3's random-process models)::

    b' = -b / tau + w,    E[b(t) b(t + L)] = sigma^2 exp(-|L| / tau),
    Var[b(t + L) - b(t)] = 2 sigma^2 (1 - exp(-L / tau)) <= 2 sigma^2 L / tau = q L.

The textbooks' exact treatment of such coloured measurement noise is to augment the
state with ``b`` (Brown & Hwang and Gelb, coloured measurement noise; Bar-Shalom, Li &
Kirubarajan, *Estimation with Applications to Tracking and Navigation*, 2001, on
autocorrelated measurement noise). Here it is
done so in the navigation filters that set their own R (``kf``, ``ukf``: the ``state``
form, :mod:`.gnss_markov_states`, the default there since session 44). Elsewhere it is
decorrelated without new states, in one of two ways (:attr:`GnssMarkov.method`):

``process``: the GM error is taken as a random walk of the measured
    position, of density ``q = 2 sigma^2 / tau``: before each GNSS update the variance
    of the measured position states is raised by ``q dt`` (dt the time since the
    previous GNSS epoch, at most ``tau``). By the inequality above the random walk's
    increments are at least as large as the GM's at every lag, so the filter never
    takes two fixes' difference, and the velocity it implies, for better than it is;
    over lags much shorter than tau the two agree (the claim is tight where the
    velocity and heading come from). Where we differ from the augmented state: the
    filter's position follows the receiver's slow error (its absolute position sigma
    lacks ``sigma``; alignment does not use it), and beyond tau the random walk is
    conservative (``q L`` against ``2 sigma^2``).
``measurement`` (the default): each fix's noise variance is raised by the
    white-equivalent of the GM error sampled every dt, ``sigma^2 (1 + rho) / (1 - rho)``
    with ``rho = exp(-dt / tau)`` (the variance factor of the mean of an AR(1) sequence;
    about ``2 sigma^2 tau / dt``, the GM spectrum at zero frequency over dt, which bounds
    the GM spectrum at every frequency: conservative everywhere). Honest over long
    windows, but it takes short-lag differences for as noisy as long-lag ones: with
    1.5 m / 60 s at 5 Hz each fix gets a 37 m sigma. Filters whose R is their own
    estimate (Sage-Husa ASCKF, the variational-Bayes family) get the ``process`` form.

Which is better, measured (bench/integrity.py's robot:posonly cells, plain MEMS, seeds
1000-1004, ``kf`` and ``ukf`` told the node's defaults and the right model, 20 runs
each, the model told 1.5 m / 60 s): ``measurement`` 0 silent-wrong runs (tilt sigma 2.4
deg), ``process`` 5 (tilt sigma 1.2-1.3 deg), none 4; the heading was unknown in all.
On car:consumer (Doppler velocity) neither moved the attitude or its sigma by more
than 0.01 deg: the velocity carries the heading there. So ``measurement`` was the
default; the augmented state (``state``, :mod:`.gnss_markov_states`) has since replaced it
in ``kf`` and ``ukf``, keeping the short-lag information ``measurement`` gives away
(robot:posonly ``kf``: tilt sigma 32-38' -> 24-26', every cell honest;
bench/results/integrity_gnss_states.md). ``measurement`` stays the form of seed 000's
engine and, on top of the states, of any epoch whose heading is unknown.

A side effect to know: taken as white, the correlated error made the 10-epoch
consistency monitor inflate the state (its innovations persist: "a model error"), which
also covered IMU errors the model lacks. Modelled, that inflation stops: on car_consumer
with its raw MEMS AHRS triads (gyro and accelerometer scale factors, misalignment), told
the sensors, seed 1001's east tilt goes from 3.3 % to 9 % of the 1-s rows outside 3 sigma
(0.36 deg off under 0.12 deg: the tilt / accelerometer-bias split the turns corrupt),
seeds 1000-1003 from 1 to 2 silent-wrong runs. The remedy belongs to the IMU model.

A position-only receiver (no GNSS velocity when the fine stage starts; the simulator's
``posonly`` receivers, the first-hour robot) with ``gnss_position_markov_sigma_m`` 0 has
each fix's horizontal sigma (reported, else configured) taken as a GM error of ``tau``
as well (:attr:`GnssMarkov.from_fixes`, :meth:`GnssMarkov.assume`; parameter
``gnss_position_only_markov``): its heading comes from position differences alone, and a
standalone receiver's error is mostly the correlated kind, which the long-horizon test
rarely sees because the filter's position and velocity states absorb it (innovations
averaged over 20-s blocks at 2.0x white against a bound of 7.1). Measured on the
integrity matrix's car:posonly cells told the defaults (receiver 0.8 m white + 1.5 m GM
over 60 s reporting 0.9 m; 10 runs each, seeds 1000-1009): silent-wrong runs
``kf``/``ukf`` plain MEMS 2/2 -> 0/0, raw AHRS triads 3/2 -> 0/0, ``asckf`` MEMS 2 -> 1;
heading sigma at the end 1.9-2.0 -> 2.7-3.2 deg with the heading RMS 1.7 -> 1.4-1.7 deg
(the right model gives 3.3 deg). The price: robot:posonly ``kf`` tilt sigma 1.2 -> 2.1
deg (RMS 0.4-0.5 -> 0.2-0.3 deg). With Doppler velocity nothing changes.

Otherwise, with ``sigma`` 0 (the default of ``gnss_position_markov_sigma_m``) nothing
changes.
The consistency monitor's long-horizon test (:class:`~.consistency.LongHorizonTest`)
switches the model on, or widens it, when the innovations show errors correlated over
tens of seconds (:meth:`GnssMarkov.widen`; never narrowed).
"""
import math

import numpy as np

METHODS = ('process', 'measurement', 'state')
#: largest GM sigma the long-horizon test widens the model to, m
MAX_SIGMA = 30.0


def increment_var(sigma, tau, L):
    """Variance (m^2) of a GM error's change over ``L`` s: ``2 sigma^2 (1 - exp(-L / tau))``."""
    return 2.0 * sigma ** 2 * -math.expm1(-L / tau)


def random_walk_var(sigma, tau, dt):
    """``q dt`` (m^2), ``q = 2 sigma^2 / tau``: the random walk bounding the GM's increments."""
    return 2.0 * sigma ** 2 / tau * dt


def white_equivalent_var(sigma, tau, dt):
    """``sigma^2 (1 + rho) / (1 - rho)``, ``rho = exp(-dt / tau)`` (m^2): one fix's share.

    The variance of the mean of N samples of the GM error taken every dt s is, for large
    N, this divided by N: N fixes are worth N white ones of this variance.
    """
    if dt <= 0.0:
        return math.inf
    rho = math.exp(-dt / tau)
    return sigma ** 2 * (1.0 + rho) / -math.expm1(-dt / tau)


class GnssMarkov:
    """The GM position error an aided engine assumes (module docstring).

    ``sigma`` (m, per ENU axis), ``tau`` (s), ``method`` one of :data:`METHODS`. The engine
    calls :meth:`epoch` with each fix's stamp before its update; ``widenings`` counts the
    long-horizon test's widenings, ``sigma0`` the sigma configured.
    """

    def __init__(self, sigma=0.0, tau=60.0, method='measurement'):
        if method not in METHODS:
            raise ValueError(f'unknown method {method!r}')
        self.sigma = self.sigma0 = float(sigma)
        self.tau = float(tau)
        self.method = method
        self.widenings = 0
        #: take each fix's horizontal sigma as a GM sigma too (:meth:`assume`; a
        #: position-only receiver, module docstring)
        self.from_fixes = False
        self._t_last = None
        #: seconds since the previous fix, as :meth:`epoch` last took them
        self.dt = 0.0

    @property
    def active(self):
        """Tell whether the model adds anything (a sigma above zero)."""
        return self.sigma > 0.0

    def epoch(self, t):
        """Take the fix stamped ``t`` (s); returns the seconds since the previous one.

        At most ``tau`` (beyond it the fixes are about independent) and 0 for the first.
        """
        dt = 0.0 if self._t_last is None else min(max(t - self._t_last, 0.0), self.tau)
        self._t_last = t
        self.dt = dt
        return dt

    def assume(self, sigma):
        """Raise ``sigma`` to at least ``sigma`` m (:attr:`from_fixes`); never narrow it."""
        if sigma > self.sigma and math.isfinite(sigma):
            self.sigma = float(min(sigma, MAX_SIGMA))

    def process_var(self, dt):
        """Variance (m^2) to add to each measured position state before an update (process)."""
        return random_walk_var(self.sigma, self.tau, dt) if self.active else 0.0

    def measurement_var(self, dt):
        """Variance (m^2) to add to each position row's noise (``measurement``); 0 at dt 0."""
        if not self.active or dt <= 0.0:
            return 0.0
        return white_equivalent_var(self.sigma, self.tau, dt)

    def widen(self, excess_var, block_s):
        """Widen by an excess ``excess_var`` (m^2) of ``block_s``-second innovation means.

        The long-horizon test's remedy (:class:`~.consistency.LongHorizonTest`). The
        excess is what the means of the innovations over ``block_s`` kept of an error
        the filter did not expect: read as a Gauss-Markov error's change over a block,
        ``2 sigma^2 (1 - exp(-block_s / tau))`` (:func:`increment_var`), it adds
        ``excess_var / (2 (1 - exp(-block_s / tau)))`` to sigma^2 (capped at
        :data:`MAX_SIGMA`). A step, not an estimate: the test repeats on the widened
        filter's innovations until they look white over the blocks. Never narrows.
        Returns ``(old, new)`` sigma (m).
        """
        old = self.sigma
        var = excess_var / increment_var(1.0, self.tau, block_s)
        if var > 0.0 and math.isfinite(var):
            self.sigma = min(math.sqrt(self.sigma ** 2 + var), MAX_SIGMA)
            if self.sigma > old:
                self.widenings += 1
        return old, self.sigma

    def status(self):
        """Figures for diagnostics."""
        return {'gnss_position_markov_sigma_m': self.sigma,
                'gnss_position_markov_tau_s': self.tau,
                'gnss_position_markov_widenings': self.widenings}


def position_rows(meas_enu):
    """Rows of the full measurement vector that measure a position (ENU axis < 3)."""
    return np.flatnonzero(np.asarray(meas_enu) < 3)

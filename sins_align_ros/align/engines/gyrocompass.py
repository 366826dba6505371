"""The gyrocompass heading of a still base, as measurements for the still-base filter.

Issue 46. The seed 002 filter finds the heading from the tilt drift it causes, read through
the accelerometers' noise; the averaged gyros of a base that does not turn give it
directly, to ``ARW / (W cos L sqrt(T))`` (the analytic coarse alignment). This module says
how much gyro time may be taken that way, and gathers the live samples into segments whose
analytic heading the engine takes as a measurement
(:meth:`~.stationary.StationaryEngine.gyrocompass_update`); the window's own heading is the
first one (:func:`~..stages.reprocess.window_heading`).

**Not counting a sample twice.** The filter's drift route draws on the same gyro samples,
through the accelerometers: its heading variance from ``T`` s of data is about
``12 (VRW/g)^2 / (W cos L)^2 / T^3`` (a slope fitted to a tilt read with white noise)
plus the gyro term ``ARW^2 / (W cos L)^2 / T``. Its gyro share is small while the first
term is the larger one; the two are equal at ``T = sqrt(12) (VRW/g) / ARW``. Measurements
are taken only while the data seen is under half of that (:func:`gyro_span`): there the
drift route's gyro share is at most a fifth (navigation grade: about 60 s; tactical:
about 6 s, so none). Disjoint segments have independent white noise, and the biases they
share are states of the filter, in each measurement's row.

A segment is dropped when any zero-velocity epoch in it was refused or the engine coasted
(the base moved: its averaged gyros are no heading).
"""
import numpy as np

from ...nav import coarse, earth
from ..inputs.heading import yaw_of

#: length of a live segment, s
SEGMENT_S = 10.0


def heading_variance_rate(noise, lat):
    """Return the gyrocompass heading's white-noise variance times its averaging time (rad^2 s).

    ``noise``: a NoiseSpec (the densities the samples show where they exceed the configured
    ones); ``lat`` rad. The east gyro's mean over the horizontal Earth rate, plus the
    north tilt's noise through ``tan L`` (the heading of a leveled body, seed 002 eq. 15).
    """
    wc = earth.OMEGA_IE * np.cos(lat)
    g = earth.gravity(lat, 0.0)
    return (noise.gyro_arw / wc) ** 2 + (np.tan(lat) * noise.accel_vrw / g) ** 2


def gyro_span(noise, lat):
    """Return the data span (s) over which gyrocompass measurements may be taken.

    Half the time at which the filter's drift route's accelerometer and gyro terms are
    equal, ``sqrt(3) (VRW/g) / ARW`` (module docstring); infinite without gyro noise.
    """
    g = earth.gravity(lat, 0.0)
    if noise.gyro_arw <= 0.0:
        return np.inf
    return float(np.sqrt(3.0) * (noise.accel_vrw / g) / noise.gyro_arw)


class GyroSegments:
    """Live segments of a still base's samples, each giving a gyrocompass heading.

    ``rate_var``: :func:`heading_variance_rate`; ``lat`` rad; ``span`` s: how much more
    gyro time may be taken (:func:`gyro_span` less what the window took); ``skip`` s: the
    samples not to gather first (the window's, which the stage runs over again after
    taking their heading).
    """

    def __init__(self, rate_var, lat, span, skip=0.0):
        self.rate_var = float(rate_var)
        self.lat = float(lat)
        self.left = float(span)
        self.skip = float(skip)
        #: measurements taken, segments dropped
        self.n_taken = 0
        self.n_dropped = 0
        self._reset()

    def _reset(self):
        self.sum_dtheta = np.zeros(3)
        self.sum_dv = np.zeros(3)
        self.T = 0.0
        self.spoilt = False

    @property
    def done(self):
        """Tell whether no more gyro time may be taken."""
        return self.left < SEGMENT_S

    def add(self, dtheta, dv, dts):
        """Add samples ``dtheta``, ``dv`` (N, 3) over ``dts`` (N,) s (or skip them)."""
        if self.skip > 1e-9:
            self.skip -= float(np.sum(dts))
            return
        self.sum_dtheta += np.sum(dtheta, axis=0)
        self.sum_dv += np.sum(dv, axis=0)
        self.T += float(np.sum(dts))

    def spoil(self):
        """Mark the segment unusable (a refused zero-velocity epoch, a coast)."""
        self.spoilt = True

    def take(self):
        """Return ``(yaw, var)`` of a full, clean segment and start the next, or None."""
        if self.T < SEGMENT_S - 1e-9:
            return None
        T, spoilt = self.T, self.spoilt
        C = coarse.triad(self.sum_dv / T, self.sum_dtheta / T, self.lat)
        self._reset()
        self.left -= T
        if spoilt:
            self.n_dropped += 1
            return None
        self.n_taken += 1
        return yaw_of(C), self.rate_var / T

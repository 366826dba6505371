"""The coarse window: its samples, and when the attitude they give is good enough.

:class:`CoarseWindow` collects the samples from ``t_first`` for ``coarse_duration``
seconds, ends early once a still base's attitude is good enough (:func:`good_enough`,
issue 46) or GNSS shows the vehicle start to move (:class:`~..inputs.motion.Onset`), and
holds a MEMS window open a minute where ``auto`` has no GNSS (:data:`DRIVE_TEST_S`).
:func:`coarse_sigma` is the conservative bound on what a coarse alignment over ``T``
seconds leaves, with :func:`seen_noise` the white noises the samples show; the coarse
stage (:mod:`.coarse_stage`) hands it to the fine filter, and the forecast
(:mod:`~..forecast.expectation`) reads :func:`expected_duration`.
"""
import math
from dataclasses import replace

import numpy as np

from ...models.stationary import sees_earth_rate
from ...nav import coarse, earth
from ...units import DEG, DPH, DPSH
from .noise_estimates import difference_density


#: the shortest window over which ``auto`` without GNSS takes the IMU's "no drive" for
#: rest, s (:meth:`CoarseWindow.hold_for_drive_test`; the drive test's window)
DRIVE_TEST_S = 60.0
#: gyro noise (deg/sqrt(h)) above which :meth:`CoarseWindow.hold_for_drive_test` holds:
#: the tactical class's upper edge (``grade_check``), above it MEMS triads
HOLD_GYRO_NOISE_DPSH = 0.15


class CoarseWindow:
    """The samples of the coarse window, ``duration`` seconds from ``t_first``.

    ``t_end`` (set by the pipeline, :class:`~..inputs.motion.Onset`): the window also ends
    with the first sample stamped at or after it. ``t_check`` (set by the pipeline): a
    :meth:`take` also stops after the first sample stamped at or after it, so that the
    pipeline judges the window there (:func:`good_enough`) and may end it (:attr:`ended`)
    at the same sample whether the samples come one by one or in blocks.
    """

    def __init__(self, duration):
        self.duration = float(duration)
        self.parts = []
        self.T = 0.0
        self.t_end = None
        self.t_check = None
        #: the pipeline ended the window (its attitude is good enough)
        self.ended = False
        #: a short moving window's early end was refused (:meth:`refuse_short_end`)
        self.short_end_refused = False
        #: stamp of the last sample taken, None before any
        self._t_last = None

    def take(self, t, dtheta, dv, i, t_last):
        """Take samples from index ``i`` until the window is full; returns the end index."""
        j, n = i, len(t)
        need = self.duration - self.T
        t_end = min(math.inf if self.t_end is None else self.t_end,
                    math.inf if self.t_check is None else self.t_check)
        while j < n and need > 1e-9 and not (j > i and t[j - 1] >= t_end):
            need -= t[j] - (t_last if j == i else t[j - 1])
            j += 1
        if j == i:
            return j
        self.T += t[j - 1] - t_last
        self._t_last = float(t[j - 1])
        self.parts.append((t[i:j], dtheta[i:j], dv[i:j]))
        return j

    def prefill(self, t_before, t, dtheta, dv):
        """Begin the window with samples already processed (a restart's, :mod:`.sample_store`).

        ``t_before``: the stamp the first one's interval starts at; ``t`` (N,) stamps,
        ``dtheta``, ``dv`` (N, 3) increments. A restart for motion begins so: its window
        waits for the motion's onset (or its full length), never for the good-enough end
        (no check is planned).
        """
        self.parts = [(t, dtheta, dv)]
        self.T = float(t[-1] - t_before)
        self._t_last = float(t[-1])
        self.t_check = math.inf

    @property
    def full(self):
        """Tell whether the window is complete (its duration, or its early end)."""
        ended = self.t_end is not None and self._t_last is not None and self._t_last >= self.t_end
        return self.ended or ended or self.T >= self.duration - 1e-9

    def plan(self, t_first, cfg, still):
        """Set the first check (before a :meth:`take`): ``t_first + coarse_min_duration``.

        ``t_first``: where the window began; ``still``: the fine filter is a still-base one
        (or ``auto`` and GNSS has not shown the base moving); else no check.
        """
        if self.t_check is None and still and cfg['coarse_min_duration'] < self.duration:
            self.t_check = t_first + cfg['coarse_min_duration']

    def hold_for_drive_test(self, t_first, cfg, noise, gnss):
        """Keep a full window open to :data:`DRIVE_TEST_S` where ``auto`` has no GNSS at all.

        Without GNSS only the IMU can tell a drive from rest
        (:func:`~..inputs.motion.imu_translation`), and over a short window it cannot: a car
        pulling away at 1.4 m/s^2 for 10 s integrates to a straight line, as a tilt of 8
        deg does, and the still-base filter started on it published that tilt under a
        0.5-deg sigma (the car preset's 10-s window on car_consumer without its receiver:
        pitch 11 deg off at 20 sigma). Over a minute a drive's speed changes and turns
        show. Held only for a gyro that cannot find north at rest (the configured bias,
        or the noise the samples show above :data:`HOLD_GYRO_NOISE_DPSH`, the tactical
        class's edge: the vehicle IMUs): a tactical or navigation-grade gyro still ends
        its window when it is good enough, the still base of issue 46. ``t_first``: where
        the window began; ``noise`` the configured model; ``gnss`` the
        :class:`~..inputs.gnss_buffer.GnssBuffer` (no message yet; the latitude if known,
        else the equator's). ``fine_filter`` other than ``auto`` (a still-base filter
        named) declares a base at rest and keeps its window.
        """
        if not (self.full and not gnss.seen and cfg['fine_filter'] == 'auto'
                and self.t_end is None and self.T < DRIVE_TEST_S - 1e-9):
            return
        if self._finds_north(t_first, cfg, noise, gnss):
            return
        self.duration, self.ended, self.t_check = DRIVE_TEST_S, False, math.inf

    def _finds_north(self, t_first, cfg, noise, gnss):
        """Tell whether the gyro can find north (tactical grade or better).

        The configured bias sees the Earth rate and the samples' noise is at most
        :data:`HOLD_GYRO_NOISE_DPSH` (the tactical class's edge).
        ``t_first``: where the window began; ``noise`` the configured model; ``gnss`` the
        :class:`~..inputs.gnss_buffer.GnssBuffer` (the latitude, 0 where unknown).
        """
        lat = gnss.position(cfg, False)[0][0] if gnss.latitude_known(cfg) else 0.0
        seen = seen_noise(self.arrays(t_first), noise)
        return sees_earth_rate(lat, noise) and seen.gyro_arw <= HOLD_GYRO_NOISE_DPSH * DPSH

    def refuse_short_end(self, onset_t, t_first, cfg, noise, gnss):
        """Keep the whole window of a MEMS IMU moving from its start (issue 46, session 52).

        A window that GNSS shows moving ends ``coarse_motion_s`` after the motion's onset
        ``onset_t`` and not before ``coarse_min_duration`` (:meth:`~..inputs.motion.Onset.
        window_end`). Where it held less rest than that before the motion (a base moving
        from the start) and has now reached that end, the end is kept only for a gyro
        that can find north (the configured bias, and the noise the samples show at most
        :data:`HOLD_GYRO_NOISE_DPSH`: the tactical class's edge, as
        :meth:`hold_for_drive_test`); a MEMS IMU keeps ``coarse_duration``. Measured
        (bench/results/integrity_ground.md, session 52): ended at 20 s, the skid-steer
        robot's MEMS triads published rows whose heading its model does not yet cover
        (asckf, told right, seed 1004: 20 deg off under a 4.5-deg sigma at 55 s; 2
        silent-wrong runs of 10, against issue 44's 1); a tactical or navigation-grade
        ship, USV or aircraft publishes 40 s sooner. ``t_first``: where the window began;
        ``noise`` the configured model; ``gnss`` the
        :class:`~..inputs.gnss_buffer.GnssBuffer` (the latitude).
        """
        if (self.short_end_refused or self.t_end is None or onset_t is None
                or onset_t - t_first >= cfg['coarse_min_duration'] or not self.full
                or self.T >= self.duration - 1e-9):
            return
        if self._finds_north(t_first, cfg, noise, gnss):
            return
        self.short_end_refused, self.t_end = True, None

    def judge(self, t_first, cfg, noise, gnss, still):
        """End the window at a due check if its attitude is good enough (:func:`good_enough`).

        Checks fall every :data:`CHECK_EVERY_S` from the first (:meth:`plan`), only where
        ``still`` (as there) and the latitude is known (``gnss``: the
        :class:`~..inputs.gnss_buffer.GnssBuffer`; the self-check estimates an unknown one
        from the whole window). ``noise``: the configured model.
        """
        if (self.t_check is None or self._t_last is None or self._t_last < self.t_check
                or self.full):
            return
        while self.t_check <= self._t_last:
            self.t_check += CHECK_EVERY_S
        if still and gnss.latitude_known(cfg):
            lat = gnss.position(cfg, False)[0][0]
            self.ended = good_enough(self.arrays(t_first), noise, lat, self.duration)

    def arrays(self, t_first):
        """Stamps (N,), increments (N, 3), (N, 3) and intervals (N,) of the window."""
        tt = np.concatenate([c[0] for c in self.parts])
        dth = np.concatenate([c[1] for c in self.parts])
        dvv = np.concatenate([c[2] for c in self.parts])
        return tt, dth, dvv, np.diff(np.concatenate([[t_first], tt]))


#: seconds between two checks of whether a still base's window is good enough
CHECK_EVERY_S = 1.0
#: a still base's window is good enough when the rest of it would narrow no sigma by more
#: than this share (:func:`good_enough`)
GOOD_ENOUGH = 0.1


def coarse_sigma(noise, T, lat, moving, cap=30.0 * DEG, floors=True):
    """Conservative 1-sigma misalignment (3,) rad after coarse alignment over T seconds.

    Returns ``(sigma, warning or None)``: the warning says when the gyro bias is not
    small against the horizontal Earth rate (no heading on a still base). ``floors``
    False: without the 0.05 deg tilt and 0.5 deg heading floors (the cap stays).
    """
    g = earth.gravity(lat, 0.0)
    wc = earth.OMEGA_IE * np.cos(lat)
    tilt = 3.0 * np.hypot(noise.accel_bias / g, noise.accel_vrw / (g * np.sqrt(T)))
    head = 3.0 * np.hypot(noise.gyro_bias, noise.gyro_arw / np.sqrt(T)) / wc
    head += abs(np.tan(lat)) * tilt
    if moving:
        tilt, head = 2.0 * tilt, 2.0 * head
    if floors:
        tilt, head = max(tilt, 0.05 * DEG), max(head, 0.5 * DEG)
    head = min(head, cap)
    warning = None
    if not sees_earth_rate(lat, noise):
        warning = (f'gyro bias {noise.gyro_bias / DPH:.3g} deg/h is not small against the '
                   f'horizontal Earth rate {wc / DPH:.3g} deg/h: heading cannot be found on a '
                   f'still base (motion with GNSS aiding is needed)')
    return np.array([tilt, tilt, head]), warning


def good_enough(window, noise, lat, duration):
    """Tell whether a still base's coarse attitude is as good as its full window would give.

    Issue 46. ``window``: the :meth:`CoarseWindow.arrays` so far; ``noise`` the configured
    sensor model (NoiseSpec); ``lat`` rad, known; ``duration`` s the full window
    (``coarse_duration``). The attitude's sigma is :func:`coarse_sigma`'s, with the white
    noises the samples show where they are larger than the configured ones
    (:func:`seen_noise`). The window is
    good enough when waiting for the rest of it would narrow no axis's sigma by more
    than :data:`GOOD_ENOUGH` (relative): the fine filter would start from as good a point
    (it runs over these samples anyway, :mod:`.reprocess`). A navigation-grade heading and
    every tilt are at :func:`coarse_sigma`'s floors or bias terms within seconds; a
    tactical heading, limited by the gyro bias, within 30 s. A gyro that cannot see Earth
    rate (:func:`coarse_sigma`'s warning: a MEMS IMU) keeps the whole window: its heading
    comes only with motion, and a base that is going to drive then ends its window soon
    after it starts (:class:`~..inputs.motion.Onset`) instead of restarting a still-base
    filter (on seed 003's car with an untold 90-deg yaw mounting, the restart's shorter
    window hid the mounting from the sideslip check: 3.7 deg of roll under 0.7 deg).
    """
    tt, dth, dvv, dts = window
    moving = coarse.detect_motion(dth, dvv, dts, noise.gyro_arw, noise.accel_vrw)[0]
    return _close_to_full(seen_noise(window, noise), float(np.sum(dts)), duration, lat,
                          moving)


def seen_noise(window, noise):
    """Return ``noise`` (NoiseSpec) with the white noises the window's samples show.

    Each density is the larger of the configured one and the samples' third differences
    (:func:`~.noise_estimates.difference_density`, which smooth sway hardly enters), so a
    base shaken by knocks or an engine does not look confident.
    """
    tt, dth, dvv, dts = window
    dt = float(np.median(dts))
    return replace(noise,
                   gyro_arw=max(noise.gyro_arw, _density(difference_density(dth / dt, dt))),
                   accel_vrw=max(noise.accel_vrw, _density(difference_density(dvv / dt, dt))))


def _close_to_full(noise, T, duration, lat, moving):
    """Tell whether :func:`coarse_sigma` after ``T`` s is near its value after ``duration`` s.

    Near: within :data:`GOOD_ENOUGH` (relative) on every axis. Never where the gyro cannot
    see Earth rate (:func:`coarse_sigma`'s warning): no heading at rest, the window waits
    for motion.
    """
    full, warning = coarse_sigma(noise, max(duration, T), lat, moving)
    if warning is not None:
        return False
    now = coarse_sigma(noise, T, lat, moving)[0]
    return bool(np.all(now <= (1.0 + GOOD_ENOUGH) * full))


def expected_duration(noise, lat, cfg):
    """Return the still base's window length (s) :func:`good_enough` gives with the model.

    The first check (``coarse_min_duration``, then every :data:`CHECK_EVERY_S`) at which the
    configured model's sigma is close to the full window's; ``coarse_duration`` when none is
    (the forecast's, :mod:`~..forecast.expectation`: the samples may show more noise).
    """
    duration, T = cfg['coarse_duration'], cfg['coarse_min_duration']
    while T < duration:
        if _close_to_full(noise, T, duration, lat, False):
            return T
        T += CHECK_EVERY_S
    return duration


def _density(d):
    """Return the estimate ``d`` (0 where it is NaN: too few samples to tell)."""
    return 0.0 if not math.isfinite(d) else d

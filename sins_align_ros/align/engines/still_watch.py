"""Whether a still-base (zero-velocity) filter's base is still at rest, and what then.

The stationary filters (seed 002) measure zero velocity: right on a base that does not
translate, wrong the moment it drives. Without GNSS nothing else tells the pipeline
that the base moves, and the coarse window's motion test (:func:`.motion.imu_translation`)
looks at the coarse window only. This module watches the whole fine stage:

* :class:`MotionWatch`: the zero-velocity innovations. At rest their normalised squares
  (NIS) follow a chi-square law of the measured axes' degrees of freedom (smaller in
  practice: the zero-velocity sigma read from the data is 1.5 times the base's velocity
  RMS at rest, which counts the accelerometers' random walk too; on the still and moored
  bases of the benchmarks the NIS stays under 2 with two axes, and on the PSINS laser-gyro
  recording, people and wind about it, the largest of its 18 000 epochs is 14.6, mean
  0.47, against the epoch gate's 27.6; with the unread 0.01 m/s it was 1.5). A base that
  accelerates or turns at speed makes the mechanized velocity run away from zero: the
  engine's gate (:data:`P_FALSE`) refuses each such epoch (so the filter does not turn the
  acceleration into tilt), and the base is taken as moving after :data:`N_GATED` refused
  epochs in a row, or when the NIS summed over the last :data:`WINDOW_S` seconds passes
  the chi-square bound of the same false-alarm probability (a slow acceleration the filter
  partly absorbs). Tested on ship_sway, the PSINS laser-gyro recording, every still grade.
* :class:`Coast`: from then on the attitude is the gyros' (free integration from the last
  epoch before the motion, :data:`ROLLBACK_S` back, whose feedbacks are undone), with a
  covariance that grows as the data allow: per axis ``(r tau)^2 + ARW^2 tau`` over the
  coasting time ``tau``, ``r`` the gyro bias (constant and slowly varying part, as
  configured and self-checked), the Earth rate turned by the heading's uncertainty (tilt
  axes) and an unmodelled transport rate of a speed bound (see :meth:`Coast.advance`).
  An angle that grows past an unknown angle's variance is published as unknown.
* :class:`RestWindow`: the stationary filter resumes only after the IMU has shown rest
  (:func:`.motion.imu_translation` finds neither a drive nor a turn) over a whole coarse
  window (``coarse_duration``), and the velocity integrated while coasting is back near
  zero (within 3 :attr:`Coast.v_sigma`): a vehicle cruising at a constant velocity looks
  still to an IMU, but a zero-velocity filter there would turn the transport rate into a
  heading error (1.5 deg for a ship at 8 m/s at 45 deg N). Even then the base may cruise
  at up to that velocity's 3-sigma bound, so the resumed filter's attitude variances get
  what such a cruise could do (:func:`cruise_floor`). A coasting tilt beyond
  :data:`MAX_RESUME_TILT` restarts the alignment from coarse instead.

Not from a seed: seed 002 assumes a base at rest throughout.
"""
import math
from collections import deque

import numpy as np

from ...filters.chi2 import chi2_quantile
from ...nav import earth
from ..inputs.motion import imu_translation

#: probability that a still base's epoch (or window) is taken for motion
P_FALSE = 1e-6
#: refused zero-velocity epochs in a row that make the base moving
N_GATED = 3
#: seconds of zero-velocity epochs whose summed NIS is tested
WINDOW_S = 2.0
#: seconds of epochs undone when the base is found moving (before the detection's window)
ROLLBACK_S = 5.0
#: the speed bound of the transport rate: this factor on the integrated speed plus
#: :data:`SPEED_MARGIN_MPS`
SPEED_FACTOR, SPEED_MARGIN_MPS = 1.5, 1.0
#: the largest unseen cruise speed counted after a base has come to rest (m/s): ground and
#: sea vehicles (an aircraft without GNSS is out of scope)
MAX_CRUISE_MPS = 100.0
#: a coasting tilt 1-sigma beyond this (rad) is outside the linear still-base model: at
#: rest again, the alignment restarts from coarse instead of resuming
MAX_RESUME_TILT = math.radians(2.0)
#: what the phase's reason says while the base moves without GNSS
MOVING_WITHOUT_GNSS = 'moving without GNSS: needs GNSS aiding or an external heading'


def cruise_floor(speed, lat, g):
    """Variances (3,) rad^2 a zero-velocity filter gets from an unseen cruise at ``speed`` m/s.

    The Coriolis acceleration ``2 Omega sin(lat) v`` is taken for tilt (``/ g``); the
    transport rate ``v / R`` for a gyrocompass heading error (``/ (Omega cos(lat))``),
    both at the worst direction; ``speed`` at most :data:`MAX_CRUISE_MPS`.
    """
    v = min(float(speed), MAX_CRUISE_MPS)
    tilt = 2.0 * earth.OMEGA_IE * abs(math.sin(lat)) * v / g
    heading = v / earth.A / (earth.OMEGA_IE * max(math.cos(lat), 1e-3))
    return np.array([tilt, tilt, heading]) ** 2


class MotionWatch:
    """The zero-velocity innovations' test for motion; see the module docstring.

    ``dof`` the measured velocity axes, ``rate_hz`` the filter's epoch rate.
    """

    def __init__(self, dof, rate_hz):
        self.dof = int(dof)
        self.n = max(3, int(round(WINDOW_S * rate_hz)))
        #: NIS above which one epoch is refused (the engine's gate)
        self.gate = chi2_quantile(1.0 - P_FALSE, self.dof)
        #: bound of the NIS summed over a full window
        self.sum_bound = chi2_quantile(1.0 - P_FALSE, self.dof * self.n)
        self.reset()

    def reset(self):
        """Forget the epochs seen (a resumed filter)."""
        self.nis = deque(maxlen=self.n)
        self.gated_run = 0

    def epoch(self, nis, gated):
        """Take an epoch's NIS and whether it was refused; return what shows motion, or ''."""
        if not math.isfinite(nis):
            return ''
        self.nis.append(nis)
        self.gated_run = self.gated_run + 1 if gated else 0
        if self.gated_run >= N_GATED:
            return (f'{self.gated_run} zero-velocity epochs in a row refused, NIS '
                    f'{nis:.0f} > {self.gate:.0f}')
        if len(self.nis) == self.n:
            total = sum(self.nis)
            if total > self.sum_bound:
                return (f'zero-velocity NIS {total:.0f} over {WINDOW_S:g} s > '
                        f'{self.sum_bound:.0f}')
        return ''


class Coast:
    """Attitude covariance of free gyro integration; see the module docstring.

    ``P`` (3, 3) the misalignment covariance about ENU (rad^2) at the start of coasting
    (``tau0`` seconds of coasting already behind it: the rollback); ``lat`` (rad);
    ``heading_sigma`` (rad) the heading's 1-sigma (pi when the gyros cannot find north);
    ``gyro_bias`` (rad/s) the 1-sigma gyro bias; ``noise`` the
    :class:`~sins_align_ros.models.stationary.NoiseSpec` (white noises, accelerometer bias).

    It also bounds the error of the velocity the still-base mechanization integrates
    meanwhile (:attr:`v_sigma`): a base found at rest again must have that velocity back
    near zero, or it cruises at a constant velocity that an IMU cannot see.
    """

    def __init__(self, P, tau0, lat, heading_sigma, gyro_bias, noise):
        self.P = np.array(P, dtype=float)
        self.tau = 0.0
        self.b = float(gyro_bias)
        self.arw2 = float(noise.gyro_arw) ** 2
        self.accel_bias = float(noise.accel_bias)
        self.vrw2 = float(noise.accel_vrw) ** 2
        self.lat = float(lat)
        self.g = earth.gravity(self.lat, 0.0)
        w_h = earth.OMEGA_IE * math.cos(lat) * min(float(heading_sigma), math.pi)
        self._tilt_r2 = w_h ** 2
        self._v_drift = 0.0
        self._v_white2 = 0.0
        self.advance(tau0, 0.0)

    @property
    def v_sigma(self):
        """1-sigma bound (m/s) of the integrated velocity's error since coasting began."""
        return self._v_drift + math.sqrt(self._v_white2)

    def advance(self, dt, speed):
        """Grow the covariance over ``dt`` s of coasting at an integrated speed ``speed`` m/s.

        The rate error per axis is ``r`` (rad/s), a random constant over the coast: its
        angle's variance grows from ``(r tau)^2`` to ``(r (tau + dt))^2``; the white noise
        adds ``ARW^2 dt``. ``r^2`` = gyro bias^2, plus on the tilt axes the Earth rate's
        horizontal part turned by the heading's uncertainty, plus the transport rate of
        the speed bound ``1.5 speed + 1 m/s`` (the still-base mechanization has none),
        on the up axis times ``tan(lat)``. The velocity's error grows by
        ``(g tilt + accelerometer bias + 2 Omega v) dt`` (summed as if always of one sign)
        and the accelerometer's white noise.
        """
        if dt <= 0.0:
            return
        v = SPEED_FACTOR * float(speed) + SPEED_MARGIN_MPS
        rho2 = (v / earth.A) ** 2
        r2 = self.b ** 2 + rho2 + np.array([self._tilt_r2, self._tilt_r2,
                                            rho2 * math.tan(self.lat) ** 2])
        t0, t1 = self.tau, self.tau + dt
        grow = r2 * (t1 * t1 - t0 * t0) + self.arw2 * dt
        self.P[np.diag_indices(3)] += grow
        self.tau = t1
        tilt = math.sqrt(max(self.P[0, 0], self.P[1, 1], 0.0))
        self._v_drift += (self.g * min(tilt, 1.0) + self.accel_bias
                          + 2.0 * earth.OMEGA_IE * v) * dt
        self._v_white2 += self.vrw2 * dt


class RestWindow:
    """IMU samples of the last ``duration`` seconds while coasting, and whether they show rest."""

    def __init__(self, duration):
        self.duration = float(duration)
        self._blocks = deque()           # (t (n,), dtheta (n, 3), dv (n, 3), dt (n,))
        self._t_first = None
        self._t_checked = -math.inf

    def push(self, t, dtheta, dv, t_prev):
        """Add samples with stamps ``t`` (n,) whose first interval starts at ``t_prev``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if not len(t):
            return
        dt = np.diff(t, prepend=t_prev)
        self._blocks.append((t, np.atleast_2d(dtheta), np.atleast_2d(dv), dt))
        if self._t_first is None:
            self._t_first = t_prev

    def shows_rest(self, t_now):
        """Tell whether the last ``duration`` seconds show rest (checked once a second)."""
        if self._t_first is None or t_now - self._t_first < self.duration:
            return False
        if t_now - self._t_checked < 1.0:
            return False
        self._t_checked = t_now
        while self._blocks and self._blocks[0][0][-1] < t_now - self.duration:
            self._blocks.popleft()
        t, dth, dv, dt = (np.concatenate(a) for a in zip(*self._blocks))
        keep = t >= t_now - self.duration
        return imu_translation((t[keep], dth[keep], dv[keep], dt[keep])) is None


class StillWatch:
    """The watch of one still-base fine stage: motion test, coasting, rest; module docstring.

    ``engine`` the :class:`~.stationary.StationaryEngine`; ``rate_hz`` its epoch rate;
    ``rest_s`` the rest it needs to resume (``coarse_duration``, at least the drive test's
    minute: :data:`~..stages.coarse_window.DRIVE_TEST_S`); ``gyro_instability``
    (rad/s) the varying part of the gyro bias, counted with the constant one while coasting.
    """

    def __init__(self, engine, rate_hz, rest_s, gyro_instability):
        self.engine = engine
        self.motion = MotionWatch(len(engine.model.meas), rate_hz)
        self.rest_s = float(rest_s)
        self.gyro_instability = float(gyro_instability)
        #: the IMU samples while the base moves (:class:`RestWindow`), or None at rest
        self.rest = None
        #: why the base is taken as moving ('' at rest)
        self.moving = ''
        #: the stage ended because the base moved while GNSS came (a GNSS-aided filter takes
        #: over; the pipeline's restart reuses the stored rest)
        self.moved_off = False

    def push(self, t, dtheta, dv, t_prev):
        """Give the rest test the samples ``t`` (whose first interval starts at ``t_prev``)."""
        if self.rest is not None:
            self.rest.push(t, dtheta, dv, t_prev)

    def epoch(self, t, gnss_recent, heading_sigma):
        """Judge after the engine's zero-velocity epoch at ``t`` whether the base moves.

        ``gnss_recent``: GNSS fixes come in; ``heading_sigma()`` the heading's 1-sigma (rad)
        now. Returns ``(event, reason)``: ``event`` ``'coast'`` (the engine started
        coasting), ``'resume'`` (it filters again) or None; ``reason`` why the stage must
        end (moving with GNSS, or at rest with a tilt beyond the still-base model) or None.
        """
        eng = self.engine
        if self.rest is not None:
            if not self.rest.shows_rest(t):
                return None, None
            speed = eng.cruise_speed_bound()
            if speed is None:
                return None, None
            if math.sqrt(max(eng.coast.P[0, 0], eng.coast.P[1, 1])) > MAX_RESUME_TILT:
                return None, (f'the IMU shows rest again after {eng.coast.tau:.0f} s of motion '
                              'without GNSS, the tilt uncertainty beyond the still-base model')
            eng.resume(speed)
            self.rest, self.moving = None, ''
            self.motion.reset()
            return 'resume', None
        what = self.motion.epoch(eng.last_nis, eng.last_gated)
        if not what:
            return None, None
        if gnss_recent:
            self.moved_off = True
            return None, (f'the IMU shows the base moving ({what}): the zero-velocity filter '
                          f'{eng.model.name} stops so that a GNSS-aided filter takes over')
        eng.start_coast(ROLLBACK_S, math.hypot(eng.noise.gyro_bias, self.gyro_instability),
                        heading_sigma())
        self.rest = RestWindow(self.rest_s)
        self.moving = f'{MOVING_WITHOUT_GNSS} (the IMU shows the base moving: {what})'
        return 'coast', None

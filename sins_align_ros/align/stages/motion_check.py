"""The self-check in motion: the sensor model against the IMU data of the fine stage.

The sensor self-check (:mod:`.self_check`) judges the grade and the noise once, on the
coarse window. A vehicle that stood still there (a robot waiting for its mission, a car at
a traffic light) shows neither its vibration nor its turns in it: a skid-steer chassis on
asphalt adds degrees per second of sample-to-sample rate that a MEMS gyro's configured
0.4 deg/sqrt(h) does not cover, and a first turn of 90 deg puts 2 % of it (1.8 deg) into
the heading of a triad whose scale factors nobody calibrated. So while a GNSS-aided fine
stage runs, its IMU samples are taken in windows of :data:`WINDOW_S` seconds and each is
checked as the coarse self-check checks a moving base, with its estimators:

* **White noise**: the third differences of the rates and of the specific force
  (:func:`~.noise_estimates.difference_density`: motion is smooth at the sample level, so what
  is left is the sensor's noise plus vibration and quantization, an upper bound). The
  gyro's random walk is the smaller of that and the bound over seconds of every window
  so far (:class:`~.angle_walk.WalkBound`: a mount's vibration is bounded in angle). Where
  it is more than :data:`~.noise_estimates.NOISE_RATIO` times the model's (as the
  coarse self-check and earlier windows left it), the engine's misalignment process noise
  is raised by the square of the ratio; the accelerometer's, counted at most to the white
  noise of the class the gyro noise shows (:data:`~.grade_check.ACCEL_VRW_BY_GYRO_NOISE`,
  as the coarse check does: vibration above it averages out over a GNSS interval), raises
  the velocity process noise the same way.
* **Velocity jitter** (a vibrating chassis's bounded velocity error,
  :func:`~.gnss_noise_check.velocity_jitter`): where a window's is at least
  :data:`~.gnss_noise_check.JITTER_COUNTED` times the GNSS velocity sigma the filter takes
  (``engine.receiver_velocity_var``) and more than :data:`~.noise_estimates.NOISE_RATIO` times
  the jitter the engine has, the engine's ``velocity_jitter_var`` is raised to it (added to
  the GNSS velocity noise, :mod:`.epoch_noise`): a robot that waited still through the
  coarse window vibrates only once it drives.
* **Turns and the grade**: a window whose rate reaches :data:`TURN_RATE` shows turns;
  the scale factors and axis misalignment of the class the gyro noise shows
  (:data:`~.grade_check.SCALE_BY_GYRO_NOISE`: 2 % and 0.5 % for MEMS triads, none for the
  tactical and navigation classes) then replace the model's where larger
  (``engine.set_rotation_error``, :mod:`.rotation_error`), and so do the accelerometer
  triad's of the same class (:data:`~.grade_check.ACCEL_SCALE_BY_GYRO_NOISE`,
  ``engine.set_force_error``, :mod:`.force_error`: a car that stood still through the
  coarse window brakes and turns with them too). The class is that of the
  smaller of the window's noise and the model's at the start of the stage (as the coarse
  self-check left it): vibration makes a tactical gyro on a vibrating chassis look like a
  MEMS one in motion, and its scale factors are still a tactical gyro's. (The coarse
  self-check on a moving base classes by the noise it sees, vibration included.)

Never narrowed, but for the gyro's random walk: the walk bound tightens as windows add
up, and where the model's is more than :data:`NARROW_RATIO` times it (a vibrating robot:
the coarse window's 60 s, or the first motion window, left 7-13 deg/sqrt(h) where 400 s
show 4-5), it is narrowed to it, never below the configured ``gyro_arw_dpsh`` (figure
``motion_check_gyro_walk_narrowed_dpsh``). On the simulated robot with positions only
this took the published tilt 1-sigma from 44-52' to 32-38' (kf, ukf) and 31-34' to
24-26' (asckf), every told cell still honest (bench/results/integrity_robot_walk.md).
Each widening is a finding (a WARN on ``/diagnostics`` once, and the
figures ``motion_check_*``). The windows are evaluated at the GNSS epoch that follows
their last sample, so the block and the sample-by-sample paths of the fine stage widen
at the same epoch. Not in the seeds; it extends the coarse self-check (same rules) to the
fine stage.
"""
import math
from dataclasses import replace

import numpy as np

from ...units import DEG, DPSH, UG
from ..engines.base import AidedEngine, Engine
from .angle_walk import WalkBound, walk_or_noise
from .gnss_noise_check import JITTER_COUNTED, velocity_jitter
from .grade_check import (ACCEL_SCALE_BY_GYRO_NOISE, ACCEL_VRW_BY_GYRO_NOISE,
                          SCALE_BY_GYRO_NOISE)
from .noise_estimates import NOISE_RATIO, difference_density

#: per triad: the class table of its scale factor and misalignment (ppm), the engine's
#: setter, and what a 1 % error does (the finding's example)
TRIADS = (('gyro', SCALE_BY_GYRO_NOISE, 'set_rotation_error',
           'a 90 deg turn: {:.2g} deg of heading', 90.0),
          ('accel', ACCEL_SCALE_BY_GYRO_NOISE, 'set_force_error',
           'a 3 m/s^2 braking: {:.2g} m/s^2 of force error', 3.0))

#: seconds of IMU samples judged at a time
WINDOW_S = 20.0
#: the model's random walk is narrowed to the walk bound where it is this many times larger
#: (and was widened above the configured figure); widening takes :data:`NOISE_RATIO`
NARROW_RATIO = 1.25
#: a rate (norm, rad/s) at least this in a window shows turns
TURN_RATE = 10.0 * DEG


def class_value(table, gyro_noise_dpsh):
    """Value of a self-check class ``table`` ((upper edge, value), ...) for a gyro noise."""
    return next(v for edge, v in table if gyro_noise_dpsh <= edge)


class MotionCheck:
    """The sensor model against the fine stage's IMU windows (module docstring).

    ``noise``: the model the engine was built with (:class:`NoiseSpec`, SI, as the coarse
    self-check widened it); ``scale``, ``misalignment`` (and ``accel_scale``,
    ``accel_misalignment``): the gyro (accelerometer) scale-factor and misalignment
    1-sigma the engine models (-).
    """

    def __init__(self, noise, scale=0.0, misalignment=0.0, window_s=WINDOW_S,
                 accel_scale=0.0, accel_misalignment=0.0, configured_arw=None):
        self.noise = noise
        #: the gyro random walk as configured (rad/sqrt(s)): never narrowed below it
        self.configured_arw = noise.gyro_arw if configured_arw is None else configured_arw
        #: the random-walk bound over all the windows so far (:mod:`.angle_walk`)
        self.walk = WalkBound()
        #: the gyro noise the grade is judged by at most (the model's at the start), rad/sqrt(s)
        self.class_arw = noise.gyro_arw
        #: triad -> (scale factor, misalignment) 1-sigma the engine models (-)
        self.scales = {'gyro': (float(scale), float(misalignment)),
                       'accel': (float(accel_scale), float(accel_misalignment))}
        self.window_s = float(window_s)
        self._t, self._w, self._f, self._dt = [], [], [], []
        #: start of the first interval kept (s), None with nothing kept
        self._t0 = None
        #: parameter name -> value (datasheet units) widened in motion
        self.widened = {}
        #: findings not yet reported (:meth:`take_findings`), and all of them
        self.new_findings = []
        self.findings = []
        self.figures = {}
        self.n_windows = 0

    def push(self, t, dtheta, dv, dt):
        """Keep samples: stamps ``t`` (N,), increments ``dtheta``, ``dv`` (N, 3), intervals ``dt``.

        They are judged at the GNSS epochs that follow them (:meth:`epoch`).
        """
        dt = np.asarray(dt, dtype=float).reshape(-1)
        if not len(dt):
            return
        d = np.maximum(dt, 1e-6)[:, None]
        t = np.asarray(t, dtype=float).reshape(-1)
        if self._t0 is None:
            self._t0 = float(t[0] - dt[0])
        self._t.append(t)
        self._w.append(np.asarray(dtheta, dtype=float).reshape(-1, 3) / d)
        self._f.append(np.asarray(dv, dtype=float).reshape(-1, 3) / d)
        self._dt.append(dt)

    def epoch(self, t_now, engine: AidedEngine):
        """At a GNSS epoch at ``t_now``: judge the samples up to it if they fill a window.

        Widens ``engine`` where the data show more than the model; returns True if it did.
        """
        # (stamps rise: the samples up to t_now span at most t_now - t0, so the arrays are
        # joined once a window, however far ahead of the epochs a block was pushed)
        if self._t0 is None or t_now - self._t0 < self.window_s:
            return False
        t = np.concatenate(self._t)
        n = int(np.searchsorted(t, t_now, side='right'))
        dt = np.concatenate(self._dt)
        if float(np.sum(dt[:n])) < self.window_s:
            return False
        w, f = np.concatenate(self._w), np.concatenate(self._f)
        self._t, self._w, self._f, self._dt = [t[n:]], [w[n:]], [f[n:]], [dt[n:]]
        self._t0 = float(t[n - 1]) if n < len(t) else None
        d = dt[:n, None]
        jitter = self._jitter(w[:n] * d, f[:n] * d, dt[:n], engine)
        return self._judge(w[:n], f[:n], float(np.mean(dt[:n])), engine) or jitter

    def _jitter(self, dth, dv, dt, engine: AidedEngine):
        """Raise ``engine``'s velocity jitter to one window's where it counts; True if so.

        ``dth``, ``dv`` (N, 3) the window's increments, ``dt`` (N,) its intervals (module
        docstring).
        """
        j = velocity_jitter(dth, dv, dt)
        var_v = engine.receiver_velocity_var()
        if var_v is None or not math.isfinite(j):
            return False
        self.figures['motion_check_velocity_jitter_mps'] = j
        old = math.sqrt(engine.velocity_jitter_var)
        if not (j >= JITTER_COUNTED * math.sqrt(var_v) and j > NOISE_RATIO * old):
            return False
        engine.velocity_jitter_var = j * j
        self._found('imu_velocity_jitter_mps', j,
                    f'IMU velocity jitter {j:.3g} m/s in motion (vibration, bounded), '
                    f'{old:.3g} in the model, GNSS velocity noise {math.sqrt(var_v):.3g} m/s: '
                    'imu_velocity_jitter_mps widened in the running filter')
        return True

    def _judge(self, w, f, dt, engine: AidedEngine):
        """Widen ``engine`` from one window's rates ``w`` and specific forces ``f`` (N, 3)."""
        arw = difference_density(w, dt)
        if not math.isfinite(arw):
            return False
        # the model's random walk follows the walk bound over every window so far
        # (vibration is bounded in angle); the grade is judged by the sample-level noise
        q = walk_or_noise(self.walk.add(w * dt, dt).bound(dt), arw)
        self.n_windows += 1
        vrw = min(difference_density(f, dt),
                  class_value(ACCEL_VRW_BY_GYRO_NOISE, arw / DPSH) * UG)
        rate = float(np.max(np.linalg.norm(w, axis=1)))
        self.figures.update(motion_check_gyro_noise_dpsh=arw / DPSH,
                            motion_check_gyro_walk_dpsh=q / DPSH,
                            motion_check_accel_noise_ug_rthz=vrw / UG,
                            motion_check_max_rate_dps=rate / DEG,
                            motion_check_windows=self.n_windows)
        did = False
        for name, field, rows, est, unit, label, what in (
                ('gyro_arw_dpsh', 'gyro_arw', engine.i_phi, q, DPSH, 'deg/sqrt(h)',
                 'gyro random walk {:.3g} {} in motion, {:.3g} in the model'),
                ('accel_vrw_ug_rthz', 'accel_vrw', engine.i_v, vrw, UG, 'ug/sqrt(Hz)',
                 "accelerometer white noise {:.3g} {} in motion (counted up to its class's), "
                 '{:.3g} in the model')):
            model = getattr(self.noise, field)
            if field == 'gyro_arw' and est * NARROW_RATIO < model > self.configured_arw:
                did = self._narrow_walk(engine, max(est, self.configured_arw), model) or did
            elif est > NOISE_RATIO * model:
                engine.widen_process_noise(rows, (est / model) ** 2, est ** 2)
                self._found(name, est / unit, what.format(est / unit, label, model / unit)
                            + f': {name} widened in the running filter')
                self.noise = replace(self.noise, **{field: est})
                did = True
        if rate >= TURN_RATE:
            grade = min(arw, self.class_arw) / DPSH
            for triad, table, setter, example, unit in TRIADS:
                did = self._raise_scales(engine, triad, class_value(table, grade), setter,
                                         f'turns at up to {rate / DEG:.0f} deg/s with a gyro '
                                         f'of the MEMS class ({grade:.3g} deg/sqrt(h))',
                                         example, unit) or did
        return did

    def _narrow_walk(self, engine: AidedEngine, q, model):
        """Narrow the engine's random walk from ``model`` to ``q`` (rad/sqrt(s)); True."""
        engine.widen_process_noise(engine.i_phi, (q / model) ** 2, q * q)
        self.noise = replace(self.noise, gyro_arw=q)
        self.widened['gyro_arw_dpsh'] = q / DPSH
        self.figures['motion_check_gyro_walk_narrowed_dpsh'] = q / DPSH
        return True

    def _raise_scales(self, engine: AidedEngine, triad, ppm, setter, why, example, unit):
        """Take the class's ``ppm`` (scale, misalignment) of ``triad`` where larger; True if so."""
        old = self.scales[triad]
        new = tuple(max(v * 1e-6, o) for v, o in zip(ppm, old))
        if new == old:
            return False
        self.scales[triad] = new
        getattr(engine, setter)(*new)
        self._found(f'{triad}_scale_factor_ppm', new[0] * 1e6,
                    f'{why}: {triad}_scale_factor_ppm {new[0] * 1e6:.3g} and '
                    f'{triad}_misalignment_ppm {new[1] * 1e6:.3g} taken in the running filter '
                    f'({example.format(new[0] * unit)})')
        self.widened[f'{triad}_misalignment_ppm'] = new[1] * 1e6
        return True

    def _found(self, name, value, text):
        self.widened[name] = value
        self.findings.append(text)
        self.new_findings.append(text)

    def take_findings(self):
        """Return the findings not reported yet (and forget them)."""
        out, self.new_findings = self.new_findings, []
        return out

    def status(self):
        """Figures for diagnostics."""
        s = dict(self.figures)
        if self.widened:
            s['motion_check_widened'] = ' '.join(f'{k}={v:.4g}'
                                                 for k, v in self.widened.items())
        return s


def for_stage(engine: Engine, cfg, noise):
    """Return the motion check of a fine stage running ``engine`` (None: still base, no check)."""
    if engine.restages or not cfg['sensor_self_check'] or noise is None:
        return None
    configured = cfg.get('configured', {}).get('gyro_arw_dpsh', cfg['gyro_arw_dpsh'])
    return MotionCheck(noise, cfg['gyro_scale_factor_ppm'] * 1e-6,
                       cfg['gyro_misalignment_ppm'] * 1e-6,
                       accel_scale=cfg['accel_scale_factor_ppm'] * 1e-6,
                       accel_misalignment=cfg['accel_misalignment_ppm'] * 1e-6,
                       configured_arw=configured * DPSH)

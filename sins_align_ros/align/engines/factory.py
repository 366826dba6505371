"""Fine-alignment engines from parameter values: each family's constructor arguments.

The engine class of a ``fine_filter`` is its row's (:mod:`.registry`: the filter table
says the family, the class names the row); this module turns the parameter values into
the family's constructor arguments, adds the class's own (``options(cfg)``) and the parts
every aided engine shares (gates, model errors, the GNSS Gauss-Markov error).

Every engine offers ``mech`` (the strapdown state), ``P``, ``attitude_cov()``,
``widen(var_phi, var_v)``, ``status()`` and the flags ``navigates`` and
``restages``; the stationary engine (:mod:`.stationary`) steps itself between its
filter epochs, the GNSS-aided ones (:mod:`.aided`: seed 000 :mod:`.moving`, seed 004
:mod:`.robust`, seeds 001/003 :mod:`.navigation`) take GNSS epochs through ``update``.
"""
import math

import numpy as np

from .. import params as prm
from ..filter_table import FILTERS, MOVING, NAVIGATION, ROBUST, STILL
from ..inputs.gnss_fix import uses_reported_covariance
from .gnss_gate import GnssGate
from .moving import model_noise as moving_model_noise
from .navigation import gyro_tau, model_noise as nav_model_noise
from .registry import engine_class
from .robust import model_noise as robust_model_noise
from ...models.stationary import NoiseSpec, StationaryModel
from ...nav import earth
from ...units import DPH, DPSH, UG


def noise_spec(cfg):
    """Return the sensor model of parameter values ``cfg`` in SI units (:class:`NoiseSpec`)."""
    return NoiseSpec(gyro_bias=math.hypot(cfg['gyro_bias_dph'],
                                          cfg['gyro_bias_instability_dph']) * DPH,
                     gyro_arw=cfg['gyro_arw_dpsh'] * DPSH,
                     accel_bias=cfg['accel_bias_ug'] * UG,
                     accel_vrw=cfg['accel_vrw_ug_rthz'] * UG)


def zero_velocity_sigmas(cfg):
    """East, north, up zero-velocity sigmas (3,) m/s of the stationary filter.

    A sigma left to the data (0) that the self-check did not read (no self-check, or a base
    not at rest in the coarse window) is ``params.ZERO_VELOCITY_UNREAD``.
    """
    zv = cfg['zero_velocity_sigma'] or prm.ZERO_VELOCITY_UNREAD
    return np.array([zv, zv, cfg['zero_velocity_sigma_up'] or zv])


def is_aided(fine_filter):
    """Tell whether ``fine_filter`` is a GNSS-aided (moving-base) filter."""
    return fine_filter in prm.MOVING_FILTERS


def make_engine(cfg, noise, start, has_velocity, heading_known=True):
    """Build the engine of ``cfg['fine_filter']`` from a coarse result ``start``.

    ``start`` is a :class:`~.coarse_stage.CoarseResult`; ``has_velocity``: GNSS velocity
    messages have arrived; ``heading_known`` False (an aided filter at rest with a gyro
    that cannot find north): the level accelerometer bias is not estimated
    (:meth:`~.prior_shaping.PriorShaping.hold_level_accel_bias`). Returns ``(engine, floor (3,),
    warnings)``: ``floor`` the variances (rad^2) the model cannot see, added to its
    attitude covariance at output.
    """
    ff = cfg['fine_filter']
    cls = engine_class(ff)
    family = FILTERS[ff].family
    if family == STILL:
        eng = cls(StationaryModel(ff), noise, start.C_b_n, start.sigma, start.position,
                  zero_velocity_sigmas(cfg), 1.0 / cfg['fine_update_hz'], start.sigma_linear)
        eng.heading_gate = _heading_gate(cfg)
        return eng, eng.floor, []
    # drift states: a random constant, plus a random walk that lets them follow a
    # Gauss-Markov bias of the given sigma and correlation time (2 sigma^2 / tau)
    q_drift = 2.0 * (cfg['gyro_bias_instability_dph'] * DPH) ** 2 / cfg['gyro_bias_tau_s']
    gate = dict(gate_probability=(None if cfg['gnss_gate_probability'] >= 1.0
                                  else cfg['gnss_gate_probability']),
                gate_max_rejects=cfg['gnss_gate_max_rejects'])
    warnings = []
    eng = _AIDED[family](cls, cfg, noise, start, has_velocity, q_drift, gate, warnings)
    lat, h = start.position[0], start.position[2]
    eng.heading_gate = _heading_gate(cfg)
    eng.set_rotation_error(cfg['gyro_scale_factor_ppm'] * 1e-6,
                           cfg['gyro_misalignment_ppm'] * 1e-6)
    eng.set_gnss_markov(cfg['gnss_position_markov_sigma_m'], cfg['gnss_position_markov_tau_s'])
    if (not has_velocity and cfg['gnss_position_only_markov']
            and cfg['gnss_position_markov_sigma_m'] <= 0.0 and eng.measures_position):
        eng.gnss_markov.from_fixes = True
        twice = 'twice ' if eng.gnss_markov.method == 'state' else ''
        warnings.append(
            f'position-only GNSS: {twice}each fix\'s horizontal position sigma is taken as a '
            'Gauss-Markov error of %.0f s as well (a standalone receiver\'s error is mostly '
            'correlated over tens of seconds, and the heading comes from position '
            'differences; gnss_position_only_markov)' % cfg['gnss_position_markov_tau_s'])
    eng.velocity_jitter_var = cfg['imu_velocity_jitter_mps'] ** 2
    eng.still_rate = eng.still_rate and bool(cfg['zero_rate_at_rest'])
    eng.set_force_error(cfg['accel_scale_factor_ppm'] * 1e-6,
                        cfg['accel_misalignment_ppm'] * 1e-6)
    if not heading_known:
        eng.hold_level_accel_bias()
    # a model without accelerometer bias leaves a tilt of bias / g, added at the output
    # (and every aided model the tilt of the yaw rate's leak into the horizontal gyros,
    # which no turn tells from an accelerometer bias: the engine's tilt_floor, FineStage)
    tilt = 0.0 if eng.has_accel_bias else (noise.accel_bias / earth.gravity(lat, h)) ** 2
    return eng, np.array([tilt, tilt, 0.0]), warnings


def _heading_gate(cfg):
    """Return the external heading's innovation gate (the GNSS gate's probability, patience)."""
    p = cfg['gnss_gate_probability']
    return GnssGate(None if p >= 1.0 else p, cfg['gnss_gate_max_rejects'], (1,), name='heading')


def _moving(cls, cfg, noise, start, has_velocity, q_drift, gate, warnings):
    """Seed 000's engine (:mod:`.moving`): 10 states + the accelerometer bias."""
    s_p = cfg['gnss_pos_sigma_m']
    # seed 000's 10 states + the accelerometer bias (a random constant: no parameter
    # gives an accelerometer bias instability)
    P0, Qc = moving_model_noise(start.sigma, start.sigma_v, s_p, noise, q_drift)
    use_vel = bool(cfg['use_gnss_velocity'] and has_velocity)
    R = [s_p ** 2] * 2 + ([cfg['gnss_vel_sigma_mps'] ** 2] * 2 if use_vel else [])
    return cls(start.C_b_n, start.v_n, *start.position, P0, Qc, np.diag(R),
               use_velocity=use_vel, adapt_q=cfg['asckf_adapt_q'], b=cfg['asckf_forgetting'],
               use_reported_cov=cfg['use_reported_gnss_covariance'],
               hold_lost_heading=cfg['course_heading'], **gate, **cls.options(cfg))


def _robust(cls, cfg, noise, start, has_velocity, q_drift, gate, warnings):
    """Seed 004's engine (:mod:`.robust`): 12 states, the GNSS velocity measured."""
    P0, Qc = robust_model_noise(start.sigma, start.sigma_v, noise, q_drift)
    R = np.eye(3) * cfg['gnss_vel_sigma_mps'] ** 2
    if not has_velocity:
        warnings.append(f'{cfg["fine_filter"]} measures the GNSS velocity: no velocity has '
                        'arrived yet (fixes reset the position only)')
    return cls(start.C_b_n, start.v_n, *start.position, P0, Qc, R, rho=cfg['vb_forgetting'],
               n_iter=cfg['vb_iterations'], C=cfg['vbch_c'], dof=cfg['vb_outlier_dof'] or None,
               **gate, **cls.options(cfg))


def _navigation(cls, cfg, noise, start, has_velocity, q_drift, gate, warnings):
    """Seed 001's 15-state or seed 003's 18-state engine (:mod:`.navigation`)."""
    n = cls.n_states
    # a coarse heading beyond the model's range is lost until found again (heading_range.py)
    lost = bool(start.sigma[2] > cls.heading_sigma_max)
    sigma = cls.prior_sigma(start.sigma)
    gyro = (cfg['gyro_bias_dph'] * DPH, cfg['gyro_bias_instability_dph'] * DPH)
    accel = (cfg['accel_bias_ug'] * UG, 0.0)
    tau_g = gyro_tau(n, gyro, cfg['gyro_bias_tau_s'])
    P0, Qc = nav_model_noise(n, sigma, start.sigma_v, max(cfg['gnss_pos_sigma_m'],
                                                          cfg['gnss_height_sigma_m']),
                             gyro, accel, noise.gyro_arw, noise.accel_vrw,
                             tau_g, cfg['accel_bias_tau_s'], q_scale=cfg['nav_q_scale'])
    R = np.diag([cfg['gnss_pos_sigma_m'] ** 2] * 2 + [cfg['gnss_height_sigma_m'] ** 2]
                + [cfg['gnss_vel_sigma_mps'] ** 2] * 3)
    return cls(
        start.C_b_n, start.v_n, *start.position, P0, Qc, R, tau_g=tau_g,
        tau_a=cfg['accel_bias_tau_s'], use_velocity=cfg['use_gnss_velocity'],
        use_reported_cov=uses_reported_covariance(cfg),
        track_heading_sigma_deg=cfg['track_heading_sigma_deg'],
        track_min_speed_mps=cfg['track_min_speed_mps'], heading_lost=lost, **gate,
        **cls.options(cfg))


#: family -> the builder of its engines' constructor arguments
_AIDED = {MOVING: _moving, ROBUST: _robust, NAVIGATION: _navigation}

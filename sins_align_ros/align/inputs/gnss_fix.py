"""One GNSS epoch as the engines take it, and the noise they take it with.

A record (:class:`GnssFix`) and three rules on the parameters (which filters take R from
the receiver's reported covariance, :func:`uses_reported_covariance`, the resulting
1-sigma, :func:`gnss_sigma`, and one epoch's variance, :func:`epoch_var`), shared by the
inputs (the GNSS buffer), the self-check, the course aids and the engines; it imports no
engine, so the inputs need none.
"""
import math
from dataclasses import dataclass

import numpy as np

from ..filter_table import FILTERS


@dataclass
class GnssFix:
    """One GNSS epoch: position (rad, rad, m), optional ENU velocity (3,) and variances.

    ``pos_var`` (2,): east and north position variance (m^2) the receiver reports,
    or None; ``vel_var`` (2,): east and north velocity variance ((m/s)^2) or None;
    ``arm_var`` (6,): variance per ENU axis, position then velocity, that moving the
    epoch from the antenna to the IMU may have left (:mod:`.installation`), or None.
    """

    t: float
    lat: float
    lon: float
    h: float
    v_n: np.ndarray = None
    pos_var: np.ndarray = None
    vel_var: np.ndarray = None
    arm_var: np.ndarray = None


def uses_reported_covariance(cfg):
    """Tell whether the engine of ``cfg['fine_filter']`` takes R from the GNSS messages.

    The filters whose row in the filter table says ``reported_covariance`` (seed 000's
    family and the 15/18-state ``kf`` and ``ukf``), when ``use_reported_gnss_covariance``
    is on; ``asckf`` only without adaptation (its Sage-Husa estimator sets R otherwise).
    """
    ff = cfg['fine_filter']
    row = FILTERS.get(ff)
    return bool(cfg['use_reported_gnss_covariance']) and row is not None \
        and row.reported_covariance and not (ff == 'asckf' and cfg['asckf_adaptive'])


def gnss_sigma(cfg, name, reported):
    """1-sigma of GNSS ``name`` (``gnss_pos_sigma_m``, ``gnss_vel_sigma_mps``) the engine uses.

    ``reported``: east/north variances (2,) the messages reported (empty if none). Their
    median when the engine takes R from the messages (:func:`uses_reported_covariance`),
    else the parameter. The coarse stage and the motion judgement weigh GNSS velocity
    with it, and the self-check compares the data with it.
    """
    if uses_reported_covariance(cfg) and len(reported):
        return math.sqrt(float(np.median([np.mean(v) for v in reported])))
    return cfg[name]


def epoch_var(configured_var, reported, use_reported):
    """Return the east/north variance the engine gives one epoch (m^2 or (m/s)^2).

    The mean of the receiver's ``reported`` (2,) variances when the engine takes them
    (``use_reported``: :func:`uses_reported_covariance`) and the message had them, else
    ``configured_var`` (the parameter, as the self-check left it). The aids that judge a
    leg's course (:mod:`~..stages.slow_monitor`, :mod:`~..stages.course_heading`) weigh
    the fixes with it, as the engine does: a datasheet figure in ``gnss_pos_sigma_m``
    beside a receiver that reports its covariance changes neither.
    """
    if use_reported and reported is not None:
        return float(np.mean(reported))
    return float(configured_var)

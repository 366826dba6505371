"""The gyro scale-factor and misalignment errors as model-error noise of the aided filters.

A gyro triad measures ``(I + S + M) w`` (issue 44): scale factors ``S`` (diagonal) and
axis misalignment ``M`` (off-diagonal) turn every rotation into an attitude error
proportional to it. No filter state models them; instead, over each filter interval the
misalignment covariance grows by what they can do to the rotation turned since (a
random constant ``s`` per scale factor and ``m`` per off-diagonal entry):

    error_j = s_j A_j + sum_{i != j} m_ji A_i,
    var_j(A) = s^2 A_j^2 + m^2 (|A|^2 - A_j^2)

in body axes, ``A`` the signed body rotation (rad) summed over the last
:data:`ROTATION_MEMORY_S` seconds (exponential forgetting: the GNSS aiding observes the
error a turn left within such a time, and a vehicle circling for minutes must not build
up a variance without bound). One term is bounded instead (:func:`coherent_variance`'s
``yaw_leak_bounded``): the horizontal gyros' share ``m`` of the yaw rate tilts the
attitude by ``(C(psi) - C(psi0)) [z x] m`` over a heading change (the tilt no turn can
find, below), of size ``2 |sin((psi - psi0) / 2)| m``, never more than ``2 m`` however
far the vehicle turns; ``m^2 A_z^2`` said ``m |A_z|``, 1.6 times that for a half turn,
and 6.3 m for a whole one, whose tilt is back to zero. So the tilt rows take ``4 m^2
sin^2(A_z / 2)`` for it. Measured (bench/integrity.py robot:posonly, kf, 10 seeds per
cell, plain MEMS and raw AHRS triads told right or the defaults): a skid-steer robot
turning 100-180 deg every 10-20 s had its tilt sigma at the end at 80-97' (a variance
that two same-way turns within the memory put at 2.6 deg), with the tilt error 11-23'
RMS; bounded, 44-52', no run silent-wrong; car:consumer (single 60-100 deg junction
turns) moved by at most 0.2' in tilt RMS and sigma. Each interval adds ``var(A + dA) -
var(A)`` (never less than zero), turned into the navigation frame with the attitude, to
the misalignment's process noise: a 90 deg turn adds the whole ``(s * 90 deg)^2`` of a
constant scale factor, not the ``1/N`` of it that white noise over its N intervals
would; the sigmas are taken :data:`COHERENCE_FACTOR` (2) times the told ones, since the
filter still reads part of the coherent error as information (the heading's once,
:data:`HEADING_COHERENCE_FACTOR`).

Not in the seeds (their IMUs are calibrated): an uncalibrated MEMS AHRS's triads have
scale factors of 1-3 % and axis misalignment of 0.5 %, so a 90-deg junction turn leaves
up to 1.8 deg of heading and 0.45 deg of tilt (the z gyro's rate leaking into x and y).

**The tilt no turn can find** (:func:`unseparable_tilt_var`). A GNSS-aided filter tells a
horizontal accelerometer bias ``b`` (body axes) from a tilt by the turns: the bias turns
with the vehicle, a tilt does not. The horizontal gyros' share ``m = (M[x, z], M[y, z])``
of the yaw rate defeats that. Over a heading change from ``psi0`` to ``psi`` about the
vertical it tilts the attitude by (``C(psi)`` the rotation about up, ``[z x]`` the cross
product with up, which commutes with it and squares to ``-1`` on horizontal vectors;
``phi_dot = -C w_err``, ``d C / d psi = [z x] C``)

    phi_n(psi) = -integral C(psi') m dpsi' = (C(psi) - C(psi0)) [z x] m,

for every turn, of every size. The specific-force error that the GNSS velocity shows,
``g [z x] phi_n + C(psi) b``, is then ``C(psi) (b - g m)`` plus a constant: to first order the
force error of an accelerometer bias ``b - g m`` and no gyro misalignment. A filter that
finds that bias leaves the tilt ``C(psi) [z x] m``: ``m`` on each horizontal body axis,
fixed to the vehicle, which its covariance cannot see. The white per-turn noise above
does not cover it: the same ``m`` acts at every turn. Measured (car_consumer, raw MEMS
AHRS triads, kf told the sensors, self-check off): body-frame tilt error (roll, pitch)
from 300 s to the end (19.6', 15.2') for seed 1009 against ``|[z x] m|`` = (20.8', 19.5'),
(24.1', 15.9') for seed 1008 against (26.9', 8.5'); the simulator's ``M[x, z]``,
``M[y, z]`` alone zeroed: (6.4', 6.9') and (6.7', 11.9'); the other errors zeroed instead
(accelerometer bias, scale factors and misalignment, the other gyro entries, gyro bias):
moved by at most 7' (seed 1009). North tilt 29-31' at the end under a 10' sigma. Not every
run shows all of it: the same column alone in an IMU of biases and white noise only (seed
1009's ``m``, the kf told 10 deg/h instability, 5000 ppm accelerometer scale factor and
misalignment) left (6', 11') of the (21', 20'), and (3', 5') told no accelerometer model;
why the filter finds less of ``b - g m`` there is not known. Its variance ``m^2``, the whole
of it, on the safe side, is added to each published tilt's (:meth:`RotationError.tilt_floor`,
which ``FineStage.floor`` adds at output, for every GNSS-aided filter).

The same from the body side: the attitude error obeys ``dphi_n/dt = -C_b_n (S + M) w_b``;
a tilt fixed in the body, ``phi_n = C_b_n phi_b``, changes as ``C_b_n (w_b x phi_b)``, so
for ``w_b = (0, 0, r)`` it solves the equation with ``phi_b = (-m_yz, m_xz, 0)`` whatever
the turns, and its velocity error ``g x phi_b`` is an accelerometer bias fixed in the
body, which seed 000's bias state takes as well. Measured (car:rtk, raw MEMS AHRS triads,
ASCKF with node defaults, seeds 1000-1005): the final east and north error was ``C_b_n
phi_b`` of the drawn ``M`` to within 0.1-3.2 arcmin, up to 34 arcmin under a 3.6 arcmin
sigma before the floor (7-8 of 10 runs silent wrong).
"""
import math

import numpy as np

#: seconds over which the rotation that the errors act on is remembered
ROTATION_MEMORY_S = 30.0
#: the model's 1-sigma per told 1-sigma. The error is one constant for the whole run, the
#: process noise white: the filter reads part of the coherent error as a state it can
#: observe (a turn's tilt, a braking's velocity ramp) and then claims to know it. Measured
#: (car_consumer, seeds 1003/1004, raw MEMS AHRS triads, kf/ukf told right or node
#: defaults): at 1x, 13 % and 0.2-8 % of the 1-s rows outside 3 sigma in north tilt; at
#: 2x none, tilt sigma 0.12 -> 0.15-0.19 deg, heading sigma 0.5 -> 0.63-0.69 deg. Shared
#: with the accelerometer's model (:mod:`.force_error`)
COHERENCE_FACTOR = 2.0
#: the same for the heading (the noise's up row and column, scaled from the factor above):
#: the told sigma. The factor 2 was measured on the north tilt; the heading a turn leaves is
#: measured afresh, absolutely, by the GNSS velocity in the next turns or by a straight leg's
#: course (:mod:`.course_heading`), and its own sigma covers it. At 2x a turning robot's
#: heading sigma grew by 2-4 deg a turn up to the claim limit while its error did not move
#: (robot_skid, positions only, raw AHRS triads, kf/ukf, 10 seeds: the heading declared
#: unknown at the end in 10 of 10 runs of every cell, 3-6 deg RMS); at 1x, with the moving
#: base's bias instability counted from the sensor and not the chassis's vibration
#: (:data:`~.grade_check.GYRO_NOISE_FOR_INSTABILITY_MOVING`), it is published at the end
#: (10 seeds per cell: mean heading sigma 8.3-9.1 deg, none silent). With Doppler velocity
#: (robot:consumer) the heading
#: sigma at the end went from 6.5 / 9.0 deg (kf / ukf) to 5.3 / 6.3, no run silent-wrong;
#: the cars (car:consumer, car:rtk, car_still:rtk, raw AHRS triads, kf/ukf, 3 seeds) moved
#: by at most 0.1 arcmin
HEADING_COHERENCE_FACTOR = 1.0


def coherent_variance(A, scale, misalignment, yaw_leak_bounded=False):
    """Variance (3,) per body axis of the error ``(S + M) A`` of a body vector ``A`` (3,).

    ``scale``, ``misalignment``: the 1-sigma of each diagonal and off-diagonal entry of a
    triad's scale-factor and misalignment matrix (a rotation for the gyro, a velocity gain
    for the accelerometer: :mod:`.force_error`). ``yaw_leak_bounded`` (a gyro triad's
    rotation): the x and y rows take the yaw rotation's share as the tilt it leaves,
    ``4 m^2 sin^2(A_z / 2)``, instead of ``m^2 A_z^2`` (module docstring).
    """
    A = np.asarray(A, dtype=float)
    a2 = A * A
    var = scale * scale * a2 + misalignment * misalignment * (a2.sum() - a2)
    if yaw_leak_bounded:
        var[:2] += misalignment * misalignment * (4.0 * math.sin(0.5 * A[2]) ** 2 - a2[2])
    return var


def coherent_increment(A, dA, T, memory_s, scale, misalignment, yaw_leak_bounded=False):
    """Add ``dA`` (3,) to the remembered body vector ``A`` (3,) faded over ``T`` s.

    Returns ``(B, inc)``: the new remembered vector and the variance per body axis it adds,
    ``var(B) - var(A)`` (never below zero: turning back adds nothing). ``yaw_leak_bounded``
    as :func:`coherent_variance`'s.
    """
    A = np.asarray(A, dtype=float) * math.exp(-T / memory_s)
    B = A + dA
    inc = np.maximum(coherent_variance(B, scale, misalignment, yaw_leak_bounded)
                     - coherent_variance(A, scale, misalignment, yaw_leak_bounded), 0.0)
    return B, inc


def unseparable_tilt_var(misalignment):
    """Tilt variance (rad^2, each horizontal axis) no turn separates from an accelerometer bias.

    ``misalignment``: the gyro misalignment 1-sigma (rad/rad) of each off-diagonal entry; the
    error ``C(psi) [z x] m`` of the module docstring has variance ``m^2`` on each horizontal
    axis (body, and so ENU, whatever the heading). Taken once, not
    :data:`COHERENCE_FACTOR` times: it is the error itself, not a white stand-in for it.
    """
    return float(misalignment) ** 2


def state_noise(n, rows, C, inc):
    """Process noise (n, n): the body-axis variances ``inc`` turned by ``C`` into ``rows``."""
    k = np.arange(n)[rows]
    E = np.zeros((n, n))
    E[np.ix_(k, k)] = ((C * inc) @ C.T)[:len(k), :len(k)]
    return E


class RotationError:
    """Mixin of :class:`~.aided.GnssAidedEngine`: the rotation-proportional process noise.

    The engine calls :meth:`_add_rotation` with the increments it mechanizes and takes
    :meth:`_rotation_noise` into its process noise at every prediction. An engine that
    can carry the scale factors as states (:mod:`.gyro_scale`) takes them there through
    :meth:`_take_scale_states`; the noise then keeps the misalignment part alone.
    """

    #: (scale factor, misalignment) 1-sigma of the noise, rad/rad; None: no noise
    _rot_sigma = None
    #: body rotation (3,) summed over the current interval, rad; None: not counted
    _rot = None
    #: the told (self-checked) misalignment 1-sigma, rad/rad (:meth:`tilt_floor`)
    _rot_misalignment = 0.0
    #: rotation about the local vertical since :meth:`take_turn`, rad
    _turn = 0.0
    #: the z gyro's scale-factor 1-sigma measured from turns (:mod:`..stages.turn_scale`),
    #: which the noise takes about the body's z axis instead of the told one; None: told
    _turn_scale_sigma = None

    def set_rotation_error(self, scale, misalignment):
        """Model gyro scale factors ``scale`` and misalignment ``misalignment`` (1-sigma, -).

        The scale factors go to the engine's states when it has them
        (:meth:`_take_scale_states`), else into the noise; the noise's sigmas are kept
        times :data:`COHERENCE_FACTOR` (module docstring); the misalignment as told also
        sets :meth:`tilt_floor`.
        """
        scale, misalignment = float(scale), float(misalignment)
        self._rot_misalignment = max(misalignment, 0.0)
        if scale > 0.0 and self._take_scale_states(scale):
            scale = 0.0
        if self._rot is None and self._counts_rotation():
            self._rot = np.zeros(3)
        if scale <= 0.0 and misalignment <= 0.0:
            self._rot_sigma = None
            return
        self._rot_sigma = (COHERENCE_FACTOR * scale, COHERENCE_FACTOR * misalignment)
        if not self._counts_rotation():        # (the states' transition keeps its interval)
            self._rot = np.zeros(3)
        self._rot_A = np.zeros(3)

    def _take_scale_states(self, scale):
        """Carry gyro scale factors of 1-sigma ``scale`` as states; True if the engine does."""
        return False

    def _counts_rotation(self):
        """Tell whether the engine needs the interval's body rotation without the noise."""
        return False

    def tilt_floor(self):
        """Variances (3,) rad^2 about E, N, U the model cannot see: :func:`unseparable_tilt_var`.

        Follows the misalignment as the motion check raises it (:mod:`.motion_check`).
        """
        v = unseparable_tilt_var(self._rot_misalignment)
        return np.array([v, v, 0.0])

    def _add_rotation(self, dtheta):
        """Count mechanized increments ``dtheta`` ((3,) or (N, 3), rad) into the interval.

        Also sums their rotation about the local vertical (``C_b_n[2] . dtheta``: the
        attitude's vertical row depends on the tilt only) for :meth:`take_turn`.
        """
        d = np.asarray(dtheta, dtype=float)
        s = d if d.ndim == 1 else np.add.reduce(d, axis=0)
        self._turn += float(self.mech.C_b_n[2] @ s)
        if self._rot is not None:
            self._rot += s

    def take_turn(self):
        """Return None: the scale factor measured from turns is not taken here.

        The rotation is dropped; engines with scale-factor compensation
        (:mod:`.gyro_scale`) return it.
        """
        self._turn = 0.0

    def set_turn_scale(self, scale, sigma):
        """Return False: this engine does not take a measured up scale factor."""
        return False

    def _rotation_noise(self, T):
        """Process noise (n, n) of the rotation since the last call, over ``T`` s, or None.

        Starts the next interval's body rotation (the engine's transition has read it).
        """
        if self._rot is None:
            return None
        rot, self._rot = self._rot, np.zeros(3)
        if self._rot_sigma is None:
            return None
        scale, mis = self._rot_sigma
        if self._turn_scale_sigma is not None:
            scale = np.array([scale, scale, COHERENCE_FACTOR * self._turn_scale_sigma])
        self._rot_A, inc = coherent_increment(self._rot_A, rot, T, ROTATION_MEMORY_S,
                                              scale, mis, yaw_leak_bounded=True)
        E = state_noise(len(self.kf.x), self.i_phi, self.mech.C_b_n, inc)
        if HEADING_COHERENCE_FACTOR != COHERENCE_FACTOR:
            k = np.arange(len(E))[self.i_phi][2]
            s = np.ones(len(E))
            s[k] = HEADING_COHERENCE_FACTOR / COHERENCE_FACTOR
            E = E * np.outer(s, s)
        return E

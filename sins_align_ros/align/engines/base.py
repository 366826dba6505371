"""The engine contract: what the stages and the pipeline may ask of a fine-alignment engine.

Three :class:`typing.Protocol` classes, structural (no engine inherits from them; a
test checks that every engine :func:`~.factory.make_engine` builds satisfies them, and
that they declare exactly the members ``align/stages`` and ``align/pipeline.py`` use):

* :class:`Engine`: what every engine offers (the attitude, its covariance, the external
  heading, the widening a bridge or a monitor asks for) and the flag :attr:`Engine.restages`
  that names its kind;
* :class:`StillEngine` (``restages`` True, :mod:`.stationary`, seed 002): it steps itself
  from one zero-velocity filter epoch to the next and may be re-initialised;
* :class:`AidedEngine` (``restages`` False, :mod:`.aided`: seed 000 :mod:`.moving`, seed
  004 :mod:`.robust`, seeds 001/003 :mod:`.navigation`): it is stepped sample by sample
  (or in compiled blocks) and takes GNSS epochs through :meth:`AidedEngine.update`; the
  fine stage's monitors read its last epoch and widen its model.

The fine stage picks one of its two stepping paths (:mod:`~..stages.fine_stepping`) by
``restages`` once, when it starts: the two kinds step differently (the still engine's rows
of a block take the covariance after its epoch, the aided engine's are cut at every
epoch), so the paths stay two, each typed by its protocol.

Frames: body FLU, navigation ENU; attitudes ``C_b_n`` (3, 3) body -> ENU; misalignment
covariances about the E, N, U axes (rad^2), as the published attitude's (docs/contracts.md).
"""
from typing import Any, Optional, Protocol, Tuple, runtime_checkable

import numpy as np


class StrapdownState(Protocol):
    """The mechanization's state an engine's ``mech`` exposes (read by the stages)."""

    #: attitude (3, 3): body FLU -> ENU
    C_b_n: np.ndarray
    #: velocity (3,) in ENU, m/s
    v_n: np.ndarray
    #: geodetic latitude and longitude (rad), height above the ellipsoid (m)
    lat: float
    lon: float
    h: float


@runtime_checkable
class Engine(Protocol):
    """What every fine-alignment engine offers the fine stage and the pipeline."""

    #: the engine keeps navigating after alignment (``~/odom``, the navigation CSV columns;
    #: :meth:`nav_cov` is then the covariance of that solution)
    navigates: bool
    #: the engine's kind: True a :class:`StillEngine` (stepped by its own filter epochs,
    #: re-initialised when it has converged), False an :class:`AidedEngine`
    restages: bool
    #: the strapdown state (:class:`StrapdownState`): attitude, velocity, position
    mech: StrapdownState

    def attitude_cov(self) -> np.ndarray:
        """Misalignment covariance (3, 3) rad^2 about E, N, U, without the stage's floor."""

    def tilt_floor(self) -> np.ndarray:
        """Variances (3,) rad^2 about E, N, U the model cannot see now (added at output).

        What the gyro misalignment leaves in the tilt (:mod:`.rotation_error`) for the aided
        engines, as the motion check raises it; zeros for the still engine (its unseen
        variances are :func:`~.factory.make_engine`'s fixed floor).
        """

    def widen(self, var_phi: float, var_v: float) -> None:
        """Add ``var_phi`` (rad^2) to each misalignment variance, ``var_v`` to each velocity's.

        ``var_v`` in (m/s)^2; a bridge over a gap in the input, or a monitor's remedy.
        """

    def update_heading(self, fix: Any, t_now: float, w_up: float = 0.0) -> str:
        """Take an external heading ``fix`` (:class:`~..inputs.heading.HeadingFix`) at ``t_now``.

        ``t_now`` (s) the stamp of the sample it is applied at;
        ``w_up`` (rad/s) the up rate that carries the yaw from the fix's stamp to
        ``t_now``. Returns ``'used'``, ``'taken'`` (directly, beyond the small-angle
        model) or ``'rejected'`` (its gate); raises :class:`~.gnss_gate.FilterDiverged`.
        """

    def heading_measured(self) -> None:
        """Act on a coarse heading an external source measured (the gyros need not find north)."""

    def nav_cov(self) -> Optional[np.ndarray]:
        """Return the navigation solution's error covariance (9, 9), or None if not navigating.

        Position (m, E N U), velocity (m/s, ENU) and misalignment (rad) errors.
        """


@runtime_checkable
class StillEngine(Engine, Protocol):
    """A still-base engine (seed 002): its own zero-velocity epochs, restaged when converged."""

    #: re-initialising after the first stage can remove an error it leaves (a large
    #: initial misalignment, :func:`~.stationary.restage_helps`)
    restage_helps: bool
    #: the misalignment (3,) rad the last epoch fed back, ``C = exp([phi x]) C~`` (zero
    #: when it updated nothing): what the settle test sums
    last_correction: np.ndarray
    #: live gyrocompass segments (:class:`~.gyrocompass.GyroSegments`) or None
    gyro_segments: object

    def run_block(self, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, i: int,
                  t_last: float) -> Tuple[int, np.ndarray, bool]:
        """Mechanize samples ``i..`` up to the next filter epoch, which it runs.

        ``t`` (N,) s, ``dtheta``, ``dv`` (N, 3) rad, m/s (body increments); ``t_last`` the
        stamp before sample ``i``. Returns ``(j, C (j - i, 3, 3), epoch)``: the end index,
        the attitudes after each sample (the last one corrected when the epoch ran) and
        whether it ran.
        """

    def step(self, dtheta: np.ndarray, dv: np.ndarray, dt: float) -> Tuple[np.ndarray, bool]:
        """Mechanize one sample (3,) rad, (3,) m/s over ``dt`` s; ``(C_b_n (3, 3), epoch ran)``.

        The filter epoch runs when the time since the last one reaches its period.
        """

    def restage(self) -> None:
        """Re-initialise the filter from the corrected attitude (seed 002 sec. 4)."""

    def gyrocompass_update(self, yaw: float, var: float,
                           max_nis: Optional[float] = None) -> Tuple[float, float, bool]:
        """Update with a still base's gyrocompass ``yaw`` (rad, white-noise ``var`` rad^2).

        Its measurement row carries the biases the heading cannot be told from at rest.
        Returns the innovation (rad), its predicted 1-sigma and whether it was used (not
        above ``max_nis``).
        """


@runtime_checkable
class AidedEngine(Engine, Protocol):
    """A GNSS-aided engine: stepped by the stage, GNSS epochs through :meth:`update`."""

    #: misalignment and velocity-error slices of the error state (rows the motion check
    #: widens the process noise of)
    i_phi: slice
    i_v: slice
    #: predictions run without a GNSS measurement so far (an outage: the sigma grew)
    n_predict_only: int
    #: the last GNSS epoch: its NIS, its degrees of freedom (measurement rows), its
    #: innovations normalised row by row (dof,) and their rows of the full measurement
    #: vector (0-2 position E, N, U m; 3-5 velocity E, N, U m/s; per engine)
    last_nis: float
    last_dof: int
    last_u: Optional[np.ndarray]
    last_rows: Optional[np.ndarray]
    #: the engine sets each epoch's R (nominal, reported, scaled by the consistency monitor)
    sets_R: bool
    #: variance ((m/s)^2) per axis of the IMU's velocity jitter added to the GNSS velocity
    #: rows' noise (the motion check raises it)
    velocity_jitter_var: float
    #: the heading is held lost (an unknown angle beyond the linear model) until found again
    heading_lost: bool
    #: the coarse heading variance (rad^2) when the filter was given a capped prior, else None
    heading_prior_var: Optional[float]

    @property
    def estimates_R(self) -> bool:
        """Tell whether the filter estimates the measurement noise itself (variational Bayes)."""

    @property
    def rejected(self) -> bool:
        """Tell whether the last GNSS epoch was rejected by the innovation gate."""

    def step_imu(self, dtheta: np.ndarray, dv: np.ndarray, dt: float) -> np.ndarray:
        """Mechanize one sample (3,) rad, (3,) m/s over ``dt`` s; returns ``C_b_n`` (3, 3)."""

    def step_block(self, dtheta: np.ndarray, dv: np.ndarray, dt: np.ndarray) -> Any:
        """Mechanize N samples as N :meth:`step_imu` calls would; a :class:`~.aided.Block`."""

    def update(self, fix: Any, t_now: float) -> Any:
        """Take GNSS epoch ``fix`` (:class:`~..inputs.gnss_fix.GnssFix`) at ``t_now`` (s).

        Predict over the interval, update, feed back; returns the filter's update record
        (innovation ``y``, its covariance ``Pzz``). Raises ``FilterDiverged``.
        """

    def update_heading(self, fix: Any, t_now: float, w_up: float = 0.0,
                       linear_max: float = ...) -> str:
        """Take a heading as :meth:`Engine.update_heading`; directly beyond ``linear_max`` rad."""

    def heading_found(self) -> None:
        """Act on a held-lost heading that a linear heading update has set (found again)."""

    def inflate(self, factor: float) -> None:
        """Inflate the process noise by ``factor`` and the covariance by its root."""

    def relax(self) -> None:
        """Halve the process noise :meth:`inflate` raised back towards the model's."""

    def inflate_noise(self, factors: dict) -> None:
        """Inflate measurement rows' noise variances: ``factors`` row -> factor."""

    def widen_gnss_noise(self, excess: np.ndarray, block_s: float) -> tuple:
        """Widen the GNSS model by a long-horizon test's ``excess`` of ``block_s``-second means.

        Returns ``(old, new, vel)`` for the consistency monitor's note.
        """

    def widen_process_noise(self, rows: slice, factor: float, floor: float) -> None:
        """Multiply the process noise of state ``rows`` by ``factor``, at least ``floor``.

        ``factor`` < 1 narrows (the motion check, a random walk the data bound tighter).
        """

    def raise_drift_noise(self, q: float) -> None:
        """Raise the gyro-drift states' process noise (rad^2/s^3) to at least ``q``, for good."""

    def set_rotation_error(self, scale: float, misalignment: float) -> None:
        """Model gyro scale factors and axis misalignment of these 1-sigma (-)."""

    def set_force_error(self, scale: float, misalignment: float) -> None:
        """Model accelerometer scale factors and misalignment of these 1-sigma (-)."""

    def take_turn(self) -> Optional[tuple]:
        """Return the rotation about up since the last call (:mod:`..stages.turn_scale`).

        ``(A, eps_applied, eps, var_eps, q_eps, prior_var)``: rad, rad/s, rad/s, rad^2/s^2,
        rad^2/s^3, -; None when the engine does not take the up scale factor measured from
        turns (now).
        """

    def set_turn_scale(self, scale: float, sigma: Optional[float]) -> bool:
        """Compensate the up gyro's scale factor measured from turns, 1-sigma ``sigma``.

        ``sigma`` None: the told model back. False when not taken.
        """

    def receiver_velocity_var(self) -> Optional[float]:
        """Return the GNSS velocity noise variance ((m/s)^2) the filter takes, jitter apart.

        None without velocity rows.
        """

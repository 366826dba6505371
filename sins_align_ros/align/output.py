"""Output rows of the pipeline: attitude, 1-sigma Euler angles, phase, navigation.

:class:`Output` is what every caller receives (N rows for N processed samples);
:class:`Rows` holds fine-phase rows before conversion, so that a run of them is
converted to quaternions and Euler sigmas in one vectorised pass (:func:`assemble`).
"""
import math
from dataclasses import dataclass

import numpy as np

from ..nav.frames import dcm_to_euler, dcm_to_quat, euler_sigma, euler_sigma_one

#: variance of an angle known to be anywhere in (-pi, pi] (uniform): pi^2 / 3, rad^2; a
#: published heading with this variance is an unknown heading, not a claim
ANGLE_UNKNOWN_VAR = math.pi ** 2 / 3.0
HEADING_UNKNOWN_VAR = ANGLE_UNKNOWN_VAR


@dataclass
class Output:
    """Rows for N processed samples.

    ``t`` (N,) stamps (s); ``q`` (N, 4) quaternion x, y, z, w body FLU -> ENU
    (NaN while unknown); ``euler`` (N, 3) REP-103 roll, pitch, yaw (rad);
    ``sigma`` (N, 3) 1-sigma of those angles (rad); ``P_phi`` (N, 3, 3)
    covariance of the misalignment about the ENU axes (rad^2); ``phase`` (N,)
    phase names; ``nav`` (N, 6) or None: the navigation solution of the navigation
    filters (``kf``, ``vbakf``, ``mvbakf``, ``ukf``) at each sample, latitude and
    longitude (rad), height (m), ENU velocity (m/s); NaN where there is none.
    """

    t: np.ndarray
    q: np.ndarray
    euler: np.ndarray
    sigma: np.ndarray
    P_phi: np.ndarray
    phase: np.ndarray
    nav: np.ndarray = None

    @staticmethod
    def concat(parts):
        """Join several outputs (or :class:`DeferredOutput`) in time order.

        Deferred parts stay deferred: the result is a :class:`DeferredOutput` over all
        the parts' rows, converted in one pass when first used.
        """
        parts = [p for p in parts if len(p)]
        if not parts:
            return Output.empty()
        if len(parts) == 1:
            return parts[0]
        if any(isinstance(p, DeferredOutput) for p in parts):
            return DeferredOutput([r for p in parts
                                   for r in (p.parts if isinstance(p, DeferredOutput) else [p])])
        out = Output(*(np.concatenate([getattr(p, f) for p in parts])
                       for f in ('t', 'q', 'euler', 'sigma', 'P_phi', 'phase')))
        out.nav = concat_nav(parts)
        return out

    @staticmethod
    def empty():
        """Return an output with no rows.

        Its arrays are shared by every empty output (most calls return one): arrays of
        no elements, which nothing can write into.
        """
        return Output(*_EMPTY)

    def __len__(self):
        return len(self.t)


#: the arrays of :meth:`Output.empty` (t, q, euler, sigma, P_phi, phase)
_EMPTY = (np.zeros(0), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros((0, 3)),
          np.zeros((0, 3, 3)), np.zeros(0, dtype=object))


class Rows:
    """Fine-phase rows before conversion.

    Attitudes (N, 3, 3), one covariance (3, 3), and the navigation solution (N, 6) or None.
    """

    __slots__ = ('t', 'C', 'P_phi', 'phase', 'nav')

    def __init__(self, t, C, P_phi, phase, nav=None):
        self.t, self.C, self.P_phi, self.phase, self.nav = t, C, P_phi, phase, nav

    def output(self):
        return convert([self])


def concat_nav(parts):
    """Join the parts' navigation rows (N, 6), NaN for parts without; None if none has any."""
    if all(p.nav is None for p in parts):
        return None
    return np.concatenate([p.nav if p.nav is not None else np.full((len(p.t), 6), np.nan)
                           for p in parts])


def one_row(t, C, P, phase, nav):
    """One-row :class:`Output` from an attitude (3, 3) and its covariance (3, 3)."""
    eul = dcm_to_euler(C)
    return Output(np.array([t]), dcm_to_quat(C)[None], eul[None],
                  euler_sigma_one(eul, P.tolist())[None], P[None],
                  np.array([phase], dtype=object), nav)


class DeferredOutput:
    """The :class:`Output` of a list of :class:`Output` and :class:`Rows` parts, made when used.

    Any :class:`Output` attribute (``t``, ``q``, ``phase``, ...) converts the parts
    (:func:`convert`) once and is read from the result; ``len`` and
    :meth:`Output.concat` need no conversion, so a replay that joins thousands of
    blocks' rows converts its fine rows in one vectorised pass instead of one per block.
    The parts must not change afterwards (the pipeline's rows are fresh arrays).
    """

    __slots__ = ('parts', '_out')

    def __init__(self, parts):
        self.parts, self._out = parts, None

    def __len__(self):
        return sum(len(p.t) for p in self.parts)

    def output(self):
        """Return the converted :class:`Output` (converting the parts the first time)."""
        if self._out is None:
            self._out = convert(self.parts)
            self.parts = [self._out]
        return self._out

    def __getattr__(self, name):
        if name.startswith('__') or name in DeferredOutput.__slots__:
            raise AttributeError(name)        # unpickling, copying: no conversion
        return getattr(self.output(), name)


def assemble(parts):
    """Return the output of ``parts`` (:class:`Output` and :class:`Rows`), converted when used."""
    return DeferredOutput(list(parts))


def convert(parts):
    """Convert runs of fine-phase :class:`Rows` in one vectorised pass; join everything."""
    done, run = [], []

    def flush():
        if not run:
            return
        t = np.concatenate([r.t for r in run])
        C = np.concatenate([r.C for r in run])
        # each part's one covariance and phase repeated over its rows (thousands of parts)
        lengths = [len(r.t) for r in run]
        P = np.repeat(np.array([r.P_phi for r in run], dtype=float), lengths, axis=0)
        phases = np.empty(len(run), dtype=object)
        phases[:] = [r.phase for r in run]
        ph = np.repeat(phases, lengths)
        eul = dcm_to_euler(C)
        sig = euler_sigma(eul, P)
        done.append(Output(t, dcm_to_quat(C), eul, sig, P, ph, concat_nav(run)))
        run.clear()

    for p in parts:
        if isinstance(p, Rows):
            run.append(p)
        else:
            flush()
            done.append(p)
    flush()
    return Output.concat(done)


def unknown(t, phase):
    n = len(t)
    nan3 = np.full((n, 3), np.nan)
    return Output(np.asarray(t, float), np.full((n, 4), np.nan), nan3, nan3.copy(),
                  np.full((n, 3, 3), np.nan), np.full(n, phase, dtype=object))

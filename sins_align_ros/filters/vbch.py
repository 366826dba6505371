"""The variational-Bayes cubature H-infinity filter (VBCH) of seed 004.

:class:`~sins_align_ros.filters.vbckf.VBCKF` with the H-infinity posterior covariance
(seed 004 eq. 10-13) for the auxiliary output ``y = L x`` and the adaptive robust factor
gamma (eq. 14-15, constant ``C``), per the algorithm box of seed 004 sec. 2.4; where we
differ from the box, and why: :mod:`~sins_align_ros.filters.variational` (the posterior's
evaluation, the normalised innovation energy of eq. 15, the cap of the posterior
variances at their initial values, ``cap_at_p0``).
"""
import numpy as np

from .vbckf import VBCKF


class VBCH(VBCKF):
    """Seed 004's variational-Bayes cubature H-infinity filter (module docstring).

    As :class:`VBCKF`, plus ``L`` (p, n) the H-infinity auxiliary output, ``C`` the
    robust-factor constant and ``cap_at_p0`` (no posterior variance above its P0).
    """

    def __init__(self, x0, P0, Q, R, L, rho=0.98, n_iter=20, C=1.5, cap_at_p0=True, dof=None):
        super().__init__(x0, P0, Q, R, rho=rho, n_iter=n_iter, dof=dof)
        self.L = np.asarray(L, dtype=float)
        self.C = float(C)
        self.var_max = np.diag(self.P).copy() if cap_at_p0 else None

    def append_states(self, var):
        """Append random constants as every filter does; ``L`` takes none of them.

        ``L`` grows by zero columns (the auxiliary output is the states it named) and the
        posterior cap by the new states' prior variances ``var`` (k,).
        """
        super().append_states(var)
        var = np.asarray(var, dtype=float)
        self.L = np.hstack([self.L, np.zeros((len(self.L), len(var)))])
        if self.var_max is not None:
            self.var_max = np.r_[self.var_max, var]

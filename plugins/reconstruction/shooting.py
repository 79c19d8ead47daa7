"""Multiple-shooting refinement of a control track (beyond the seed).

Single shooting — the seed's parameterisation, one initial state and the controls — makes an
early control move every later position, so on long manoeuvring flights the cost is strongly
curved and a local refinement stalls. Multiple shooting (Bock & Plitt 1984) frees the state
S_k = (x, y, φ, v) at the start of every segment and ties the segments together with continuity
residuals instead::

    plot i in segment k:   L_i⁻¹ (z_i − p(Flow_k(t_i − t_k, S_k)))
    continuity k → k+1:    (Flow_k(t_{k+1} − t_k, S_k) − S_{k+1}) / σ_c

Each residual depends on one or two segments only, so the problem is far less nonlinear. The
result is handed back as a single-shooting parameter vector (S_0, u, w, switch times), whose own
refinement then removes the remaining continuity gaps. The control-jump prior is not part of this
stage (it fits the plots alone); the single-shooting refinement after it is the MAP fit.
The residuals and the Jacobian are compiled kernels (:func:`._kernels.ms_residuals`,
:func:`._kernels.ms_jacobian`); the solver is :func:`.lm.levenberg_marquardt`.
"""

from __future__ import annotations

import numpy as np

from radartracker_plugins.reconstruction import _kernels as kern
from radartracker_plugins.reconstruction.lm import levenberg_marquardt


class MultipleShooting:
    """Residuals and Jacobian of the multiple-shooting problem for a :class:`~.fit.ControlObjective`.

    φ = [S_0 … S_{K−1} (4K), u (K), w (K), interior switch times (K − 1)].
    """

    def __init__(self, obj) -> None:
        self.obj, self.K = obj, obj.K
        self.n_rows = 2 * len(obj.times) + 4 * (obj.K - 1)

    def _args(self, phi: np.ndarray) -> tuple:
        o = self.obj
        return np.ascontiguousarray(phi, float), self.K, o.lower, o.upper, o.cs, o.times

    def residuals(self, phi: np.ndarray) -> np.ndarray:
        """The plot rows L_i⁻¹(z_i − p_i) (2n), then the continuity gaps / σ_c (4(K − 1))."""
        r = np.empty(self.n_rows)
        kern.ms_residuals(*self._args(phi), self.obj.z, self.obj.Linv, self.obj.wk, self.obj.p, r)
        return r

    def jacobian(self, phi: np.ndarray) -> np.ndarray:
        """∂ residuals / ∂φ, block-sparse (:func:`._kernels.ms_jacobian`)."""
        J = np.empty((self.n_rows, len(phi)))
        kern.ms_jacobian(*self._args(phi), self.obj.Linv, self.obj.wk, np.empty((4, 6)), J)
        return J

    def order(self) -> np.ndarray:
        """Place of each parameter of φ in the normal equations: segment by segment (S_k, u_k, w_k, t_k) at
        7k … 7k + 6. A plot row then spans places 7k − 1 … 7k + 5 and a continuity row 7k − 1 … 7k + 10, so
        JᵀJ is banded with bandwidth 11."""
        K, k = self.K, np.arange(self.K)
        return np.concatenate([(7 * k[:, None] + np.arange(4)).ravel(), 7 * k + 4, 7 * k + 5, 7 * k[:-1] + 6])

    def from_single(self, theta: np.ndarray) -> np.ndarray:
        """φ of a single-shooting θ (states chained through the segments)."""
        init, u, w, bounds, _ = self.obj.unpack(theta)
        _, w_eff, _ = self.obj.positions(init, u, w, bounds)
        S, states = tuple(init), []
        for k in range(self.K):
            states.append(S)
            S = kern.flow(*S, u[k], w_eff[k], bounds[k + 1] - bounds[k])
        return np.concatenate([np.ravel(states), u, w_eff, bounds[1:-1]])

    def to_single(self, phi: np.ndarray) -> np.ndarray:
        """The single-shooting θ = (S_0, u, w, switch times) of φ."""
        K = self.K
        return np.concatenate([phi[:4], phi[4 * K:]])

    def refine(self, theta: np.ndarray, max_nfev: int) -> tuple[np.ndarray, int]:
        """θ after a multiple-shooting Levenberg–Marquardt refinement, and the evaluations spent."""
        phi, nfev = levenberg_marquardt(self.residuals, self.jacobian, self.from_single(theta), max_nfev, self.order())
        return self.to_single(phi), nfev

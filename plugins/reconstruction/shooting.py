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
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from radartracker.api import propagate

# continuity scale (x, y m; φ rad; v m/s): gaps this size cost as much as one σ of one plot
SIGMA_CONTINUITY = np.array([1.0, 1.0, 1e-4, 1e-2])
_FD = ((2, 1e-6), (3, 1e-4), (4, 1e-5), (5, 1e-5))


def _rhs(s: np.ndarray, u: float, w: float) -> np.ndarray:
    return np.array([s[3] * np.sin(s[2]), s[3] * np.cos(s[2]), u / s[3], w])


def _flow(S, u, w, tau) -> tuple[np.ndarray, np.ndarray]:
    """States (4, m) at ``tau`` and their derivatives (4, m, 6) wrt (x0, y0, φ0, v0, u, w)."""
    base = np.array(propagate(*S, u, w, tau))
    D = np.zeros((4, len(tau), 6))
    D[0, :, 0] = D[1, :, 1] = 1.0
    for j, h in _FD:
        hi, lo = [*S, u, w], [*S, u, w]
        hi[j] += h
        lo[j] -= h
        D[:, :, j] = (np.array(propagate(*hi[:4], hi[4], hi[5], tau)) - np.array(propagate(*lo[:4], lo[4], lo[5], tau))) / (2 * h)
    return base, D


class MultipleShooting:
    """Residuals and Jacobian of the multiple-shooting problem for a :class:`~.fit.ControlObjective`.

    φ = [S_0 … S_{K−1} (4K), u (K), w (K), interior switch times (K − 1)].
    """

    def __init__(self, obj) -> None:
        self.obj, self.K = obj, obj.K
        self.Linv, self.z, self.times = obj.weight.Linv, obj.weight.z, obj.times

    def split(self, phi: np.ndarray):
        K = self.K
        S = phi[:4 * K].reshape(K, 4)
        # the controls and switch times are projected like the single-shooting ones
        _, u, w, bounds, _ = self.obj.unpack(np.concatenate([S[0], phi[4 * K:]]))
        return S, u, w, bounds

    def _segments(self, phi: np.ndarray):
        S, u, w, bounds = self.split(phi)
        cut = np.concatenate([[0], np.searchsorted(self.times, bounds[1:-1], side="left"), [len(self.times)]])
        for k in range(self.K):
            S_k = S[k].copy()
            S_k[3] = max(S_k[3], self.obj.cfg.v_min)
            w_k = max(w[k], (self.obj.cfg.v_min - S_k[3]) / (bounds[k + 1] - bounds[k]))
            tau = np.append(self.times[cut[k]:cut[k + 1]] - bounds[k], bounds[k + 1] - bounds[k])
            yield k, slice(cut[k], cut[k + 1]), S, S_k, u[k], w_k, tau

    def residuals(self, phi: np.ndarray) -> np.ndarray:
        out = [np.empty(2 * len(self.times))]
        gaps = []
        for k, sl, S, S_k, u, w, tau in self._segments(phi):
            st = np.array(propagate(*S_k, u, w, tau))
            out[0][2 * sl.start:2 * sl.stop] = np.einsum("nij,nj->ni", self.Linv[sl], self.z[sl] - st[:2, :-1].T).ravel()
            if k + 1 < self.K:
                gaps.append((st[:, -1] - S[k + 1]) / SIGMA_CONTINUITY)
        return np.concatenate(out + gaps)

    def jacobian(self, phi: np.ndarray) -> np.ndarray:
        K, n = self.K, len(self.times)
        J = np.zeros((2 * n + 4 * (K - 1), len(phi)))
        for k, sl, S, S_k, u, w, tau in self._segments(phi):
            st, D = _flow(S_k, u, w, tau)
            cols = [4 * k, 4 * k + 1, 4 * k + 2, 4 * k + 3, 4 * K + k, 5 * K + k]
            rows = slice(2 * sl.start, 2 * sl.stop)
            J[rows, cols] = -np.einsum("nij,jnp->nip", self.Linv[sl], D[:2, :-1, :]).reshape(-1, 6)
            f_end = _rhs(st[:, -1], u, w)
            if k > 0:  # moving t_k shortens τ for every plot of segment k
                pdot = np.stack([st[3, :-1] * np.sin(st[2, :-1]), st[3, :-1] * np.cos(st[2, :-1])], axis=1)
                J[rows, 6 * K + k - 1] = np.einsum("nij,nj->ni", self.Linv[sl], pdot).ravel()
            if k + 1 < K:
                r = slice(2 * n + 4 * k, 2 * n + 4 * k + 4)
                J[r, cols] = D[:, -1, :] / SIGMA_CONTINUITY[:, None]
                J[r, 4 * (k + 1):4 * (k + 2)] = -np.diag(1.0 / SIGMA_CONTINUITY)
                J[r, 6 * K + k] = f_end / SIGMA_CONTINUITY
                if k > 0:
                    J[r, 6 * K + k - 1] = -f_end / SIGMA_CONTINUITY
        return J

    def from_single(self, theta: np.ndarray) -> np.ndarray:
        """φ of a single-shooting θ (states chained through the segments)."""
        init, u, w, bounds, _ = self.obj.unpack(theta)
        _, w_eff, _ = self.obj.positions(init, u, w, bounds)
        S, states = np.array(init, float), []
        for k in range(self.K):
            states.append(S)
            S = np.array(propagate(*S, u[k], w_eff[k], np.array([bounds[k + 1] - bounds[k]])))[:, 0]
        return np.concatenate([np.ravel(states), u, w_eff, bounds[1:-1]])

    def to_single(self, phi: np.ndarray) -> np.ndarray:
        K = self.K
        return np.concatenate([phi[:4], phi[4 * K:]])

    def refine(self, theta: np.ndarray, max_nfev: int) -> tuple[np.ndarray, int]:
        """θ after a multiple-shooting Levenberg–Marquardt refinement, and the evaluations spent."""
        res = least_squares(self.residuals, self.from_single(theta), jac=self.jacobian, method="lm",
                            x_scale="jac", ftol=1e-8, xtol=1e-12, max_nfev=max_nfev)
        return self.to_single(res.x), int(res.nfev)

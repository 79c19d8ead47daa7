"""A plain, FilterPy-shaped IMM: the test oracle of the ``imm`` plugin (none of the plugin's code).

Mode filters are objects with their own state (``x``, ``P``), ``predict(dt)`` and
``update(z, R) -> log N(ν; 0, Λ)``: :class:`CVKalman` wraps FilterPy's ``KalmanFilter`` with the
constant-velocity A(Δt), Q(Δt) written here; :class:`CTExtendedKalman` is a coordinated-turn EKF whose
Jacobian is taken by complex-step differentiation of f (exact to rounding, independent of the
plugin's closed-form Jacobian). :class:`PlainIMM` mixes them as Blom & Bar-Shalom (and FilterPy's
``IMMEstimator``) do, in the largest mode's state: a 4-state mode enters the mixing with ω = 0 ± σ_e.
"""

from __future__ import annotations

import numpy as np
from filterpy.kalman import KalmanFilter
from scipy.linalg import expm
from scipy.stats import multivariate_normal


def cv_matrices(dt: float, q: float) -> tuple[np.ndarray, np.ndarray]:
    """A(Δt) = [[I, Δt I], [0, I]] and Q = q [[|Δt|³/3 I, Δt²/2 I], [Δt²/2 I, |Δt| I]]."""
    I2, a = np.eye(2), abs(dt)
    A = np.block([[I2, dt * I2], [0 * I2, I2]])
    Q = q * np.block([[a**3 / 3 * I2, a**2 / 2 * I2], [a**2 / 2 * I2, a * I2]])
    return A, Q


def ct_mean(xi: np.ndarray, T: float) -> np.ndarray:
    """f(ξ) of the coordinated turn, ξ = [x, y, vx, vy, ω] (ω clockwise), through numpy's sinc so that
    ω = 0 is the constant-velocity limit: sin(ωT)/ω = T sinc(a/π), (1 − cos ωT)/ω = T (a/2) sinc²(a/2π)."""
    x, y, vx, vy, w = xi
    a = w * T
    f1, f2 = T * np.sinc(a / np.pi), T * (a / 2) * np.sinc(a / (2 * np.pi)) ** 2
    s, c = np.sin(a), np.cos(a)
    return np.array([x + f1 * vx + f2 * vy, y - f2 * vx + f1 * vy, c * vx + s * vy, -s * vx + c * vy, w])


def ct_jacobian(xi: np.ndarray, T: float, h: float = 1e-30) -> np.ndarray:
    """∂f/∂ξ by complex steps: column k = Im f(ξ + i h e_k) / h."""
    J = np.empty((5, 5))
    for k in range(5):
        step = xi.astype(complex)
        step[k] += 1j * h
        J[:, k] = ct_mean(step, T).imag / h
    return J


class CVKalman:
    """Constant-velocity mode: FilterPy's KalmanFilter on [x, y, vx, vy], density ``q``."""

    dim = 4

    def __init__(self, q: float, x: np.ndarray, P: np.ndarray) -> None:
        self.q, self.kf = q, KalmanFilter(dim_x=4, dim_z=2)
        self.kf.x, self.kf.P, self.kf.H = x.copy(), P.copy(), np.eye(2, 4)

    x = property(lambda self: self.kf.x, lambda self, v: setattr(self.kf, "x", v))
    P = property(lambda self: self.kf.P, lambda self, v: setattr(self.kf, "P", v))

    def predict(self, dt: float) -> None:
        self.kf.F, self.kf.Q = cv_matrices(dt, self.q)
        self.kf.predict()

    def update(self, z: np.ndarray, R: np.ndarray) -> float:
        self.kf.update(z, R=R)
        return float(self.kf.log_likelihood)


class CTExtendedKalman:
    """Coordinated-turn mode: an EKF on [x, y, vx, vy, ω], white acceleration ``q`` and a turn-rate
    random walk of σ_ω² |Δt|."""

    dim = 5

    def __init__(self, q: float, turn_rate_sd: float, x: np.ndarray, P: np.ndarray) -> None:
        self.q, self.turn_rate_sd, self.x, self.P = q, turn_rate_sd, x.copy(), P.copy()

    def predict(self, dt: float) -> None:
        F = ct_jacobian(self.x, dt)
        Q = np.zeros((5, 5))
        Q[:4, :4] = cv_matrices(dt, self.q)[1]
        Q[4, 4] = self.turn_rate_sd**2 * abs(dt)
        self.x, self.P = ct_mean(self.x, dt), F @ self.P @ F.T + Q

    def update(self, z: np.ndarray, R: np.ndarray) -> float:
        H = np.eye(2, 5)
        S = H @ self.P @ H.T + R
        K = self.P @ H.T @ np.linalg.inv(S)
        loglik = multivariate_normal(H @ self.x, S).logpdf(z)
        self.x, self.P = self.x + K @ (z - H @ self.x), (np.eye(5) - K @ H) @ self.P
        return float(loglik)


def sojourn_generator(tau) -> np.ndarray:
    """G with G_ii = −1/τ_i and the leaving rate shared equally among the other modes."""
    tau = np.asarray(tau, float)
    G = np.ones((len(tau), len(tau))) / ((len(tau) - 1) * tau[:, None])
    np.fill_diagonal(G, -1.0 / tau)
    return G


class PlainIMM:
    """IMM of mode filter objects: Π(Δt) = expm(G|Δt|) (or a fixed ``M``), mixing in 5 states (a 4-state
    mode padded with ω = 0 ± σ_e), each mode's own predict and update, μ_j ∝ c̄_j N(ν_j; 0, Λ_j) and
    the moment-matched output on [x, y, vx, vy]."""

    def __init__(self, modes: list, mu, entry_var: float, G=None, M=None) -> None:
        self.modes, self.mu, self.entry_var, self.G, self.M = modes, np.asarray(mu, float), entry_var, G, M
        self.D = max(m.dim for m in modes)

    def _padded(self, m) -> tuple[np.ndarray, np.ndarray]:
        x, P = np.zeros(self.D), np.zeros((self.D, self.D))
        x[:m.dim], P[:m.dim, :m.dim] = m.x, m.P
        if m.dim < self.D:
            P[4, 4] = self.entry_var
        return x, P

    def predict(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Mix and predict every mode; the predicted mixture Σ c̄_j N(x̄_j, P̄_j) on 4 states."""
        Pi = self.M if self.M is not None else expm(self.G * abs(dt))
        self.cbar = self.mu @ Pi
        states = [self._padded(m) for m in self.modes]
        for j, m in enumerate(self.modes):
            w = Pi[:, j] * self.mu / self.cbar[j]
            x0 = sum(wi * x for wi, (x, _) in zip(w, states))
            P0 = sum(wi * (P + np.outer(x - x0, x - x0)) for wi, (x, P) in zip(w, states))
            m.x, m.P = x0[:m.dim].copy(), P0[:m.dim, :m.dim].copy()
            m.predict(dt)
        return self._mixture(self.cbar)

    def update(self, z: np.ndarray, R: np.ndarray) -> float:
        """Every mode's update and the new μ; returns the predicted mixture's NIS."""
        xb, Pb = self._mixture(self.cbar)
        nu = z - xb[:2]
        nis = float(nu @ np.linalg.solve(Pb[:2, :2] + R, nu))
        loglik = np.array([m.update(z, R) for m in self.modes])
        w = np.log(self.cbar) + loglik
        self.mu = np.exp(w - w.max()) / np.exp(w - w.max()).sum()
        return nis

    def _mixture(self, weights) -> tuple[np.ndarray, np.ndarray]:
        x = sum(c * m.x[:4] for c, m in zip(weights, self.modes))
        P = sum(c * (m.P[:4, :4] + np.outer(m.x[:4] - x, m.x[:4] - x)) for c, m in zip(weights, self.modes))
        return x, P

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        return self._mixture(self.mu)

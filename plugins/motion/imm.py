"""Interacting multiple model filter (Blom & Bar-Shalom 1988), plugin ``imm``.

Modes j = 1..n (default: constant velocity and coordinated turn with unknown turn rate) with
switching probabilities Π_ij(Δt) = P(mode j at t+Δt | mode i at t). One cycle, for mode
probabilities μ and mode estimates (ξ_i, P_i)::

    c̄_j = Σ_i Π_ij μ_i,   ω_ij = Π_ij μ_i / c̄_j                                   (mixing)
    ξ⁰_j = Σ_i ω_ij ξ_i,  P⁰_j = Σ_i ω_ij [P_i + (ξ_i − ξ⁰_j)(ξ_i − ξ⁰_j)ᵀ]
    (ξ̄_j, P̄_j) = mode-j prediction of (ξ⁰_j, P⁰_j);  Kalman correction with z    (mode filters)
    μ_j ∝ c̄_j N(ν_j; 0, Λ_j)                                                      (mode probabilities)
    χ̂ = Σ_j μ_j ξ_j,  P̂ = Σ_j μ_j [P_j + (ξ_j − χ̂)(ξ_j − χ̂)ᵀ]                     (output, moment matched)

States of different size are mixed in the largest one: the 4-state constant-velocity mode is the
coordinated-turn mode with ω = 0, padded with ω = 0 and variance σ_e² (``turn_rate_entry_sd``: the
turn rate is unknown when a turn begins); a mode keeps only its own components of the mixture. At
``start`` every mode takes the one-point state, the CT mode with ω = 0 ± σ_e.
The CT mode is an extended Kalman filter (:mod:`radartracker_plugins.motion.ct`).

``params``:
  ``models`` — list of ``{"kind": "cv", "q": …}`` / ``{"kind": "ct", "q": …, "turn_rate_sd": …}``
  (default CV with ``settings.q`` and CT with ``settings.q_turn``, ``settings.turn_rate_sd``);
  ``sojourn_s`` — mean time in each mode (default 120 s CV, 30 s CT): Π(Δt) = exp(G |Δt|) with
  G_ii = −1/τ_i and the leaving rate shared equally among the other modes, so Π = I at Δt = 0;
  ``transition`` — instead, a fixed Π applied at every update (FilterPy's ``M``);
  ``initial_probabilities`` — μ at start (default ∝ τ, the chain's stationary law, or uniform);
  ``turn_rate_entry_sd`` — σ_e (rad/s, default 2°/s).
"""

from __future__ import annotations

import math

import numpy as np

from radartracker.api import MotionModel, MotionSettings, TrackFilter, symmetrize
from radartracker_plugins.motion.base import (check_measurement, check_time, max_gap,
                                               position_update, require_started, start_state)
from radartracker_plugins.motion.ct import ct_noise, ct_transition


class _CV:
    dim = 4

    def __init__(self, q: float) -> None:
        self.model = MotionModel(q)

    def predict(self, x, P, dt):
        A, Q = self.model.transition(dt)
        return A @ x, symmetrize(A @ P @ A.T + Q)


class _CT:
    dim = 5

    def __init__(self, q: float, turn_rate_sd: float) -> None:
        self.q, self.turn_rate_sd = q, turn_rate_sd

    def predict(self, x, P, dt):
        f, F = ct_transition(x, dt)
        return f, symmetrize(F @ P @ F.T + ct_noise(dt, self.q, self.turn_rate_sd))


def _make_mode(spec: dict, s: MotionSettings):
    kind = spec.get("kind")
    if kind == "cv":
        return _CV(float(spec.get("q", s.q)))
    if kind == "ct":
        return _CT(float(spec.get("q", s.q_turn)), float(spec.get("turn_rate_sd", s.turn_rate_sd)))
    raise ValueError(f"params['models']: unknown kind {kind!r} (expected 'cv' or 'ct')")


class IMMFilter(TrackFilter):
    """IMM of constant-velocity and coordinated-turn Kalman filters, output moment matched."""

    name = "imm"

    def __init__(self, settings: MotionSettings | None = None) -> None:
        super().__init__(settings)
        self.max_gap = max_gap(self.settings)
        p = self.settings.params
        specs = p.get("models", [{"kind": "cv"}, {"kind": "ct"}])
        self.modes = [_make_mode(dict(m), self.settings) for m in specs]
        n = len(self.modes)
        if n == 0:
            raise ValueError("params['models']: at least one model is needed")
        self.dim = max(m.dim for m in self.modes)
        self.entry_sd = float(p.get("turn_rate_entry_sd", math.radians(2.0)))
        if "transition" in p:
            self.fixed_pi = np.asarray(p["transition"], float)
            if self.fixed_pi.shape != (n, n) or not np.allclose(self.fixed_pi.sum(axis=1), 1.0) \
                    or np.any(self.fixed_pi < 0):
                raise ValueError("params['transition']: expected an n×n matrix of rows summing to 1")
            self.expG = None
            default_mu = np.full(n, 1.0 / n)
        else:
            self.fixed_pi = None
            tau = np.asarray(p.get("sojourn_s", [120.0 if m.dim == 4 else 30.0 for m in self.modes]), float)
            if tau.shape != (n,) or np.any(tau <= 0):
                raise ValueError("params['sojourn_s']: expected one positive time per model")
            # G = D B, D = diag(1/τ), B = (J − n I)/(n − 1) symmetric: exp(G t) through the symmetric
            # D^½ B D^½ = U Λ Uᵀ, exp(G t) = D^½ U e^{Λt} Uᵀ D^-½ (scipy's expm costs ms per call)
            B = (np.ones((n, n)) - n * np.eye(n)) / max(n - 1, 1)
            d = np.sqrt(1.0 / tau)
            lam, U = np.linalg.eigh(d[:, None] * B * d[None, :])
            self.expG = (np.minimum(lam, 0.0), d[:, None] * U, U.T / d[None, :])
            default_mu = tau / tau.sum()
        mu0 = np.asarray(p.get("initial_probabilities", default_mu), float)
        if mu0.shape != (n,) or np.any(mu0 < 0) or mu0.sum() <= 0:
            raise ValueError("params['initial_probabilities']: expected n non-negative numbers")
        self.mu0 = mu0 / mu0.sum()
        self.time: float | None = None
        self.mu = self.mu0.copy()
        self.xs: list[np.ndarray] = []
        self.Ps: list[np.ndarray] = []

    # --- IMM cycle -----------------------------------------------------------------------------
    def switching(self, dt: float) -> np.ndarray:
        """Π(Δt): the fixed matrix, or exp(G |Δt|)."""
        if self.expG is None:
            return self.fixed_pi
        lam, left, right = self.expG
        return np.maximum((left * np.exp(lam * abs(dt))) @ right, 0.0)

    def _pad(self, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if len(x) == self.dim:
            return x, P
        xp, Pp = np.zeros(self.dim), np.zeros((self.dim, self.dim))
        xp[:4], Pp[:4, :4] = x, P
        Pp[4, 4] = self.entry_sd**2
        return xp, Pp

    def _predicted(self, time: float):
        """c̄ and each mode's prediction from its mixed initial condition."""
        Pi = self.switching(time - self.time)
        cbar = self.mu @ Pi
        padded = [self._pad(x, P) for x, P in zip(self.xs, self.Ps)]
        out = []
        for j, mode in enumerate(self.modes):
            w = Pi[:, j] * self.mu / cbar[j] if cbar[j] > 0 else np.eye(len(self.modes))[j]
            x0 = sum(wi * x for wi, (x, _) in zip(w, padded))
            P0 = sum(wi * (P + np.outer(x - x0, x - x0)) for wi, (x, P) in zip(w, padded))
            d = mode.dim
            out.append(mode.predict(x0[:d], symmetrize(P0[:d, :d]), time - self.time))
        return cbar, out

    @staticmethod
    def _combine(mu: np.ndarray, states) -> tuple[np.ndarray, np.ndarray]:
        x = sum(m * s[0][:4] for m, s in zip(mu, states))
        P = sum(m * (s[1][:4, :4] + np.outer(s[0][:4] - x, s[0][:4] - x)) for m, s in zip(mu, states))
        return x, symmetrize(P)

    # --- TrackFilter -----------------------------------------------------------------------------
    def start(self, time: float, z: np.ndarray, R: np.ndarray) -> None:
        self.time, z, R = check_measurement(time, z, R)
        x, P = start_state(z, R, self.settings.prior_sd_velocity_mps)
        self.mu = self.mu0.copy()
        self.xs, self.Ps = [], []
        for mode in self.modes:
            xp, Pp = self._pad(x, P) if mode.dim == 5 else (x, P)
            self.xs.append(xp.copy())
            self.Ps.append(Pp.copy())

    def predict(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        time = check_time(time, self.time, self.max_gap)
        cbar, pred = self._predicted(time)
        return self._combine(cbar, pred)

    def update(self, time: float, z: np.ndarray, R: np.ndarray) -> float:
        time, z, R = check_measurement(time, z, R)
        check_time(time, self.time, self.max_gap)
        cbar, pred = self._predicted(time)
        x_bar, P_bar = self._combine(cbar, pred)
        nis = position_update(x_bar, P_bar, z, R).nis
        steps = [position_update(x, P, z, R) for x, P in pred]
        logw = np.log(np.maximum(cbar, 1e-300)) + np.array([s.loglik for s in steps])
        w = np.exp(logw - logw.max())
        self.mu = w / w.sum()
        self.xs = [s.x for s in steps]
        self.Ps = [s.P for s in steps]
        self.time = time
        return nis

    def estimate(self) -> tuple[float, np.ndarray, np.ndarray]:
        require_started(self.time)
        x, P = self._combine(self.mu, list(zip(self.xs, self.Ps)))
        return self.time, x, P

    @property
    def probabilities(self) -> np.ndarray:
        """Current mode probabilities μ."""
        return self.mu.copy()

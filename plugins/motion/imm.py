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

Composition, in the spirit of FilterPy's ``IMMEstimator(filters, mu, M)``: the mode filters are
:class:`CVMode` / :class:`CTMode` objects (or any object with ``dim`` 4 or 5 and
``predict(x, P, dt) -> (x̄, P̄)``) passed in :class:`IMMConfig` ``modes`` (default: CV with ``q`` and CT
with ``q_turn``, ``turn_rate_sd``), with the Markov chain either ``sojourn_s`` — mean time in each mode
(default 120 s CV, 30 s CT): Π(Δt) = exp(G |Δt|) with G_ii = −1/τ_i and the leaving rate shared
equally among the other modes, so Π = I at Δt = 0 — or ``transition``, a fixed Π applied at every
update (FilterPy's ``M``); ``initial_probabilities`` μ at start (default ∝ τ, the chain's stationary
law, or uniform); ``turn_rate_entry_sd`` σ_e (rad/s, default 2°/s). :meth:`IMMFilter.from_modes`
builds one from modes and a matrix directly.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import attrs
import numpy as np

from radartracker.api import ConfigurationError, MotionConfig, TrackFilter, kernels
from radartracker_plugins.motion.base import check_measurement, check_time, position_update, require_started, start_state

_v = attrs.validators


def _floats(v: Any) -> tuple[float, ...] | None:
    return None if v is None else tuple(float(x) for x in np.ravel(v))


def _matrix(v: Any) -> tuple[tuple[float, ...], ...] | None:
    return None if v is None else tuple(tuple(float(x) for x in row) for row in np.atleast_2d(np.asarray(v, float)))


@attrs.frozen
class CVMode:
    """IMM mode filter: constant velocity, χ̄ = A χ, P̄ = A P Aᵀ + Q(Δt) of density ``q`` (m²/s³)."""

    q: float = attrs.field(default=1.0, converter=float, validator=_v.ge(0.0))
    dim = 4

    def predict(self, x: np.ndarray, P: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        return kernels.cv_predict(x, P, float(dt), self.q)


@attrs.frozen
class CTMode:
    """IMM mode filter: coordinated turn with unknown rate (EKF on [x, y, vx, vy, ω],
    :mod:`radartracker_plugins.motion.ct`), densities ``q`` (m²/s³) and ``turn_rate_sd`` (rad/s/√s)."""

    q: float = attrs.field(default=1.0, converter=float, validator=_v.ge(0.0))
    turn_rate_sd: float = attrs.field(default=math.radians(0.5), converter=float, validator=_v.ge(0.0))
    dim = 5

    def predict(self, x: np.ndarray, P: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        return kernels.ct_predict(x, P, float(dt), self.q, self.turn_rate_sd)


@attrs.frozen
class IMMConfig(MotionConfig):
    """Settings of ``imm`` (module docstring): mode filters and their Markov chain.

    ``modes`` None means (CVMode(``q``), CTMode(``q_turn``, ``turn_rate_sd``)); giving ``modes``
    together with a non-default ``q``, ``q_turn`` or ``turn_rate_sd`` is refused (they would be unused).
    """

    q: float = attrs.field(default=1.0, converter=float, validator=_v.ge(0.0))
    q_turn: float = attrs.field(default=1.0, converter=float, validator=_v.ge(0.0))
    turn_rate_sd: float = attrs.field(default=math.radians(0.5), converter=float, validator=_v.ge(0.0))
    modes: tuple[Any, ...] | None = attrs.field(default=None, converter=attrs.converters.optional(tuple))
    sojourn_s: tuple[float, ...] | None = attrs.field(default=None, converter=_floats)
    transition: tuple[tuple[float, ...], ...] | None = attrs.field(default=None, converter=_matrix)
    initial_probabilities: tuple[float, ...] | None = attrs.field(default=None, converter=_floats)
    turn_rate_entry_sd: float = attrs.field(default=math.radians(2.0), converter=float, validator=_v.ge(0.0))

    def __attrs_post_init__(self) -> None:
        if self.modes is not None:
            default = IMMConfig()
            if (self.q, self.q_turn, self.turn_rate_sd) != (default.q, default.q_turn, default.turn_rate_sd):
                raise ConfigurationError("IMMConfig: q, q_turn and turn_rate_sd set the default modes; "
                                         "with 'modes' given, set them in the modes")
            if not self.modes:
                raise ConfigurationError("IMMConfig: 'modes': at least one mode is needed")
            for m in self.modes:
                if getattr(m, "dim", None) not in (4, 5) or not callable(getattr(m, "predict", None)):
                    raise ConfigurationError(f"IMMConfig: 'modes': {m!r} is not a mode filter (dim 4 or 5, predict(x, P, dt))")
        n = len(self.mode_filters())
        if self.transition is not None:
            pi = np.asarray(self.transition)
            if pi.shape != (n, n) or not np.allclose(pi.sum(axis=1), 1.0) or np.any(pi < 0):
                raise ConfigurationError(f"IMMConfig: 'transition': expected a {n}×{n} matrix of rows summing to 1")
            if self.sojourn_s is not None:
                raise ConfigurationError("IMMConfig: give either 'transition' or 'sojourn_s', not both")
        if self.sojourn_s is not None and (len(self.sojourn_s) != n or min(self.sojourn_s) <= 0):
            raise ConfigurationError(f"IMMConfig: 'sojourn_s': expected {n} positive times, one per mode")
        mu = self.initial_probabilities
        if mu is not None and (len(mu) != n or min(mu) < 0 or sum(mu) <= 0):
            raise ConfigurationError(f"IMMConfig: 'initial_probabilities': expected {n} non-negative numbers")

    def mode_filters(self) -> tuple[Any, ...]:
        """The mode filters: ``modes``, or the default CV and CT pair."""
        if self.modes is not None:
            return self.modes
        return CVMode(self.q), CTMode(self.q_turn, self.turn_rate_sd)


class IMMFilter(TrackFilter):
    """IMM of mode filters (default constant velocity and coordinated turn), output moment matched."""

    name = "imm"
    config_class = IMMConfig

    @classmethod
    def from_modes(cls, modes: Sequence[Any], transition: Any = None, initial_probabilities: Any = None,
                   **settings: Any) -> IMMFilter:
        """An IMM of ``modes`` with a fixed Markov matrix Π (FilterPy's ``IMMEstimator(filters, mu, M)``)."""
        return cls(IMMConfig(modes=tuple(modes), transition=transition,
                             initial_probabilities=initial_probabilities, **settings))

    def __init__(self, config: IMMConfig | None = None) -> None:
        super().__init__(config)
        c = self.config
        self.modes = list(c.mode_filters())
        n = len(self.modes)
        self.dim = max(m.dim for m in self.modes)
        self.entry_sd = c.turn_rate_entry_sd
        if c.transition is not None:
            self.fixed_pi = np.asarray(c.transition, float)
            self.expG = None
            default_mu = np.full(n, 1.0 / n)
        else:
            self.fixed_pi = None
            tau = np.asarray(c.sojourn_s if c.sojourn_s is not None
                             else [120.0 if m.dim == 4 else 30.0 for m in self.modes], float)
            # G = D B, D = diag(1/τ), B = (J − n I)/(n − 1) symmetric: exp(G t) through the symmetric
            # D^½ B D^½ = U Λ Uᵀ, exp(G t) = D^½ U e^{Λt} Uᵀ D^-½ (scipy's expm costs ms per call)
            B = (np.ones((n, n)) - n * np.eye(n)) / max(n - 1, 1)
            d = np.sqrt(1.0 / tau)
            lam, U = np.linalg.eigh(d[:, None] * B * d[None, :])
            self.expG = (np.minimum(lam, 0.0), d[:, None] * U, U.T / d[None, :])
            default_mu = tau / tau.sum()
        mu0 = np.asarray(c.initial_probabilities if c.initial_probabilities is not None else default_mu, float)
        self.mu0 = mu0 / mu0.sum()
        self.time: float | None = None
        self.mu = self.mu0.copy()
        self.xs: list[np.ndarray] = []
        self.Ps: list[np.ndarray] = []
        self._combined: tuple[np.ndarray, np.ndarray] | None = None  # estimate() until the next start/update

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
        X, PP = np.array([x for x, _ in padded]), np.array([P for _, P in padded])
        out = []
        for j, mode in enumerate(self.modes):
            w = Pi[:, j] * self.mu / cbar[j] if cbar[j] > 0 else np.eye(len(self.modes))[j]
            x0, P0 = kernels.moment_match(w, X, PP)  # mixing, compiled
            d = mode.dim
            out.append(mode.predict(x0[:d], np.ascontiguousarray(P0[:d, :d]), time - self.time))
        return cbar, out

    @staticmethod
    def _combine(mu: np.ndarray, states) -> tuple[np.ndarray, np.ndarray]:
        return kernels.moment_match(np.asarray(mu, float), np.array([s[0][:4] for s in states]),
                                    np.array([s[1][:4, :4] for s in states]))

    # --- TrackFilter -----------------------------------------------------------------------------
    def start(self, time: float, z: np.ndarray, R: np.ndarray) -> None:
        self.time, z, R = check_measurement(time, z, R)
        x, P = start_state(z, R, self.config.prior_sd_velocity_mps)
        self.mu = self.mu0.copy()
        self.xs, self.Ps = [], []
        self._combined = None
        for mode in self.modes:
            xp, Pp = self._pad(x, P) if mode.dim == 5 else (x, P)
            self.xs.append(xp.copy())
            self.Ps.append(Pp.copy())

    def predict(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        time = check_time(time, self.time, self.config.max_gap_s)
        cbar, pred = self._predicted(time)
        return self._combine(cbar, pred)

    def update(self, time: float, z: np.ndarray, R: np.ndarray) -> float:
        time, z, R = check_measurement(time, z, R)
        check_time(time, self.time, self.config.max_gap_s)
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
        self._combined = None
        return nis

    def estimate(self) -> tuple[float, np.ndarray, np.ndarray]:
        require_started(self.time)
        if self._combined is None:  # read several times per input by the manager: combined once per update
            self._combined = self._combine(self.mu, list(zip(self.xs, self.Ps)))
        x, P = self._combined
        return self.time, x.copy(), P.copy()

    @property
    def probabilities(self) -> np.ndarray:
        """Current mode probabilities μ."""
        return self.mu.copy()

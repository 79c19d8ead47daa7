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

import functools
import math
from collections.abc import Sequence
from typing import Any

import attrs
import numpy as np

from radartracker.api import ConfigurationError, InputError, MotionConfig, SingularInnovation, TrackFilter
from radartracker_plugins.motion import _imm_compiled as compiled
from radartracker_plugins.motion._compiled import ct_predict, cv_predict, mixture_into, moment_match
from radartracker_plugins.motion.base import check_measurement, check_time, require_started, start_state

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
        return cv_predict(x, P, float(dt), self.q)


@attrs.frozen
class CTMode:
    """IMM mode filter: coordinated turn with unknown rate (EKF on [x, y, vx, vy, ω],
    :mod:`radartracker_plugins.motion.ct`), densities ``q`` (m²/s³) and ``turn_rate_sd`` (rad/s/√s)."""

    q: float = attrs.field(default=1.0, converter=float, validator=_v.ge(0.0))
    turn_rate_sd: float = attrs.field(default=math.radians(0.5), converter=float, validator=_v.ge(0.0))
    dim = 5

    def predict(self, x: np.ndarray, P: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        return ct_predict(x, P, float(dt), self.q, self.turn_rate_sd)


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
    """IMM of mode filters (default constant velocity and coordinated turn), output moment matched.

    Mode states are held padded to the largest mode's size (``X`` n×D, ``PP`` n×D×D; a 4-state mode
    carries ω = 0 ± σ_e in the fifth place), in the state block of the filter's work array of
    :mod:`radartracker_plugins.motion._imm_compiled` (``mu``, ``X``, ``PP`` and the output ``x``, ``P``
    are views of it; the prediction and the scratch of a cycle live beside it, so that a compiled call
    takes the filter as one array and allocates nothing). The default modes (:class:`CVMode`, :class:`CTMode`) are predicted in the
    compiled ``advance``; other mode filters are called through their ``predict``. A prediction is
    kept until the state changes, so the update at the time innovation screening just predicted to
    reuses it, and the output (χ̂, P̂) is combined once per update.
    """

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
        try:  # the same for every filter of a config: made once (a national replay starts thousands of tracks)
            settings = _settings(self.config)
        except TypeError:  # a setting that cannot be hashed (a user's mode filter): made for this filter
            settings = _settings.__wrapped__(self.config)
        modes, self.dims, self.entry_var, self._settings, self.mu0, self._compiled = settings
        self.modes = list(modes)
        n, self.dim = len(modes), int(max(self.dims))
        self._work = np.zeros(compiled.work_shape(n, self.dim))  # the state, the prediction and the scratch
        # the kernels' own layout functions, run as plain numpy slicing (their py_func): views made in Python
        # without numba boxing each one
        blocks, scratch = compiled.block_views.py_func, compiled.scratch_views.py_func
        self.mu, self.X, self.PP, self.x, self.P = blocks(self._work, n, self.dim, compiled.STATE)
        self._pred = blocks(self._work, n, self.dim, compiled.PREDICTION)  # (c̄, X̄, P̄, χ̄, P̄)
        _, _, self._zc, self._Rc, _, self._X0, _, _, self._P0, _ = scratch(self._work, n, self.dim)
        self.mu[:] = self.mu0
        self.time: float | None = None
        self._pred_time = math.nan  # the time _pred is the prediction for (nan: none)

    # --- IMM cycle -----------------------------------------------------------------------------
    def switching(self, dt: float) -> np.ndarray:
        """Π(Δt): the fixed matrix, or exp(G |Δt|)."""
        return compiled.markov_switching(self._settings, float(dt))

    def _predicted(self, time: float) -> tuple[np.ndarray, ...]:
        """(c̄, X̄, P̄, χ̄, P̄): each mode's prediction from its mixed initial condition, and the
        predicted mixture; computed once per state and time."""
        if self._pred_time != time:
            dt = time - self.time
            if self._compiled:
                compiled.advance(self._settings, self._work, dt)
            else:
                self._predict_modes_in_python(dt)
            self._pred_time = time
        return self._pred

    def _predict_modes_in_python(self, dt: float) -> None:
        """The prediction of :func:`compiled.advance` with each mode's own ``predict``."""
        cbar, Xp, PPp, x_bar, P_bar = self._pred
        compiled.mix(self._settings, self._work, dt)  # c̄ into the prediction, (X⁰, P⁰) into the scratch
        Xp[:], PPp[:] = 0.0, 0.0
        for j, (mode, d) in enumerate(zip(self.modes, self.dims)):
            Xp[j, :d], PPp[j, :d, :d] = mode.predict(self._X0[j, :d].copy(), self._P0[j, :d, :d].copy(), dt)
        mixture_into(cbar, Xp, PPp, 4, x_bar, P_bar)

    # --- TrackFilter -----------------------------------------------------------------------------
    def start(self, time: float, z: np.ndarray, R: np.ndarray) -> None:
        time, z, R = check_measurement(time, z, R)
        x, P = start_state(z, R, self.config.prior_sd_velocity_mps)
        self.X[:], self.PP[:] = 0.0, 0.0
        self.X[:, :4], self.PP[:, :4, :4] = x, P
        if self.dim == 5:  # the turn rate is unknown: ω = 0 ± σ_e in every mode
            self.PP[:, 4, 4] = self.entry_var
        self.mu[:] = self.mu0
        mixture_into(self.mu, self.X, self.PP, 4, self.x, self.P)
        self.time, self._pred_time = time, math.nan

    def _checked_time(self, time: float) -> float:
        """``time`` as :func:`check_time` accepts it (within ``max_gap_s`` of the started filter's epoch)."""
        if self.time is not None and abs(time - self.time) <= self.config.max_gap_s:
            return float(time)
        return check_time(time, self.time, self.config.max_gap_s)

    def predict(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        x_bar, P_bar = self._predicted(self._checked_time(time))[3:]
        return x_bar.copy(), P_bar.copy()

    def screen(self, time: float, z: np.ndarray, C: np.ndarray, R: np.ndarray, bias: np.ndarray,
               bias_cov: np.ndarray, gate: float | None = None) -> tuple[float, np.ndarray, np.ndarray, bool]:
        """:meth:`TrackFilter.screen` in one compiled call (:func:`_imm_compiled.screen`: bias correction,
        the prediction to ``time`` unless kept, d² and the correction when it passes ``gate``); a
        prediction not used is kept for the update at ``time``. Modes called in Python predict first.
        z_c and R_c are written into the filter's scratch and returned as copies (the caller keeps them)
        unless the filter was updated with them."""
        time = self._checked_time(time)
        if self._compiled and self._pred_time != time:
            dt = time - self.time
        else:  # the kept prediction, or the modes' own
            dt = math.nan
            self._predicted(time)
        d2, nis, code = compiled.screen(self._settings, self._work, dt, z, C, R, bias, bias_cov,
                                        -1.0 if gate is None else gate)
        if code == -2:  # updated: z_c and R_c are of no further use
            self.time, self._pred_time = time, math.nan
            return d2, None, None, True
        self._pred_time = time
        zc, Rc = self._zc.copy(), self._Rc.copy()
        if code == -4:
            return d2, zc, Rc, False
        if code == -3:  # a measurement the compiled checks refused: the update raises with the messages
            self.update(time, zc, Rc)
        self._raise_singular(code, Rc)

    def update(self, time: float, z: np.ndarray, R: np.ndarray) -> float:
        """Predict to ``time`` (or take the kept prediction), correct with z; SingularInnovation, the
        state unchanged, when an innovation covariance is not positive definite."""
        time, z, R = check_measurement(time, z, R)
        time = self._checked_time(time)
        self._predicted(time)
        nis, code = compiled.correct(self._settings, self._work, z, R)
        if code != -2:
            self._raise_singular(code, R)
        self.time, self._pred_time = time, math.nan
        return float(nis)

    def _raise_singular(self, code: int, R: np.ndarray) -> None:
        """SingularInnovation for :func:`_imm_compiled.correct`'s ``code``: the predicted mixture's (−1) or
        mode ``code``'s innovation covariance, of the prediction kept in ``_pred``."""
        P_bad = self._pred[4] if code == -1 else self._pred[2][code]
        raise SingularInnovation(f"innovation covariance not positive definite: {(P_bad[:2, :2] + R).tolist()}")

    def estimate(self) -> tuple[float, np.ndarray, np.ndarray]:
        require_started(self.time)
        return self.time, self.x.copy(), self.P.copy()

    @property
    def probabilities(self) -> np.ndarray:
        """Current mode probabilities μ."""
        return self.mu.copy()

    # --- snapshots and pickles: the configuration and the state, not the blocks derived from it -------
    def __getstate__(self) -> dict:
        return {"config": self.config, "state": self.state_dict()}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["config"])
        self.load_state_dict(state["state"])

    def state_dict(self) -> dict:
        """``time``, ``mu`` and each mode's own ``xs``/``Ps`` (without the padding)."""
        return {"time": self.time, "mu": self.mu.copy(),
                "xs": [self.X[j, :d].copy() for j, d in enumerate(self.dims)],
                "Ps": [self.PP[j, :d, :d].copy() for j, d in enumerate(self.dims)]}

    def load_state_dict(self, state: dict) -> None:
        """Take back :meth:`state_dict` (other keys, which older versions saved, are derived from the
        configuration and ignored)."""
        n = len(self.modes)
        X, PP = np.zeros((n, self.dim)), np.zeros((n, self.dim, self.dim))
        time, mu = None, self.mu0.copy()
        if state.get("time") is not None:
            try:
                time, mu, xs, Ps = float(state["time"]), np.array(state["mu"], float), state["xs"], state["Ps"]
                if mu.shape != (n,) or len(xs) != n or len(Ps) != n:
                    raise ValueError(f"expected {n} modes")
                for j, d in enumerate(self.dims):
                    X[j, :d], PP[j, :d, :d] = xs[j], Ps[j]
                    if d < self.dim:
                        PP[j, 4, 4] = self.entry_var
            except (KeyError, TypeError, ValueError) as exc:
                raise InputError(f"IMMFilter: state does not fit this configuration: {exc}") from None
        self.time, self.mu[:], self.X[:], self.PP[:] = time, mu, X, PP
        self.x[:], self.P[:] = moment_match(mu, X, PP, 4) if time is not None else (0.0, 0.0)
        self._pred_time = math.nan


def _chain(c: IMMConfig, modes: tuple[Any, ...]) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
    """The Markov chain (λ, L, R) of :func:`compiled.switching_into` and the default μ₀: a fixed Π
    (an empty λ, L = Π) with uniform μ₀, or the sojourn-time chain with μ₀ ∝ τ (its stationary law)."""
    n = len(modes)
    if c.transition is not None:
        return (np.zeros(0), np.asarray(c.transition, float), np.zeros((0, 0))), np.full(n, 1.0 / n)
    default_tau = [120.0 if m.dim == 4 else 30.0 for m in modes]
    tau = np.asarray(c.sojourn_s if c.sojourn_s is not None else default_tau, float)
    # G = D B, D = diag(1/τ), B = (J − n I)/(n − 1) symmetric: exp(G t) through the symmetric
    # D^½ B D^½ = U Λ Uᵀ, exp(G t) = D^½ U e^{Λt} Uᵀ D^-½ (scipy's expm costs ms per call)
    B = (np.ones((n, n)) - n * np.eye(n)) / max(n - 1, 1)
    d = np.sqrt(1.0 / tau)
    lam, U = np.linalg.eigh(d[:, None] * B * d[None, :])
    return (np.minimum(lam, 0.0), d[:, None] * U, U.T / d[None, :]), tau / tau.sum()


@functools.lru_cache(maxsize=32)
def _settings(c: IMMConfig) -> tuple:
    """What a filter of ``c`` derives from its settings alone: (mode filters, their dimensions, σ_e², the
    settings array of :mod:`radartracker_plugins.motion._imm_compiled`, μ₀, whether every mode is
    built in (predicted in the compiled step)). Shared by the filters of one config: nothing writes
    into these arrays."""
    modes = tuple(c.mode_filters())
    dims = np.array([m.dim for m in modes], np.int64)
    builtin = all(type(m) in (CVMode, CTMode) for m in modes)
    rows = (np.array([[compiled.CV if type(m) is CVMode else compiled.CT, m.q, getattr(m, "turn_rate_sd", 0.0)]
                      for m in modes]) if builtin else np.tile([compiled.PYTHON, 0.0, 0.0], (len(modes), 1)))
    chain, default_mu = _chain(c, modes)
    mu0 = np.asarray(c.initial_probabilities if c.initial_probabilities is not None else default_mu, float)
    entry_var = c.turn_rate_entry_sd**2
    return modes, dims, entry_var, compiled.settings_array(rows, dims, entry_var, *chain), mu0 / mu0.sum(), builtin

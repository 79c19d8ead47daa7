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
from operator import attrgetter
from typing import Any

import attrs
import numpy as np

from radartracker.api import ConfigurationError, InputError, MotionConfig, SingularInnovation, TrackFilter, kernels
from radartracker_plugins.motion.base import check_measurement, check_time, require_started, start_state

_v = attrs.validators
_ADDRESS = attrgetter("_address")
_EPOCH, _PREDICTED = kernels.IMM_EPOCH, kernels.IMM_PREDICTED


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
    """IMM of mode filters (default constant velocity and coordinated turn), output moment matched.

    Mode states are held padded to the largest mode's size (``X`` n×D, ``PP`` n×D×D; a 4-state mode
    carries ω = 0 ± σ_e in the fifth place). The default modes (:class:`CVMode`, :class:`CTMode`) run
    the whole cycle in compiled kernels (:func:`radartracker.api.kernels.imm_predict`,
    ``imm_correct``, ``imm_cycle``); other mode filters are called through their ``predict``. A
    prediction is kept until the state changes, so the update at the time innovation screening just
    predicted to reuses it, and the output (χ̂, P̂) is combined once per update.
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
        modes, self.dims, self.entry_var, self.kernel_modes, self.chain, self.mu0, template = settings
        self.modes = list(modes)
        self.dim = int(max(self.dims))
        self.mu = self.mu0.copy()
        self.X = np.zeros((len(modes), self.dim))  # mode states, padded (class docstring)
        self.PP = np.zeros((len(modes), self.dim, self.dim))
        self.x, self.P = np.zeros(4), np.zeros((4, 4))  # output (χ̂, P̂) of the current state
        self._scratch(template)

    def _scratch(self, template: np.ndarray | None = None) -> None:
        """The state (μ, X, PP, χ̂, P̂) moved into one buffer with the settings the packed kernels take
        (a copy of ``template``, a buffer of the same settings, if given), not started, the prediction from
        it to time ``_pred_time`` (none yet), ``_pred`` = (c̄, X̄, P̄ of the modes, χ̄, P̄), and their scratch
        (:func:`radartracker.api.kernels.imm_buffer`)."""
        self._compiled = self.kernel_modes is not None  # else the modes' rows in the buffer are unused
        self._buf = template.copy() if template is not None else _buffer(
            self.kernel_modes, self.dims, self.entry_var, self.chain, self.config.max_gap_s)
        state, self._pred = kernels.imm_views(self._buf)
        for view, value in zip(state, (self.mu, self.X, self.PP, self.x, self.P)):
            view[...] = value
        self.mu, self.X, self.PP, self.x, self.P = state
        self._max_gap = self.config.max_gap_s
        self._address = self._buf.ctypes.data  # the buffer's memory, for screen_many's compiled loop

    # --- the epoch and the kept prediction's time, held in the buffer (screen_many's compiled loop moves them)
    @property
    def time(self) -> float | None:
        """Time (s) of the current estimate; None before :meth:`start`."""
        t = self._buf[_EPOCH]
        return None if t != t else float(t)

    @time.setter
    def time(self, value: float | None) -> None:
        self._buf[_EPOCH] = math.nan if value is None else value

    @property
    def _pred_time(self) -> float:
        """The time ``_pred`` is the prediction for (nan: none)."""
        return float(self._buf[_PREDICTED])

    @_pred_time.setter
    def _pred_time(self, value: float) -> None:
        self._buf[_PREDICTED] = value

    # --- IMM cycle -----------------------------------------------------------------------------
    def switching(self, dt: float) -> np.ndarray:
        """Π(Δt): the fixed matrix, or exp(G |Δt|)."""
        return kernels.markov_switching(*self.chain, float(dt))

    def _predicted(self, time: float) -> tuple[np.ndarray, ...]:
        """(c̄, X̄, P̄, χ̄, P̄): each mode's prediction from its mixed initial condition, and the
        predicted mixture; computed once per state and time."""
        if self._pred_time != time:
            dt = time - self.time
            if self._compiled:
                kernels.imm_advance(self._buf, dt)
            else:
                cbar, Xp, PPp, x_bar, P_bar = self._pred
                cbar[:], X0, P0 = kernels.imm_mix(self.mu, self.X, self.PP, self.switching(dt))
                Xp[:], PPp[:] = 0.0, 0.0
                for j, (mode, d) in enumerate(zip(self.modes, self.dims)):
                    Xp[j, :d], PPp[j, :d, :d] = mode.predict(X0[j, :d].copy(), P0[j, :d, :d].copy(), dt)
                x_bar[:], P_bar[:] = kernels.imm_combine(cbar, Xp, PPp)
            self._pred_time = time
        return self._pred

    # --- TrackFilter -----------------------------------------------------------------------------
    def start(self, time: float, z: np.ndarray, R: np.ndarray) -> None:
        time, z, R = check_measurement(time, z, R)
        x, P = start_state(z, R, self.config.prior_sd_velocity_mps)
        self.X[:], self.PP[:] = 0.0, 0.0
        self.X[:, :4], self.PP[:, :4, :4] = x, P
        if self.dim == 5:  # the turn rate is unknown: ω = 0 ± σ_e in every mode
            self.PP[:, 4, 4] = self.entry_var
        self.mu[:] = self.mu0
        self.x[:], self.P[:] = kernels.imm_combine(self.mu, self.X, self.PP)
        self.time, self._pred_time = time, math.nan

    def _within_gap(self, time: float) -> bool:
        """Whether the filter has started and ``time`` is within ``max_gap_s`` of its epoch (False for a
        nan or infinite time): the common case of :func:`check_time`, tested before calling it."""
        return self.time is not None and abs(time - self.time) <= self._max_gap

    def _checked_time(self, time: float) -> float:
        """``time`` as :func:`check_time` accepts it."""
        return float(time) if self._within_gap(time) else check_time(time, self.time, self._max_gap)

    def predict(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        x_bar, P_bar = self._predicted(self._checked_time(time))[3:]
        return x_bar.copy(), P_bar.copy()

    def screen(self, time: float, z: np.ndarray, C: np.ndarray, R: np.ndarray, bias: np.ndarray,
               bias_cov: np.ndarray, gate: float | None = None) -> tuple[float, np.ndarray, np.ndarray, bool]:
        """:meth:`TrackFilter.screen` in one compiled call (bias correction, prediction, d² and the update
        when it passes ``gate``); a prediction not used is kept for the update at ``time``."""
        t0 = self.time
        if t0 is None or not self._compiled:
            return super().screen(time, z, C, R, bias, bias_cov, gate)
        time = float(time)  # as check_time; the kernel checks the step against max_gap_s (_within_gap's rule)
        zc, Rc = np.empty(2), np.empty((2, 2))
        d2, nis, bad = kernels.imm_screen(self._buf, time - t0, self._pred_time == time, z, C, R, bias, bias_cov,
                                          zc, Rc, -1.0 if gate is None else gate)
        if bad == -2:  # updated (the common case of _corrected)
            self.time, self._pred_time = time, math.nan
            return d2, zc, Rc, True
        if bad == -5:  # a step the kernel refused: the default raises with check_time's message
            return super().screen(time, z, C, R, bias, bias_cov, gate)
        self._pred_time = time
        if bad == -4:
            return d2, zc, Rc, False
        if bad == -3:  # a measurement the kernel's checks refused: the update with its messages
            self.update(time, zc, Rc)
        else:
            self._corrected(time, nis, bad, Rc)
        return d2, zc, Rc, True

    @classmethod
    def screen_many(cls, filters: Sequence[IMMFilter], times: np.ndarray, z: np.ndarray, C: np.ndarray,
                    R: np.ndarray, bias: np.ndarray, bias_cov: np.ndarray, gate: np.ndarray) -> tuple:
        """:meth:`TrackFilter.screen_many` in one compiled call (:func:`radartracker.api.kernels.imm_screen_many`
        over the filters' packed buffers); filters of other modes or not started are left to ``screen``."""
        if cls.screen is not IMMFilter.screen:  # a subclass screening its own way
            return super().screen_many(filters, times, z, C, R, bias, bias_cov, gate)
        n = len(filters)
        d2, zc, Rc = np.full(n, math.nan), np.zeros((n, 2)), np.zeros((n, 2, 2))
        x, P, done = np.zeros((n, 4)), np.zeros((n, 4, 4)), np.zeros(n, bool)
        if n:  # the epochs, kept predictions and whether compiled are read (and moved) in the buffers
            kernels.imm_screen_many(np.fromiter(map(_ADDRESS, filters), np.int64, n),
                                    np.ascontiguousarray(times, float), z, C, R, bias, bias_cov,
                                    np.ascontiguousarray(gate, float), d2, zc, Rc, x, P, done)
        return d2, zc, Rc, done, x, P

    def update(self, time: float, z: np.ndarray, R: np.ndarray) -> float:
        t0, bad = self.time, -3
        if (self._compiled and self._within_gap(time) and type(z) is np.ndarray
                and type(R) is np.ndarray and z.ndim == 1 and R.ndim == 2):  # the checks in the kernel
            time = float(time)
            nis, bad = kernels.imm_update(self._buf, time - t0, self._pred_time == time, np.asarray(z, float),
                                          np.asarray(R, float))
        if bad == -3:  # any other input, or one the kernel refused: the checks with their messages
            time, z, R = check_measurement(time, z, R)
            check_time(time, t0, self._max_gap)
            if self._compiled and self._pred_time != time:
                nis, bad = kernels.imm_cycle(self.mu, self.X, self.PP, *self.chain, self.kernel_modes, self.dims,
                                             self.entry_var, time - t0, z, R, self.x, self.P, *self._pred)
            else:  # from the prediction innovation screening asked for at this time
                nis, bad = kernels.imm_correct(*self._predicted(time), self.dims, self.entry_var, z, R,
                                               self.mu, self.X, self.PP, self.x, self.P)
        return self._corrected(time, nis, bad, R)

    def _corrected(self, time: float, nis: float, bad: int, R: np.ndarray) -> float:
        """After a correction at ``time`` (code ``bad`` of :func:`~radartracker.api.kernels.imm_correct`):
        the new epoch and the NIS, or SingularInnovation with the state unchanged."""
        if bad != -2:  # the state is unchanged; the prediction in _pred is the one that failed
            P_bad = self._pred[4] if bad == -1 else self._pred[2][bad, :2, :2]
            self._pred_time = time
            raise SingularInnovation(f"innovation covariance not positive definite: {(P_bad[:2, :2] + R).tolist()}")
        self.time, self._pred_time = time, math.nan
        return float(nis)

    def estimate(self) -> tuple[float, np.ndarray, np.ndarray]:
        if self.time is None:
            require_started(self.time)
        return self.time, self.x.copy(), self.P.copy()

    @property
    def probabilities(self) -> np.ndarray:
        """Current mode probabilities μ."""
        return self.mu.copy()

    # --- snapshots and pickles: the state, not the buffers derived from it -------------------------
    def __getstate__(self) -> dict:
        skip = ("_buf", "_pred", "_compiled", "_max_gap", "_address")
        return {**{k: v for k, v in vars(self).items() if k not in skip}, "time": self.time}

    def __setstate__(self, state: dict) -> None:
        vars(self).update((k, v) for k, v in state.items() if k != "time")
        self._scratch()
        self.time = state.get("time")

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
        self.x[:], self.P[:] = kernels.imm_combine(mu, X, PP) if time is not None else (0.0, 0.0)
        self._pred_time = math.nan


def _buffer(kernel_modes: np.ndarray | None, dims: np.ndarray, entry_var: float, chain: tuple, max_gap: float) -> np.ndarray:
    """The packed buffer of these settings with a zero state (:func:`radartracker.api.kernels.imm_buffer`)."""
    rows = kernel_modes if kernel_modes is not None else np.zeros((len(dims), 3))
    return kernels.imm_buffer(rows, dims, entry_var, *chain, max_gap, kernel_modes is not None)


@functools.lru_cache(maxsize=32)
def _settings(c: IMMConfig) -> tuple:
    """What a filter of ``c`` derives from its settings alone: (mode filters, their dimensions, σ_e², the
    compiled modes' rows (kind, q, turn-rate σ) or None when some mode is called in Python, the Markov
    chain (λ, L, R) of :func:`radartracker.api.kernels.markov_switching`, μ₀, a packed buffer with these
    settings and a zero state). Shared by the filters of one config: nothing writes into these arrays."""
    modes = tuple(c.mode_filters())
    n = len(modes)
    dims = np.array([m.dim for m in modes], np.int64)
    builtin = all(type(m) in (CVMode, CTMode) for m in modes)
    kernel_modes = (np.array([[0.0 if type(m) is CVMode else 1.0, m.q, getattr(m, "turn_rate_sd", 0.0)]
                              for m in modes]) if builtin else None)
    if c.transition is not None:  # kernels.markov_switching: an empty λ means the fixed Π
        chain = (np.zeros(0), np.asarray(c.transition, float), np.zeros((0, 0)))
        default_mu = np.full(n, 1.0 / n)
    else:
        tau = np.asarray(c.sojourn_s if c.sojourn_s is not None else [120.0 if m.dim == 4 else 30.0 for m in modes], float)
        # G = D B, D = diag(1/τ), B = (J − n I)/(n − 1) symmetric: exp(G t) through the symmetric
        # D^½ B D^½ = U Λ Uᵀ, exp(G t) = D^½ U e^{Λt} Uᵀ D^-½ (scipy's expm costs ms per call)
        B = (np.ones((n, n)) - n * np.eye(n)) / max(n - 1, 1)
        d = np.sqrt(1.0 / tau)
        lam, U = np.linalg.eigh(d[:, None] * B * d[None, :])
        chain = (np.minimum(lam, 0.0), np.ascontiguousarray(d[:, None] * U), np.ascontiguousarray(U.T / d[None, :]))
        default_mu = tau / tau.sum()
    mu0 = np.asarray(c.initial_probabilities if c.initial_probabilities is not None else default_mu, float)
    entry_var = c.turn_rate_entry_sd**2
    return modes, dims, entry_var, kernel_modes, chain, mu0 / mu0.sum(), _buffer(kernel_modes, dims, entry_var, chain, c.max_gap_s)

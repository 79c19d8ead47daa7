"""Exact coupled estimator in sparse information form (DESIGN §5 item 2): cost per plot independent of n.

The joint state ξ = [χ_1..χ_n, ς_1..ς_m] of the dense ``coupled`` filter (seed 000 §1.2.1) is kept as
its information Y = P⁻¹, η = Y ξ̂. Radar j's bias ς_j is its sensor model's m_j components
(``EstimatorConfig.sensor``: the range and azimuth offsets, and a range gain and a time offset where
configured; 2 ≤ m_j ≤ 4, M = Σ m_j). Aircraft are coupled only through the biases, so Y is an
*arrowhead*: blocks Y_ii (4×4), Y_ib (4×m_b, only for the radars b that observed aircraft i), Y_bb
(M×M); Y_ik = 0 for two aircraft i ≠ k. Equivalently, given the biases the aircraft are
independent::

    χ_i | ς  ~  N(m_i − G_i ς_K,  Y_ii⁻¹),   G_i = Y_ii⁻¹ Y_ib,   m_i = Y_ii⁻¹ η_i          (1)
    ς        ~  N(S⁻¹ s,  S⁻¹),   S = Y_bb − Σ_i Y_bi Y_ii⁻¹ Y_ib,   s = η_b − Σ_i Y_bi Y_ii⁻¹ η_i   (2)

**Measurement** z = C_x χ_i + C_s ς_j + v, v ~ N(0, R), with C_s = B the sensor model's 2×m_j Jacobian
at the plot (columns c_ρ, c_θ, ρ c_ρ, −v̄) and C_x = [I, −τ̄ I] (module ``_measurement``: the time offset
linearised at the predicted velocity v̄ and offset τ̄ with the second-order terms, exactly the dense
filter's step, as the linear update of z − d with noise R_eff; without a time offset C_x = [I, 0],
d = 0, R_eff = R): Y += Hᵀ R_eff⁻¹ H, η += Hᵀ R_eff⁻¹ (z − d) with H = [C_x at i, C_s at j]
— it touches Y_ii, Y_ij, Y_jj only, so the pattern is kept. S changes by ΔY_jj minus the change of
aircraft i's term Y_bi Y_ii⁻¹ Y_ib, which in closed form (eliminate χ_i with (1)) is the PSD rank-2
term H_bᵀ Ω⁻¹ H_b with H_b = C_s E_j − C_x G_i, Ω = R + C_x Y_ii⁻¹ C_xᵀ (s: H_bᵀ Ω⁻¹ (z − C_x m_i)):
O(K²) with K the bias entries of the radars that saw aircraft i; S only grows between its recomputations.
The moments the linearisation needs (v̄, P_vv, P_vτ, P_ττ) come from the same conditional, O(K²).

**Prediction** of aircraft i alone, χ_i' = A χ_i + w, w ~ N(0, Q): by (1), χ_i' | ς ~
N(A m_i − A G_i ς_K, A Y_ii⁻¹ Aᵀ + Q), still independent of the other aircraft given ς, and the
marginal of everything else is untouched. Hence, in information form::

    Y_ii' = (A Y_ii⁻¹ Aᵀ + Q)⁻¹,   Y_ib' = Y_ii' A G_i,   η_i' = Y_ii' A m_i,
    Y_bb' = Y_bb − Y_bi Y_ii⁻¹ Y_ib + Y_bi' Y_ii'⁻¹ Y_ib' = Y_bb − G_iᵀ (Y_ii − Aᵀ Y_ii' A) G_i,
    η_b' = η_b − G_iᵀ (Y_ii − Aᵀ Y_ii' A) m_i,   S' = S, s' = s

— the arrowhead is kept with or without process noise. With Q = 0 this is Y_ii' = A⁻ᵀ Y_ii A⁻¹,
Y_ib' = A⁻ᵀ Y_ib, η_i' = A⁻ᵀ η_i and Y_bb' = Y_bb.

**Creation** adds Y_ii = P₀⁻¹, η_i = Y_ii χ₀ with no bias block (S unchanged); **deletion**
marginalises: Y_bb −= Y_bi Y_ii⁻¹ Y_ib, η_b −= Y_bi Y_ii⁻¹ η_i (S unchanged), so what the aircraft
taught about the biases is kept — both O(k²).

**Reads** without the dense matrix: the bias covariance S⁻¹; aircraft i's estimate m_i − G_i ς̂_K and
marginal covariance Y_ii⁻¹ + G_i S⁻¹_KK G_iᵀ; cross-covariances G_i S⁻¹_KL G_lᵀ and −G_i S⁻¹_K·.
The plot's innovation needs the same quantities. To avoid an O(M³) solve per plot, S⁻¹ and ς̂ are
also kept in covariance form by the rank-2 Kalman update of the bias marginal
(S⁻¹ −= K_b Λ⁻¹ K_bᵀ, ς̂ += K_b Λ⁻¹ ν, K_b = Cov(ς, h)), O(M²) per plot, and reset from S every
``refresh_every`` updates; S itself is recomputed from the blocks by (2) every ``rebuild_factor``
× (n + 1) updates (amortised O(k²) per plot) to bound round-off.

**Numerical hygiene.** Every block update is symmetric by construction (Gram products such as VᵀV
with V = L⁻¹Y_ib, L Lᵀ = Y_ii, or one triangle computed and mirrored). Positive definiteness is checked by a Cholesky factorisation of R, Y_ii
(at every prediction, update and read), Λ (every plot) and S (every refresh); a failure raises
:class:`SingularInformation` (a :class:`~radartracker.kalman.SingularInnovation`, hence a
ValueError) naming the aircraft, radar and time — never a NaN. Non-finite input raises ValueError.
The information form needs R ≻ 0, a proper aircraft prior (P₀ ≻ 0) and every bias component's prior
σ > 0 (a radar with a zero one is refused).

**Bias drift is refused.** A random walk on ς adds noise to the biases after aircraft have been
conditioned on the old values: given the new biases the aircraft are no longer independent (two
aircraft seen by one radar keep their correlation through the old bias), so Y_xx fills in and the
exact filter cannot stay sparse. A config with ``bias_drifts`` raises ValueError; use ``coupled``.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

import attrs
import numpy as np

from radartracker.api import (AircraftEstimate, BiasState, ConfigurationError, Estimator, EstimatorConfig, Innovation,
                              MotionModel, PlaneMeasurement, SensorModel, SingularInnovation, require_new_radar,
                              validated_prior)

from . import _kernels as K
from ._layout import (C_ALIVE, C_REBUILD_FACTOR, C_REFRESH_EVERY, ERR_LAMBDA, ERR_NONFINITE, ERR_R, ERR_REBUILD,
                      ERR_S, ERR_YII, OK, STORE, allocate, carve, carve_work)
from ._linalg import chol
from ._refresh import rebuild as _rebuild
from ._refresh import refresh
from ._state import checked_state


class SingularInformation(SingularInnovation):
    """A block of the information form (R, Y_ii, Λ or S) is not positive definite."""


_WHY = {
    ERR_NONFINITE: "non-finite time, z, C or R (or slant range ρ of a radar with a range gain)",
    ERR_R: "measurement noise covariance R is not positive definite (the information form needs R⁻¹)",
    ERR_YII: "aircraft information block Y_ii is not positive definite",
    ERR_LAMBDA: "innovation covariance Λ is not positive definite",
    ERR_S: "bias Schur complement S is not positive definite",
    ERR_REBUILD: "recomputing S from the blocks met an aircraft block Y_ii that is not positive definite",
}


@attrs.frozen
class CoupledSparseConfig:
    """Options of ``coupled-sparse`` (round-off control, module docstring): ``refresh_every`` updates
    between resets of S⁻¹, ς̂ from S; S is recomputed from the blocks every ``rebuild_factor`` × (n + 1)
    updates."""

    refresh_every: int = attrs.field(default=256, converter=int, validator=attrs.validators.ge(1))
    rebuild_factor: int = attrs.field(default=64, converter=int, validator=attrs.validators.ge(1))


class CoupledSparseEstimator(Estimator):
    """Dense ``coupled`` filter's estimates from a sparse arrowhead information matrix (module docstring).

    Options: :class:`CoupledSparseConfig` (``refresh_every=`` and ``rebuild_factor=`` keywords set them too).
    """

    name = "coupled-sparse"
    options_class = CoupledSparseConfig

    def __init__(self, config: EstimatorConfig | None = None, options: CoupledSparseConfig | None = None,
                 **option_values: int) -> None:
        super().__init__(config, options if options is not None or not option_values
                         else CoupledSparseConfig(**option_values))
        refresh_every, rebuild_factor = self.options.refresh_every, self.options.rebuild_factor
        if self.config.bias_drifts:
            raise ValueError("coupled-sparse: drifting biases make the information matrix dense "
                             "(see the module docstring); use the 'coupled' estimator")
        if type(self.config.motion) is not MotionModel:
            raise ValueError("coupled-sparse supports the constant-velocity MotionModel only")
        self._q = float(self.config.motion.q)
        self._rad: dict[str, int] = {}
        self._models: list[SensorModel] = []  # by radar index: each radar's sensor model (its bias block)
        self._radar_codes: dict[str | None, int] = {None: -1}  # radar → its index in the kernels, None → −1
        self._ac: dict[Hashable, int] = {}  # key -> slot
        self._free: list[int] = []
        self._bias_time = float("nan")  # latest update time, as coupled's global bias epoch
        self._alloc(0)
        self._ctr[:] = 0, refresh_every, 0, rebuild_factor, 0

    # --- storage -----------------------------------------------------------------------------
    def _alloc(self, cap: int) -> None:
        """(Re)allocate for ``cap`` aircraft slots and the radars of ``_models``, keeping the contents: every array a
        view into one float and one int buffer (``_F``, ``_I``; layout ``_layout.carve``), the scratch into ``_WF``."""
        F, I, WF = allocate(cap, self._models, self._q)
        st = carve(F, I)
        for name, dst in zip(STORE, st):
            src = getattr(self, "_" + name, None)
            if src is not None:  # what is kept: the old extent of each array (a new radar's block comes last)
                dst[tuple(slice(0, n) for n in src.shape)] = src
            setattr(self, "_" + name, dst)
        self._F, self._I, self._WF = F, I, WF
        self._st, self._wk = st, carve_work(WF, max(self._Pb.shape[0], 1))
        # by radar index, then False for −1 (unbiased): whether its plots need their slant range
        self._has_gain = np.array(["range_gain" in model.names for model in self._models] + [False])
        # read-only views of each radar's block of ς̂ and P_ς, by radar index (bias_views)
        self._bias_views = [(self._bh[b], self._Pb[b, b]) for b in map(self._block, range(len(self._models)))]
        for v in self._bias_views:
            v[0].flags.writeable = v[1].flags.writeable = False

    def _block(self, j: int) -> slice:
        """Radar index j's entries in the bias vector (its sensor model's size, after the radars before it)."""
        start = sum(model.size for model in self._models[:j])
        return slice(start, start + self._models[j].size)

    def state_dict(self) -> dict:
        """Radars, aircraft slots, free slots, the bias epoch and the stored arrays (module ``_state``)."""
        return {"radars": list(self._rad), "aircraft": dict(self._ac), "free": list(self._free),
                "bias_time": self._bias_time, **{name: getattr(self, "_" + name).copy() for name in STORE}}

    def load_state_dict(self, state: dict) -> None:
        """Take back a :meth:`state_dict`, every field checked against the others first (``_state``)."""
        checked = checked_state(state, list(self._rad), [model.size for model in self._models],
                                self._ctr[C_REFRESH_EVERY], self._ctr[C_REBUILD_FACTOR])
        for name in STORE:  # the checked arrays, then packed into new storage of their size
            setattr(self, "_" + name, checked[name])
        self._ac, self._free, self._bias_time = checked["aircraft"], checked["free"], checked["bias_time"]
        self._alloc(len(checked["tx"]))

    def __setstate__(self, state: dict) -> None:
        """copy.deepcopy: the copied arrays no longer share one buffer; pack them again."""
        self.__dict__.update(state)
        self._alloc(self._Yxx.shape[0])

    def add_radar(self, radar: str) -> None:
        """Radar ``radar`` with its sensor model (``EstimatorConfig.sensor``): its block of the bias vector,
        after the other radars', starts at its prior information P₀⁻¹ (every prior σ must be positive)."""
        require_new_radar(radar, self._rad)
        model = self.config.sensor(radar)
        if any(c.prior_sd <= 0.0 for c in model.components):
            raise ConfigurationError(f"coupled-sparse: radar {radar!r} has a bias component with prior σ 0 (the "
                                     "information form needs the prior's inverse); use 'coupled'")
        j = len(self._rad)
        self._models.append(model)
        self._alloc(self._Yxx.shape[0])
        b = self._block(j)
        P0 = model.prior()
        Y0 = np.linalg.inv(P0)
        self._Ybb[b, b] = Y0
        self._S[b, b] = Y0
        self._Pb[b, b] = P0
        self._rad[radar] = j
        self._radar_codes[radar] = j

    def add_aircraft(self, key: Hashable, time: float, state: np.ndarray, cov: np.ndarray) -> None:
        state, cov = validated_prior(key, state, cov, self._ac)
        L = np.zeros((4, 4))
        if not chol(cov, L, 4):
            raise SingularInformation(f"aircraft {key!r}: prior covariance is not positive definite "
                                      "(the information form needs its inverse)")
        if not self._free:
            cap, new_cap = self._Yxx.shape[0], max(16, 2 * self._Yxx.shape[0])
            self._alloc(new_cap)
            self._free = list(range(new_cap - 1, cap - 1, -1))
        s = self._free.pop()
        Li = np.linalg.inv(L)
        self._Yxx[s] = Li.T @ Li
        self._ex[s] = self._Yxx[s] @ state
        self._tx[s], self._nk[s] = float(time), 0
        self._ac[key] = s
        self._ctr[C_ALIVE] += 1

    def remove_aircraft(self, key: Hashable) -> None:
        """Marginalise aircraft ``key`` into Y_bb, η_b (S unchanged) and free its slot."""
        s = self._slot(key)
        if K.marginalise(self._st, self._wk, s) != OK:
            raise SingularInformation(f"aircraft {key!r}: {_WHY[ERR_YII]}")
        del self._ac[key]
        self._free.append(s)

    # --- filter ------------------------------------------------------------------------------
    def update(self, m: PlaneMeasurement) -> Innovation:
        """One measurement: :meth:`update_many` of one row."""
        inn = self.update_many([m.time], [m.aircraft], [m.radar], np.asarray(m.z, float)[None],
                               np.asarray(m.C, float)[None], np.asarray(m.R, float)[None], [m.rho])
        return Innovation(inn.nu[0], inn.S[0], float(inn.nis[0]))

    def update_many(self, time: Sequence[float], aircraft: Sequence[Hashable], radar: Sequence[str | None],
                    z: np.ndarray, C: np.ndarray, R: np.ndarray, rho: Sequence[float] | None = None) -> Innovation:
        """A time-ordered batch through the compiled update (``_kernels.update_rows``), row by row, ``rho`` the
        plots' slant ranges (NaN where not given: a radar with a range gain needs it); if row i fails, the
        rows before it have been applied and the exception carries ``index = i``."""
        n = len(time)
        z, C, R = (np.ascontiguousarray(a, dtype=float) for a in (z, C, R))
        rho = np.full(n, np.nan) if rho is None else np.ascontiguousarray(rho, dtype=float)
        if z.shape != (n, 2) or C.shape != (n, 2, 2) or R.shape != (n, 2, 2) or len(aircraft) != n or len(radar) != n \
                or rho.shape != (n,):
            exc = ValueError(f"a batch of {n} measurements: z must have shape (n, 2), C and R (n, 2, 2), rho (n,), not "
                             f"{z.shape}, {C.shape}, {R.shape}, {rho.shape}")
            exc.index = 0
            raise exc
        slots, radars = np.empty(n, np.int64), np.empty(n, np.int64)
        for k in range(n):
            try:
                slots[k] = self._slot(aircraft[k])
                radars[k] = self._radar_codes[radar[k]] if radar[k] in self._radar_codes else self._radar_index(radar[k])
            except KeyError as exc:
                return self._applied(time, aircraft, radar, z, C, R, rho, k, exc)
        no_rho = self._has_gain[radars] & ~np.isfinite(rho)  # radar −1 (unbiased): the last entry, False
        if no_rho.any():
            k = int(np.argmax(no_rho))
            return self._applied(time, aircraft, radar, z, C, R, rho, k, ValueError(
                f"measurement of {aircraft[k]!r} at t={time[k]}: radar {radar[k]!r} has a range gain, which needs "
                "the plot's slant range (PlaneMeasurement.rho)"))
        out = np.zeros((n, 7))
        code, k, latest = K.update_rows(self._F, self._I, self._WF, slots, radars, np.asarray(time, float), z, C, R,
                                        rho, out)
        if latest == latest and not latest <= self._bias_time:  # a row applied; the epoch NaN at first
            self._bias_time = float(latest)
        if code != OK:
            exc_type = ValueError if code == ERR_NONFINITE else SingularInformation
            when = "after" if code in (ERR_S, ERR_REBUILD) else "at"
            exc = exc_type(f"{when} the measurement of aircraft {aircraft[k]!r} by radar {radar[k]!r} at t={time[k]}: "
                           f"{_WHY[code]}")
            exc.index = k
            raise exc
        return Innovation(out[:, 0:2].copy(), out[:, 2:6].reshape(n, 2, 2).copy(), out[:, 6].copy())

    def _applied(self, time, aircraft, radar, z, C, R, rho, k: int, exc: Exception) -> Innovation:
        """Row ``k`` names an unknown aircraft or radar, or lacks the slant range its radar needs: the rows before
        it applied, then ``exc`` raised with ``index = k``."""
        if k:
            self.update_many(time[:k], aircraft[:k], radar[:k], z[:k], C[:k], R[:k], rho[:k])
        exc.index = k
        raise exc

    def _slot(self, key: Hashable) -> int:
        try:
            return self._ac[key]
        except KeyError:
            raise KeyError(f"aircraft {key!r} is not being estimated (add_aircraft first)") from None

    def _radar_index(self, radar: str) -> int:
        try:
            return self._rad[radar]
        except KeyError:
            raise KeyError(f"radar {radar!r} is not known (add_radar first)") from None

    def refresh(self, rebuild: bool = True) -> None:
        """Recompute S from the blocks (``rebuild``), then S⁻¹ and ς̂ from S, now."""
        if rebuild and not _rebuild(self._st, self._wk):
            raise SingularInformation(_WHY[ERR_REBUILD])
        if not refresh(self._S, self._sv, self._Pb, self._bh, self._ctr, self._wk[6], self._wk[7]):
            raise SingularInformation(_WHY[ERR_S])

    # --- reads -------------------------------------------------------------------------------
    def aircraft(self, key: Hashable) -> AircraftEstimate:
        s = self._slot(key)
        x, P = np.zeros(4), np.zeros((4, 4))
        if not K.read_aircraft(self._st, self._wk, s, x, P):
            raise SingularInformation(f"aircraft {key!r}: {_WHY[ERR_YII]}")
        return AircraftEstimate(float(self._tx[s]), x, P)

    def bias(self, radar: str) -> BiasState:
        """``radar``'s ς̂ and P_ς (copies of :meth:`bias_views`) at the latest update time."""
        b, P = self.bias_views(radar)
        return BiasState(radar, self._bias_time, b.copy(), P.copy(), self._models[self._rad[radar]].names)

    def bias_views(self, radar: str) -> tuple[np.ndarray, np.ndarray]:
        """Read-only views of ``radar``'s ς̂ and P_ς in the estimator's storage."""
        return self._bias_views[self._rad[radar] if radar in self._rad else self._radar_index(radar)]

    def joint(self, keys: list[Hashable] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(ξ̂, P̂) over ``keys`` (default: all, in insertion order) then all radars, as ``coupled.joint``.

        Formed on demand from (1)–(2): Cov(χ_i, χ_l) = δ_il Y_ii⁻¹ + G_i S⁻¹_KL G_lᵀ,
        Cov(χ_i, ς) = −G_i S⁻¹_K· — O((4n + M)²), for tests and small problems.
        """
        keys = list(self._ac) if keys is None else keys
        nb = self._Pb.shape[0]
        N = 4 * len(keys)
        E = np.zeros((N, nb))  # rows: −G_i scattered to the bias columns, so Cov = diag(Σ) + E Pb Eᵀ
        x = np.zeros(N + nb)
        Sig = np.zeros((N, N))
        for r, key in enumerate(keys):
            s = self._ac[key]
            k = max(int(self._nk[s]), 0)
            idx = np.array([i for j in self._rk[s, :k] for i in range(self._block(j).start, self._block(j).stop)],
                           int)
            Yi = np.linalg.inv(self._Yxx[s])
            G = Yi @ self._Yxb[s, :, :len(idx)]
            E[4 * r:4 * r + 4, idx] = -G
            x[4 * r:4 * r + 4] = Yi @ self._ex[s] - G @ self._bh[idx]
            Sig[4 * r:4 * r + 4, 4 * r:4 * r + 4] = Yi
        x[N:] = self._bh
        EP = E @ self._Pb
        P = np.block([[Sig + EP @ E.T, EP], [EP.T, self._Pb]])
        return x, 0.5 * (P + P.T)

    def information(self) -> dict:
        """The stored blocks: {'aircraft': {key: (Y_ii, {radar: Y_ib}, η_i, epoch)}, 'Ybb', 'eta_b', 'radars'}."""
        names = list(self._rad)
        ac = {}
        for key, s in self._ac.items():
            k = max(int(self._nk[s]), 0)
            widths = [self._models[j].size for j in self._rk[s, :k]]
            starts = np.cumsum([0] + widths)
            blocks = {names[j]: self._Yxb[s, :, starts[c]:starts[c] + widths[c]].copy()
                      for c, j in enumerate(self._rk[s, :k])}
            ac[key] = (self._Yxx[s].copy(), blocks, self._ex[s].copy(), float(self._tx[s]))
        return {"aircraft": ac, "Ybb": self._Ybb.copy(), "eta_b": self._eb.copy(), "radars": names}

    @property
    def aircraft_keys(self) -> list[Hashable]:
        return list(self._ac)

    @property
    def radars(self) -> list[str]:
        return list(self._rad)

"""Exact coupled estimator in sparse information form (DESIGN §5 item 2): cost per plot independent of n.

The joint state ξ = [χ_1..χ_n, ς_1..ς_m] of the dense ``coupled`` filter (seed 000 §1.2.1) is kept as
its information Y = P⁻¹, η = Y ξ̂. Aircraft are coupled only through the biases, so Y is an
*arrowhead*: blocks Y_ii (4×4), Y_ib (4×2, only for the radars b that observed aircraft i), Y_bb
(2m×2m); Y_ik = 0 for two aircraft i ≠ k. Equivalently, given the biases the aircraft are
independent::

    χ_i | ς  ~  N(m_i − G_i ς_K,  Y_ii⁻¹),   G_i = Y_ii⁻¹ Y_ib,   m_i = Y_ii⁻¹ η_i          (1)
    ς        ~  N(S⁻¹ s,  S⁻¹),   S = Y_bb − Σ_i Y_bi Y_ii⁻¹ Y_ib,   s = η_b − Σ_i Y_bi Y_ii⁻¹ η_i   (2)

**Measurement** z = C_x χ_i + C_s ς_j + v, v ~ N(0, R) (C_s, R evaluated at the plot, so the model is
linear and identical to the dense filter's): Y += Hᵀ R⁻¹ H, η += Hᵀ R⁻¹ z with H = [C_x at i, C_s at j]
— it touches Y_ii, Y_ij, Y_jj only, so the pattern is kept. S changes by ΔY_jj minus the change of
aircraft i's term Y_bi Y_ii⁻¹ Y_ib, which in closed form (eliminate χ_i with (1)) is the PSD rank-2
term H_bᵀ Ω⁻¹ H_b with H_b = C_s E_j − C_x G_i, Ω = R + C_x Y_ii⁻¹ C_xᵀ (s: H_bᵀ Ω⁻¹ (z − C_x m_i)):
O(k²) with k the radars that saw aircraft i; S only grows between its recomputations.

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
The plot's innovation needs the same quantities. To avoid an O(m³) solve per plot, S⁻¹ and ς̂ are
also kept in covariance form by the rank-2 Kalman update of the bias marginal
(S⁻¹ −= K_b Λ⁻¹ K_bᵀ, ς̂ += K_b Λ⁻¹ ν, K_b = Cov(ς, h)), O(m²) per plot, and reset from S every
``refresh_every`` updates; S itself is recomputed from the blocks by (2) every ``rebuild_factor``
× (n + 1) updates (amortised O(k²) per plot) to bound round-off.

**Numerical hygiene.** Every block update is symmetric by construction (Gram products such as VᵀV
with V = L⁻¹Y_ib, L Lᵀ = Y_ii, or one triangle computed and mirrored). Positive definiteness is checked by a Cholesky factorisation of R, Y_ii
(at every prediction, update and read), Λ (every plot) and S (every refresh); a failure raises
:class:`SingularInformation` (a :class:`~radartracker.kalman.SingularInnovation`, hence a
ValueError) naming the aircraft, radar and time — never a NaN. Non-finite input raises ValueError.
The information form needs R ≻ 0 and a proper aircraft prior (P₀ ≻ 0).

**Bias drift is refused.** A random walk on ς adds noise to the biases after aircraft have been
conditioned on the old values: given the new biases the aircraft are no longer independent (two
aircraft seen by one radar keep their correlation through the old bias), so Y_xx fills in and the
exact filter cannot stay sparse. A config with ``bias_drifts`` raises ValueError; use ``coupled``.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

import numpy as np

import attrs

from radartracker.api import (AircraftEstimate, BiasState, Estimator, EstimatorConfig, Innovation, MotionModel, PlaneMeasurement, SingularInnovation, validated_prior)

from . import _kernels as K


class SingularInformation(SingularInnovation):
    """A block of the information form (R, Y_ii, Λ or S) is not positive definite."""


_WHY = {
    K.ERR_NONFINITE: "non-finite time, z, C or R",
    K.ERR_R: "measurement noise covariance R is not positive definite (the information form needs R⁻¹)",
    K.ERR_YII: "aircraft information block Y_ii is not positive definite",
    K.ERR_LAMBDA: "innovation covariance Λ is not positive definite",
    K.ERR_S: "bias Schur complement S is not positive definite",
    K.ERR_REBUILD: "recomputing S from the blocks met an aircraft block Y_ii that is not positive definite",
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
        self._radar_codes: dict[str | None, int] = {None: -1}  # radar → its index in the kernels, None → −1
        self._ac: dict[Hashable, int] = {}  # key -> slot
        self._free: list[int] = []
        self._bias_time = float("nan")  # latest update time, as coupled's global bias epoch
        self._ctr = np.array([0, refresh_every, 0, rebuild_factor, 0], np.int64)
        self._alloc(0, 0)

    # --- storage -----------------------------------------------------------------------------
    _STORE = ("_Yxx", "_Yxb", "_ex", "_tx", "_Ybb", "_eb", "_S", "_sv", "_Pb", "_bh", "_nk", "_rk", "_ctr")

    def _alloc(self, cap: int, m: int) -> None:
        """(Re)allocate for ``cap`` aircraft slots and ``m`` radars, keeping the contents: every array a view
        into one float and one int buffer (``_F``, ``_I``; layout ``_kernels.carve``)."""
        nb, mm = 2 * m, max(m, 1)
        nf, ni = K.storage_sizes(cap, mm, nb)
        F, I = np.zeros(nf), np.zeros(ni, np.int64)
        I[:3] = cap, mm, nb
        new = K.carve(F, I, cap, mm, nb)
        new[10][:] = -1  # nk: free slot
        for name, dst in zip(self._STORE, new[:-1]):
            src = getattr(self, name, None)
            if src is not None:  # what is kept: the old extent of each array
                dst[tuple(slice(0, n) for n in src.shape)] = src
            setattr(self, name, dst)
        self._F, self._I = F, I
        self._work = K.Work(m, new[-1], self._q)
        # bias_arrays(): read-only views of each radar's block of ς̂ and P_ς, by radar index
        self._bias_views = [(self._bh[2 * j:2 * j + 2], self._Pb[2 * j:2 * j + 2, 2 * j:2 * j + 2]) for j in range(m)]
        for v in self._bias_views:
            v[0].flags.writeable = v[1].flags.writeable = False

    def state_dict(self) -> dict:
        """The default state without the buffers behind the arrays and the views into them (rebuilt on load)."""
        return {k: v for k, v in super().state_dict().items()
                if k not in ("_F", "_I", "_bias_views", "_radar_codes")}

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        self._alloc(self._Yxx.shape[0], self._Ybb.shape[0] // 2)  # the loaded arrays into packed storage
        self._radar_codes = {**self._rad, None: -1}

    def __setstate__(self, state: dict) -> None:
        """copy.deepcopy: the copied arrays no longer share one buffer; pack them again."""
        self.__dict__.update(state)
        self._alloc(self._Yxx.shape[0], self._Ybb.shape[0] // 2)

    def add_radar(self, radar: str) -> None:
        if radar in self._rad:
            raise ValueError(f"radar {radar!r} already added")
        j = len(self._rad)
        self._alloc(self._Yxx.shape[0], j + 1)
        P0 = self.config.bias_prior()
        b = slice(2 * j, 2 * j + 2)
        Y0 = np.linalg.inv(P0)
        self._Ybb[b, b] = Y0
        self._S[b, b] = Y0
        self._Pb[b, b] = P0
        self._rad[radar] = j
        self._radar_codes[radar] = j

    def add_aircraft(self, key: Hashable, time: float, state: np.ndarray, cov: np.ndarray) -> None:
        if key in self._ac:
            raise ValueError(f"aircraft {key!r} already estimated")
        state, cov = validated_prior(key, state, cov)
        L = np.zeros((4, 4))
        if not K.chol(cov, L, 4):
            raise SingularInformation(f"aircraft {key!r}: prior covariance is not positive definite "
                                      "(the information form needs its inverse)")
        if not self._free:
            cap, new_cap = self._Yxx.shape[0], max(16, 2 * self._Yxx.shape[0])
            self._alloc(new_cap, len(self._rad))
            self._free = list(range(new_cap - 1, cap - 1, -1))
        s = self._free.pop()
        Li = np.linalg.inv(L)
        self._Yxx[s] = Li.T @ Li
        self._ex[s] = self._Yxx[s] @ state
        self._tx[s], self._nk[s] = float(time), 0
        self._ac[key] = s
        self._ctr[K.C_ALIVE] += 1

    def remove_aircraft(self, key: Hashable) -> None:
        """Marginalise aircraft ``key`` into Y_bb, η_b (S unchanged) and free its slot."""
        s = self._ac.pop(key)
        w = self._work
        k = int(self._nk[s])
        if k > 0:
            K.bias_index(self._rk, s, k, w.idx)
            if not K.conditional(self._Yxx, self._Yxb, self._ex, s, 2 * k, w.f4[0], w.V, w.v4[0], w.G, w.v4[1]):
                raise SingularInformation(f"aircraft {key!r}: {_WHY[K.ERR_YII]}")
            K.add_contribution(self._Ybb, self._eb, w.idx, w.V, w.v4[0], 2 * k, -1.0)
        self._nk[s] = -1
        self._free.append(s)
        self._ctr[K.C_ALIVE] -= 1

    # --- filter ------------------------------------------------------------------------------
    def update(self, m: PlaneMeasurement) -> Innovation:
        """One measurement: :meth:`update_arrays` on its fields (one kernel call per measurement, where
        building the batch arrays cost more than the update), ν and Λ copied out of its scratch."""
        z = np.ascontiguousarray(m.z, dtype=float)
        C = np.ascontiguousarray(m.C, dtype=float)
        R = np.ascontiguousarray(m.R, dtype=float)
        if z.shape != (2,) or C.shape != (2, 2) or R.shape != (2, 2):  # as update_many's batch would refuse it
            nu, lam, nis = self.update_many([m.time], [m.aircraft], [m.radar], z[None], C[None], R[None])
            return Innovation(nu[0], lam[0], float(nis[0]))
        self.update_arrays(m.time, m.aircraft, m.radar, z, C, R)
        w = self._work
        return Innovation(w.nu.copy(), w.lam.copy(), float(w.io[6]))

    def update_arrays(self, time: float, aircraft: Hashable, radar: str | None, z: np.ndarray, C: np.ndarray,
                      R: np.ndarray) -> None:
        """The TrackManager's path (:meth:`Estimator.update_arrays`): the compiled update on the caller's
        arrays, ν, Λ and the NIS into scratch space."""
        try:
            s = self._ac[aircraft]
            j = -1 if radar is None else self._rad[radar]
        except KeyError:
            s, j = self._slot(aircraft), self._radar_index(radar)  # the KeyError naming which
        t = float(time)
        code = K.update_packed(self._F, self._I, self._work.flat, s, j, t, z, C, R)
        if code == K.OK or code in (K.ERR_LAMBDA, K.ERR_S, K.ERR_REBUILD):  # applied, or predicted: as update_many
            if not t <= self._bias_time:  # NaN at first, like np.fmax
                self._bias_time = t
        if code != K.OK:
            raise self._failure(code, 0, aircraft, radar, t)

    def update_many(self, time: Sequence[float], aircraft: Sequence[Hashable], radar: Sequence[str | None],
                    z: np.ndarray, C: np.ndarray, R: np.ndarray) -> Innovation:
        """All updates in one compiled loop (see :meth:`Estimator.update_many`)."""
        n = len(aircraft)
        try:
            slots = np.fromiter(map(self._ac.__getitem__, aircraft), np.int64, n)
            radars = np.fromiter(map(self._radar_codes.__getitem__, radar), np.int64, len(radar))
        except KeyError:  # the KeyError naming which
            slots = np.fromiter((self._slot(a) for a in aircraft), np.int64, n)
            radars = np.fromiter((-1 if r is None else self._radar_index(r) for r in radar), np.int64, len(radar))
        times = np.asarray(time, float)
        Z = np.ascontiguousarray(z, dtype=float)
        Cs = np.ascontiguousarray(C, dtype=float)
        Rs = np.ascontiguousarray(R, dtype=float)
        if n == 0:
            return Innovation(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros(0))
        out = np.zeros((n, 7))  # ν, Λ, NIS of each plot: one array, one argument
        code, i, t = K.update_batch(self._F, self._I, self._work.flat, slots, radars, times, Z, Cs, Rs, out)
        # plots before i are applied; plot i was predicted (Λ) or fully applied (S) — as coupled does; t the
        # latest time of those (finite: the kernel stops at a non-finite time)
        if (i or code in (K.ERR_LAMBDA, K.ERR_S, K.ERR_REBUILD)) and not t <= self._bias_time:  # NaN at first
            self._bias_time = t
        if code != K.OK:
            raise self._failure(code, i, aircraft[i], radar[i], times[i])
        return Innovation(out[:, :2], out[:, 2:6].reshape(n, 2, 2), out[:, 6])

    @staticmethod
    def _failure(code: int, i: int, aircraft: Hashable, radar: str | None, time: float) -> ValueError:
        """The error of kernel status ``code`` at the batch's measurement ``i`` (its ``index``)."""
        exc_type = ValueError if code == K.ERR_NONFINITE else SingularInformation
        when = "after" if code in (K.ERR_S, K.ERR_REBUILD) else "at"
        exc = exc_type(f"{when} the measurement of aircraft {aircraft!r} by radar {radar!r} at t={time}: {_WHY[code]}")
        exc.index = i
        return exc

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
        w = self._work
        if rebuild and not K.rebuild(self._Yxx, self._Yxb, self._ex, self._nk, self._rk, self._Ybb, self._eb,
                                     self._S, self._sv, self._ctr, w.f4, w.V, w.G, w.v4, w.idx, w.LSi, w.Kb[0]):
            raise SingularInformation(_WHY[K.ERR_REBUILD])
        if not K.refresh(self._S, self._sv, self._Pb, self._bh, self._ctr, w.LS, w.LSi):
            raise SingularInformation(_WHY[K.ERR_S])

    # --- reads -------------------------------------------------------------------------------
    def aircraft(self, key: Hashable) -> AircraftEstimate:
        s = self._slot(key)
        x, P = np.zeros(4), np.zeros((4, 4))
        w = self._work
        if not K.read_aircraft(self._Yxx, self._Yxb, self._ex, self._nk, self._rk, self._Pb, self._bh, s, x, P,
                               w.f4, w.V, w.G, w.v4, w.idx):
            raise SingularInformation(f"aircraft {key!r}: {_WHY[K.ERR_YII]}")
        return AircraftEstimate(float(self._tx[s]), x, P)

    def bias(self, radar: str) -> BiasState:
        """``radar``'s ς̂ and P_ς (copies of :meth:`bias_arrays`' views) at the latest update time."""
        b, P = self.bias_arrays(radar)
        return BiasState(radar, self._bias_time, b.copy(), P.copy())

    def bias_arrays(self, radar: str) -> tuple[np.ndarray, np.ndarray]:
        """Read-only views of ``radar``'s ς̂ and P_ς in the estimator's storage (:meth:`Estimator.bias_arrays`)."""
        return self._bias_views[self._rad[radar] if radar in self._rad else self._radar_index(radar)]

    def joint(self, keys: list[Hashable] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(ξ̂, P̂) over ``keys`` (default: all, in insertion order) then all radars, as ``coupled.joint``.

        Formed on demand from (1)–(2): Cov(χ_i, χ_l) = δ_il Y_ii⁻¹ + G_i S⁻¹_KL G_lᵀ,
        Cov(χ_i, ς) = −G_i S⁻¹_K· — O((4n + 2m)²), for tests and small problems.
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
            idx = np.ravel([[2 * j, 2 * j + 1] for j in self._rk[s, :k]]).astype(int)
            Yi = np.linalg.inv(self._Yxx[s])
            G = Yi @ self._Yxb[s, :, :2 * k]
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
            blocks = {names[j]: self._Yxb[s, :, 2 * c:2 * c + 2].copy() for c, j in enumerate(self._rk[s, :k])}
            ac[key] = (self._Yxx[s].copy(), blocks, self._ex[s].copy(), float(self._tx[s]))
        return {"aircraft": ac, "Ybb": self._Ybb.copy(), "eta_b": self._eb.copy(), "radars": names}

    @property
    def aircraft_keys(self) -> list[Hashable]:
        return list(self._ac)

    @property
    def radars(self) -> list[str]:
        return list(self._rad)

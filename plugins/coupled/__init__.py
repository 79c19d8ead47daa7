"""Coupled estimator: one joint Kalman filter over all aircraft and radar biases (seed 000 §1.2.1).

The joint state ξ = [χ_1..χ_n, ς_1..ς_m] (χ = [x, y, vx, vy], ς = [Δr, Δθ]) has one dense
covariance P with every cross-covariance kept. A plot z of aircraft i by radar j observes
h(ξ) = C ξ with C = [0 .. C_x .. 0 .. C_s .. 0] (seed eq. 1.10), so with K = P̄ Cᵀ
(DESIGN §5, the seed's Λ read as Λ⁻¹ and DDᵀ as R = D W Dᵀ)::

    predict (aircraft i only, to its own epoch):  χ̄_i = A χ̂_i,  P̄ = Φ P̂ Φᵀ + diag(.., Q, ..)
    innovate:  ν = z − C_x χ̄_i − C_s ς̄_j,        Λ = C P̄ Cᵀ + R
    correct:   ξ̂ = ξ̄ + K Λ⁻¹ ν,                   P̂ = P̄ − K Λ⁻¹ Kᵀ

Λ⁻¹ is applied through its 2×2 Cholesky factor L (P̂ = P̄ − U Uᵀ with U = K L⁻ᵀ), which keeps
P̂ exactly symmetric. An unbiased measurement (ADS-B, radar ``None``) has C_s = 0 and still
corrects the biases through the cross-covariances: that is how ADS-B anchors them.

Adding an aircraft augments ξ with its prior (zero cross-covariance); removing it marginalises
it (drops its rows and columns), which keeps exactly what it taught about the biases. With a bias
random walk, all biases are predicted together to a global bias epoch. Cost O((4n + 2m)²) per plot.

A radar's bias vector is its sensor model's components (``EstimatorConfig.sensor``; docs/design-notes.md):
the plot's row of C is [I, −τ̄ I] in the aircraft's columns and B = ∂z/∂ς_j in the radar's (range
offset c_ρ, azimuth offset c_θ, range gain ρ c_ρ, time offset −v̄), and ẑ = p̄ + B ς̄_j: the extended
Kalman step of z = p − τ v + …, linearised at the predicted velocity v̄ and time offset τ̄, with the
second-order terms of the product τ v (ẑ −= P_vτ, Λ += P_ττ P_vv + P_vτ P_vτᵀ). Without a time offset
this is the linear filter above, unchanged.
"""

from __future__ import annotations

from collections.abc import Hashable

import numpy as np

from radartracker.api import (AircraftEstimate, BiasState, Estimator, Innovation, PlaneMeasurement, SensorModel,
                              SingularInnovation, StateCheck, require_new_radar, validated_prior)


class CoupledEstimator(Estimator):
    """Dense joint filter over all aircraft states and radar biases (seed 000 §1.2.1)."""

    name = "coupled"

    def __init__(self, config=None) -> None:
        super().__init__(config)
        self._x = np.zeros(0)  # joint state, capacity-sized; free slots hold zeros
        self._P = np.zeros((0, 0))
        self._size = 0  # high-water mark of used entries
        self._free: list[int] = []  # start indices of free aircraft slots (4 entries each)
        self._ac: dict[Hashable, list] = {}  # key -> [start index, epoch]
        self._rad: dict[str, int] = {}  # radar -> start index (its sensor model's size of entries)
        self._models: dict[str, SensorModel] = {}  # radar -> its sensor model
        self._bias_time: float | None = None

    # --- state layout ----------------------------------------------------------------------------
    def _alloc(self, n: int) -> int:
        start = self._size
        if start + n > self._x.size:
            cap = max(self._x.size * 3 // 2, start + n, 16)
            x, P = np.zeros(cap), np.zeros((cap, cap))
            x[:start], P[:start, :start] = self._x[:start], self._P[:start, :start]
            self._x, self._P = x, P
        self._size += n
        return start

    def add_radar(self, radar: str) -> None:
        require_new_radar(radar, self._rad)
        model = self.config.sensor(radar)
        k = self._alloc(model.size)
        self._P[k:k + model.size, k:k + model.size] = model.prior()
        self._rad[radar] = k
        self._models[radar] = model

    def add_aircraft(self, key: Hashable, time: float, state: np.ndarray, cov: np.ndarray) -> None:
        state, cov = validated_prior(key, state, cov, self._ac)
        k = self._free.pop() if self._free else self._alloc(4)
        self._x[k:k + 4] = state
        self._P[k:k + 4, :] = 0.0
        self._P[:, k:k + 4] = 0.0
        self._P[k:k + 4, k:k + 4] = cov
        self._ac[key] = [k, float(time)]

    def remove_aircraft(self, key: Hashable) -> None:
        """Marginalise aircraft ``key``: zero its rows and columns and free its slot."""
        k, _ = self._ac.pop(key)
        self._x[k:k + 4] = 0.0
        self._P[k:k + 4, :] = 0.0
        self._P[:, k:k + 4] = 0.0
        self._free.append(k)

    # --- snapshots -------------------------------------------------------------------------------
    def state_dict(self) -> dict:
        """The used part of ξ̂ and P̂ (``size`` entries), where each radar, aircraft and free slot starts in it,
        each aircraft's epoch and the bias epoch."""
        n = self._size
        return {"size": n, "x": self._x[:n].copy(), "P": self._P[:n, :n].copy(), "radars": dict(self._rad),
                "aircraft": {k: list(v) for k, v in self._ac.items()}, "free": list(self._free),
                "bias_time": self._bias_time}

    def load_state_dict(self, state: dict) -> None:
        """Take back a :meth:`state_dict`, checked first: ``size`` the length of ξ̂ (never allocated from the
        number alone), the radars this estimator's, every radar block (its sensor model's size), aircraft and free
        slot (4) inside it, disjoint and covering it, values finite, P̂ symmetric and positive semi-definite over the
        radars and aircraft."""
        c = StateCheck("coupled", state, ("size", "x", "P", "radars", "aircraft", "free", "bias_time"))
        x = c.array("x", (None,))
        n = c.integer("size", state["size"], len(x), len(x))
        P = c.array("P", (n, n))
        c.names("radars", self.radars, c.mapping("radars"))
        width = {r: m.size for r, m in self._models.items()}
        rad = {r: c.integer(f"start of radar {r!r}", k, 0, n - width[r]) for r, k in state["radars"].items()}
        ac = {}
        for key, entry in c.mapping("aircraft").items():
            start, epoch = c.sequence(f"aircraft {key!r}", entry, length=2)
            ac[key] = [c.integer(f"start of aircraft {key!r}", start, 0, n - 4), c.number(f"epoch of {key!r}", epoch)]
        free = [c.integer("a free slot's start", k, 0, n - 4) for k in c.sequence("free", max_len=n)]
        used = np.zeros(n, np.int64)
        for k, w in [(k, width[r]) for r, k in rad.items()] + [(v[0], 4) for v in ac.values()] + [(k, 4) for k in free]:
            used[k:k + w] += 1
        if np.any(used != 1):
            raise c.fail(f"radar, aircraft and free blocks overlap or leave gaps (entry {int(np.argmax(used != 1))})")
        live = [k + i for r, k in rad.items() for i in range(width[r])] + [v[0] + i for v in ac.values() for i in range(4)]
        c.covariance("P over the radars and aircraft", P[np.ix_(live, live)])
        bias_time = c.number("bias_time", state["bias_time"], none=True)
        self._x, self._P, self._size, self._rad, self._ac, self._free = x, P, n, rad, ac, free
        self._bias_time = bias_time

    # --- filter ----------------------------------------------------------------------------------
    def _predict_aircraft(self, k: int, dt: float) -> None:
        if dt == 0.0:
            return
        n = self._size
        A, Q = self.config.motion.transition(dt)
        x, P = self._x, self._P[:n, :n]
        x[k:k + 4] = A @ x[k:k + 4]
        P[k:k + 4, :] = A @ P[k:k + 4, :]
        P[:, k:k + 4] = P[:, k:k + 4] @ A.T
        P[k:k + 4, k:k + 4] += Q

    def _predict_biases(self, time: float) -> None:
        """Random-walk biases: add the drift since the global bias epoch to every radar."""
        if self._bias_time is not None and self.config.bias_drifts:
            for r, k in self._rad.items():
                model = self._models[r]
                self._P[k:k + model.size, k:k + model.size] += model.drift(time - self._bias_time)
        self._bias_time = time if self._bias_time is None else max(self._bias_time, time)

    def update(self, m: PlaneMeasurement) -> Innovation:
        _check_finite(m)
        if m.radar is not None and not np.isfinite(m.rho) and "range_gain" in self._models[m.radar].names:
            raise ValueError(f"measurement of {m.aircraft!r} at t={m.time}: radar {m.radar!r} has a range gain, "
                             "which needs the plot's slant range (PlaneMeasurement.rho)")
        ac = self._ac[m.aircraft]
        k = ac[0]
        self._predict_aircraft(k, m.time - ac[1])
        ac[1] = float(m.time)
        self._predict_biases(m.time)
        n = self._size
        x, P = self._x, self._P[:n, :n]
        # K = P̄ Cᵀ (n×2) and the predicted measurement C ξ̄
        K = P[:, k:k + 2].copy()
        zhat = x[k:k + 2].copy()
        if m.radar is not None:
            b, model, tau = self._bias_row(m)
            w = model.size
            B = model.jacobian(m.C, m.rho, x[k + 2:k + 4])
            if tau != 0.0:  # ∂z/∂v = −τ̄ I
                K -= tau * P[:, k + 2:k + 4]
            K += P[:, b:b + w] @ B.T
            zhat += B @ x[b:b + w]
        S = K[k:k + 2] + m.R
        if m.radar is not None:
            if tau != 0.0:
                S -= tau * K[k + 2:k + 4]
            S += B @ K[b:b + w]
            if "time_offset" in model.names:  # the second-order terms of −τ v (Gaussian second-order filter)
                t = b + model.index("time_offset")
                c = P[k + 2:k + 4, t]
                zhat -= c
                S += P[t, t] * P[k + 2:k + 4, k + 2:k + 4] + np.outer(c, c)
        nu = m.z - zhat
        S = 0.5 * (S + S.T)
        Linv = _inverse_cholesky_2x2(S)
        U = K @ Linv.T  # U = K L⁻ᵀ, so K Λ⁻¹ Kᵀ = U Uᵀ
        e = Linv @ nu  # L⁻¹ ν
        x[:n] += U @ e
        rows = max(16, 2**17 // n)  # in place, by row blocks: no n×n temporary
        for i in range(0, n, rows):
            P[i:i + rows] -= U[i:i + rows] @ U.T
        return Innovation(nu, S, float(e @ e))

    def _bias_row(self, m: PlaneMeasurement) -> tuple[int, SensorModel, float]:
        """(start of the radar's block, its sensor model, τ̄ its predicted time offset or 0)."""
        b = self._rad[m.radar]
        model = self._models[m.radar]
        tau = float(self._x[b + model.index("time_offset")]) if "time_offset" in model.names else 0.0
        return b, model, tau

    # --- reads -----------------------------------------------------------------------------------
    def aircraft(self, key: Hashable) -> AircraftEstimate:
        k, t = self._ac[key]
        return AircraftEstimate(t, self._x[k:k + 4].copy(), self._P[k:k + 4, k:k + 4].copy())

    def bias(self, radar: str) -> BiasState:
        b, model = self._rad[radar], self._models[radar]
        w = model.size
        t = float("nan") if self._bias_time is None else self._bias_time
        return BiasState(radar, t, self._x[b:b + w].copy(), self._P[b:b + w, b:b + w].copy(), model.names)

    def joint(self, keys: list[Hashable] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(ξ̂, P̂) over ``keys`` (default: all aircraft, in insertion order) then all radars."""
        keys = list(self._ac) if keys is None else keys
        idx = [self._ac[a][0] + i for a in keys for i in range(4)]
        idx += [b + i for r, b in self._rad.items() for i in range(self._models[r].size)]
        return self._x[idx].copy(), self._P[np.ix_(idx, idx)].copy()

    @property
    def aircraft_keys(self) -> list[Hashable]:
        return list(self._ac)

    @property
    def radars(self) -> list[str]:
        return list(self._rad)


def _check_finite(m: PlaneMeasurement) -> None:
    if not (np.isfinite(m.time) and np.isfinite(m.z).all() and np.isfinite(m.C).all() and np.isfinite(m.R).all()):
        raise ValueError(f"measurement of {m.aircraft!r} at t={m.time}: z, C, R and time must be finite")


def _inverse_cholesky_2x2(S: np.ndarray) -> np.ndarray:
    """L⁻¹ for the Cholesky factor L Lᵀ = S of a 2×2 Λ (closed form: LAPACK overhead dominates at 2×2)."""
    a, b, d = float(S[0, 0]), float(S[1, 0]), float(S[1, 1])
    l11 = np.sqrt(a) if a > 0.0 else 0.0
    l21 = b / l11 if l11 > 0.0 else 0.0
    r = d - l21 * l21
    if not (l11 > 0.0 and r > 0.0 and np.isfinite(r)):
        raise SingularInnovation(f"innovation covariance not positive definite: {S.tolist()}")
    l22 = np.sqrt(r)
    return np.array([[1.0 / l11, 0.0], [-l21 / (l11 * l22), 1.0 / l22]])

"""Blom–van Doorn estimator: a Kalman filter per aircraft plus one macro bias filter (seed 000 §1.3.1).

For a plot z of aircraft i by radar j, with the shared innovation ν = z − C_x χ̄_i − C_s ς̄
(ς the stacked bias vector of all m radars, C_s = [0 .. C_{s,j} .. 0]; DESIGN §5 item 3, the
seed's Λ read as Λ⁻¹ and DDᵀ as R = D W Dᵀ)::

    aircraft:  K_x = P̄_x C_xᵀ,  Λ_x = C_x P̄_x C_xᵀ + R
    bias:      K_s = P̄_s C_sᵀ + Hᵀ,
               Λ_s = C_x P̄_x C_xᵀ + C_s P̄_s C_sᵀ + H C_sᵀ + C_s Hᵀ + R
               H = −(F_xᵀF_x)⁻¹ F_xᵀ F_s P̄_s,  F_x = Σ_k R_k⁻¹,  F_s = Σ_k R_k⁻¹ C_{s,k}

H stands in for the ignored cross-covariance C_x P̄_xs: it is the cross-covariance of the
position with the biases if the position were the weighted least-squares fusion of the sources
that see the aircraft, H = −G P̄_s with G = F_x⁻¹F_s. **Which sources enter F_x, F_s:** every
source that has measured aircraft i so far — each radar k that has plotted it, with its *most
recent* C_{s,k} and R_k for this aircraft (the current plot's for radar j), and ADS-B if the
aircraft has reported it (C_s = 0, so it enters F_x only: an ADS-B-anchored position is less tied
to the biases). An aircraft seen by one radar k alone has G = C_{s,k} and K_s = 0: a single radar
cannot separate its bias from the aircraft position, and the bias filter rightly learns nothing.

**Deviation from the seed (documented in docs/estimators.md).** The seed copies Λ from the full
filter, where C_x P̄_x C_xᵀ is the *total* position covariance. Here P̄_x is the aircraft filter's,
which treats the biases as known; the position error it misses is the bias-induced part
G P̄_s Gᵀ = H P̄_s⁻¹ Hᵀ, consistent with the cross term H. We therefore use

    Λ_s = C_x P̄_x C_xᵀ + G P̄_s Gᵀ + C_s P̄_s C_sᵀ + H C_sᵀ + C_s Hᵀ + R
        = C_x P̄_x C_xᵀ + R + (C_s − G) P̄_s (C_s − G)ᵀ,

which is always positive definite and keeps P̂_s = P̄_s − K_s Λ_s⁻¹ K_sᵀ positive semi-definite
(it is a Schur complement). Read literally (without G P̄_s Gᵀ), Λ_s = C_x P̄_x C_xᵀ + R − C P̄_s Cᵀ
for a single-radar aircraft, which is indefinite as soon as the track is more precise than the
bias prior. Both covariances are symmetrised after each update.
"""

from __future__ import annotations

from collections.abc import Hashable

import numpy as np

from radartracker.api import (AircraftEstimate, BiasState, Estimator, Innovation, PlaneMeasurement, StateCheck, correct,
                              require_new_radar, validated_prior)

_ADSB = None  # source key of unbiased measurements


class BlomEstimator(Estimator):
    """Per-aircraft Kalman filters and the Blom–van Doorn macro bias filter (seed 000 §1.3.1)."""

    name = "blom"

    def __init__(self, config=None) -> None:
        super().__init__(config)
        self._x: dict[Hashable, list] = {}  # key -> [time, state, cov, {source: (C, R)}]
        self._rad: dict[str, int] = {}  # radar -> column of its Δr in the bias vector
        self._s = np.zeros(0)
        self._Ps = np.zeros((0, 0))
        self._bias_time: float | None = None

    def add_radar(self, radar: str) -> None:
        require_new_radar(radar, self._rad)
        self.config.require_two_components(self.name, radar)
        k = self._s.size
        self._rad[radar] = k
        self._s = np.append(self._s, [0.0, 0.0])
        P = np.zeros((k + 2, k + 2))
        P[:k, :k] = self._Ps
        P[k:, k:] = self.config.bias_prior()
        self._Ps = P

    def add_aircraft(self, key: Hashable, time: float, state: np.ndarray, cov: np.ndarray) -> None:
        self._x[key] = [float(time), *validated_prior(key, state, cov, self._x), {}]

    def remove_aircraft(self, key: Hashable) -> None:
        del self._x[key]

    def state_dict(self) -> dict:
        """The bias filter (ς̂, P̂_ς, the column of each radar, its epoch) and each aircraft's
        [epoch, χ̂, P̂, {source: (C_s, R)}]."""
        return {"radars": dict(self._rad), "s": self._s.copy(), "Ps": self._Ps.copy(), "bias_time": self._bias_time,
                "aircraft": {k: [t, x.copy(), P.copy(), {src: (C.copy(), R.copy()) for src, (C, R) in srcs.items()}]
                             for k, (t, x, P, srcs) in self._x.items()}}

    def load_state_dict(self, state: dict) -> None:
        """Take back a :meth:`state_dict`, checked first: this estimator's radars at columns 0, 2, 4, …,
        finite values, covariances symmetric positive semi-definite, each aircraft's sources known radars
        (or None, ADS-B) with a 2×2 C_s and a positive definite R (F_x needs R⁻¹)."""
        c = StateCheck("blom", state, ("radars", "s", "Ps", "bias_time", "aircraft"))
        rad = c.mapping("radars")
        c.names("radars", self.radars, rad)
        if rad != {r: 2 * i for i, r in enumerate(self.radars)}:
            raise c.fail(f"radar columns {list(rad.items())[:10]!r} are not this estimator's radars at 0, 2, 4, …")
        s, Ps = c.gaussian("bias", state["s"], state["Ps"], 2 * len(rad))
        aircraft = {}
        for key, entry in c.mapping("aircraft").items():
            t, x, P, sources = c.sequence(f"aircraft {key!r}", entry, length=4)
            what = f"aircraft {key!r}"
            aircraft[key] = [c.number(f"{what} epoch", t), *c.gaussian(what, x, P, 4), {}]
            for src, pair in c.mapping(f"{what} sources", sources).items():
                if src is not _ADSB and src not in rad:
                    raise c.fail(f"{what}: source {src!r} is not a radar of this estimator")
                C, R = c.sequence(f"{what} source {src!r}", pair, length=2)
                C, R = c.array(f"{what} C of {src!r}", (2, 2), value=C), c.array(f"{what} R of {src!r}", (2, 2), value=R)
                c.covariance(f"{what} R of {src!r}", R, definite=True)
                aircraft[key][3][src] = (C, R)
        bias_time = c.number("bias_time", state["bias_time"], none=True)
        self._s, self._Ps, self._x, self._bias_time = s, Ps, aircraft, bias_time

    def _predict_biases(self, time: float) -> None:
        if self._bias_time is not None and self.config.bias_drifts:
            D = self.config.bias_drift(time - self._bias_time)
            for k in self._rad.values():
                self._Ps[k:k + 2, k:k + 2] += D
        self._bias_time = time if self._bias_time is None else max(self._bias_time, time)

    def _macro_G(self, sources: dict) -> np.ndarray:
        """G = (F_xᵀF_x)⁻¹F_xᵀ F_s = F_x⁻¹ F_s (F_x is square and invertible); H = −G P̄_s."""
        Fx = np.zeros((2, 2))
        Fs = np.zeros((2, self._s.size))
        for src, (C, R) in sources.items():
            Ri = np.linalg.inv(R)
            Fx += Ri
            if src is not _ADSB:
                k = self._rad[src]
                Fs[:, k:k + 2] += Ri @ C
        return np.linalg.solve(Fx, Fs)

    def update(self, m: PlaneMeasurement) -> Innovation:
        if not (np.isfinite(m.time) and np.isfinite(m.z).all() and np.isfinite(m.C).all() and np.isfinite(m.R).all()):
            raise ValueError(f"measurement of {m.aircraft!r} at t={m.time}: z, C, R and time must be finite")
        ac = self._x[m.aircraft]
        A, Q = self.config.motion.transition(m.time - ac[0])
        x, P = A @ ac[1], A @ ac[2] @ A.T + Q
        self._predict_biases(m.time)
        nu = m.z - x[:2]
        Sx = P[:2, :2] + m.R
        Cs = np.zeros((2, self._s.size))
        if m.radar is not _ADSB:
            k = self._rad[m.radar]
            Cs[:, k:k + 2] = m.C
            nu = nu - m.C @ self._s[k:k + 2]
        ac[3][m.radar] = (m.C, m.R)
        self._correct_biases(ac[3], Cs, Sx, nu)
        ac[1], ac[2] = correct(x, P, P[:, :2], Sx, nu)
        ac[0] = m.time
        return Innovation(nu, Sx, float(nu @ np.linalg.solve(Sx, nu)))

    def _correct_biases(self, sources: dict, Cs: np.ndarray, Sx: np.ndarray, nu: np.ndarray) -> None:
        if self._s.size == 0:
            return
        M = Cs - self._macro_G(sources)  # C_s − G
        Ks = self._Ps @ M.T  # = P̄_s C_sᵀ + Hᵀ
        Ss = Sx + M @ self._Ps @ M.T  # = C_x P̄_x C_xᵀ + R + (C_s − G) P̄_s (C_s − G)ᵀ
        self._s, self._Ps = correct(self._s, self._Ps, Ks, Ss, nu)

    def aircraft(self, key: Hashable) -> AircraftEstimate:
        t, x, P, _ = self._x[key]
        return AircraftEstimate(t, x.copy(), P.copy())

    def bias(self, radar: str) -> BiasState:
        k = self._rad[radar]
        t = float("nan") if self._bias_time is None else self._bias_time
        return BiasState(radar, t, self._s[k:k + 2].copy(), self._Ps[k:k + 2, k:k + 2].copy())

    @property
    def aircraft_keys(self) -> list[Hashable]:
        return list(self._x)

    @property
    def radars(self) -> list[str]:
        return list(self._rad)


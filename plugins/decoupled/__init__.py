"""Decoupled estimator: separate filters for each aircraft and each radar bias (seed 000 §1.3.2).

For a plot z of aircraft i by radar j, with the shared innovation ν = z − C_x χ̄_i − C_s ς̄_j
(DESIGN §5 item 4, the seed's Λ read as Λ⁻¹)::

    aircraft:  K_x = P̄_x C_xᵀ,  Λ_x = C_x P̄_x C_xᵀ + R,  χ̂ = χ̄ + K_x Λ_x⁻¹ ν,  P̂_x = P̄_x − K_x Λ_x⁻¹ K_xᵀ
    bias:      K_s = P̄_s C_sᵀ,  Λ_s = C_s P̄_s C_sᵀ + R,  ς̂ = ς̄ + K_s Λ_s⁻¹ ν,  P̂_s = P̄_s − K_s Λ_s⁻¹ K_sᵀ

Each filter ignores the other's uncertainty and all cross-covariances, so the reported
covariances are optimistic (the comparison in docs/estimators.md shows by how much). An unbiased
measurement (ADS-B, radar ``None``) updates only the aircraft filter.
"""

from __future__ import annotations

from collections.abc import Hashable

import numpy as np

from radartracker.api import (AircraftEstimate, BiasState, Estimator, Innovation, PlaneMeasurement, StateCheck, correct,
                              require_new_radar, validated_prior)


class DecoupledEstimator(Estimator):
    """Independent Kalman filters per aircraft and per radar bias (seed 000 §1.3.2)."""

    name = "decoupled"

    def __init__(self, config=None) -> None:
        super().__init__(config)
        self._x: dict[Hashable, list] = {}  # key -> [time, state, cov]
        self._s: dict[str, list] = {}  # radar -> [time, bias, cov]

    def add_radar(self, radar: str) -> None:
        require_new_radar(radar, self._s)
        self.config.require_two_components(self.name, radar)
        self._s[radar] = [None, np.zeros(2), self.config.bias_prior()]

    def add_aircraft(self, key: Hashable, time: float, state: np.ndarray, cov: np.ndarray) -> None:
        self._x[key] = [float(time), *validated_prior(key, state, cov, self._x)]

    def remove_aircraft(self, key: Hashable) -> None:
        del self._x[key]

    def state_dict(self) -> dict:
        """Each aircraft's [epoch, χ̂, P̂] and each radar's [epoch or None, ς̂, P̂_ς]."""
        return {"aircraft": {k: [t, x.copy(), P.copy()] for k, (t, x, P) in self._x.items()},
                "radars": {r: [t, s.copy(), P.copy()] for r, (t, s, P) in self._s.items()}}

    def load_state_dict(self, state: dict) -> None:
        """Take back a :meth:`state_dict`, checked first: this estimator's radars, finite values, covariances
        symmetric positive semi-definite."""
        c = StateCheck("decoupled", state, ("aircraft", "radars"))
        radars = c.mapping("radars")
        c.names("radars", self.radars, radars)
        loaded = {}
        for what, table, n, none in (("aircraft", c.mapping("aircraft"), 4, False), ("radar", radars, 2, True)):
            loaded[what] = {}
            for key, entry in table.items():
                t, mean, cov = c.sequence(f"{what} {key!r}", entry, length=3)
                loaded[what][key] = [c.number(f"{what} {key!r} epoch", t, none=none),
                                     *c.gaussian(f"{what} {key!r}", mean, cov, n)]
        self._x, self._s = loaded["aircraft"], loaded["radar"]

    def update(self, m: PlaneMeasurement) -> Innovation:
        ac = self._x[m.aircraft]
        A, Q = self.config.motion.transition(m.time - ac[0])
        x, P = A @ ac[1], A @ ac[2] @ A.T + Q
        nu = m.z - x[:2]
        Sx = P[:2, :2] + m.R
        if m.radar is not None:
            b = self._s[m.radar]
            if self.config.bias_drifts and b[0] is not None:
                b[2] = b[2] + self.config.bias_drift(m.time - b[0])
            nu = nu - m.C @ b[1]
            Ks = b[2] @ m.C.T
            Ss = m.C @ Ks + m.R
            b[1], b[2] = correct(b[1], b[2], Ks, Ss, nu)
            b[0] = m.time
        ac[1], ac[2] = correct(x, P, P[:, :2], Sx, nu)
        ac[0] = m.time
        return Innovation(nu, Sx, float(nu @ np.linalg.solve(Sx, nu)))

    def aircraft(self, key: Hashable) -> AircraftEstimate:
        t, x, P = self._x[key]
        return AircraftEstimate(t, x.copy(), P.copy())

    def bias(self, radar: str) -> BiasState:
        t, s, P = self._s[radar]
        return BiasState(radar, float("nan") if t is None else t, s.copy(), P.copy())

    @property
    def aircraft_keys(self) -> list[Hashable]:
        return list(self._x)

    @property
    def radars(self) -> list[str]:
        return list(self._s)

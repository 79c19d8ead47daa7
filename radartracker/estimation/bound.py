"""The Cramér–Rao bound of every radar's bias components, from the plots' geometry and times (issue 30).

For the model of :mod:`radartracker.estimation.sensor` with its Jacobians evaluated at the true (or best
known) aircraft states, z = H ξ + w is linear-Gaussian in the joint state ξ = [χ_1..χ_n, ς_1..ς_m], and
the posterior Cramér–Rao bound (Tichavský, Muravchik & Nehorai 1998) is the covariance of the Kalman
recursion over those Jacobians, which needs no measured values::

    J_{k+1}⁻¹ = F J_k⁻¹ Fᵀ + Q          (prediction: the aircraft's CV model, a bias's drift)
    J_{k+1}   = J_{k+1} + Hᵀ R⁻¹ H        (a plot: H = [I, −τ I] at the aircraft, B at its radar; ADS-B [I, 0])

started from the priors (the same priors the estimator is given). With q = 0 and constant biases it is
the inverse of the batch Fisher information Σ Hᵀ R⁻¹ H + priors, the bound of any unbiased estimate
from the recording. An aircraft is marginalised after its last measurement, as the estimator does.

A component's status compares its bound with its prior variance σ₀²: ``unobservable`` when CRLB ≥
``UNOBSERVABLE_RATIO``·σ₀² (the plots add less than 11 % of the prior's information: a time offset
seen only on hovering traffic, whose column −v is zero; a range gain on a lone radar without ADS-B), never
reported as a small σ; ``weak`` when CRLB ≥ ``WEAK_RATIO``·σ₀² (the prior still holds a tenth or more of
the information, so the estimate leans on it); ``observable`` otherwise.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping

import attrs
import numpy as np
from scipy.linalg import block_diag

from radartracker.estimation.base import EstimatorConfig
from radartracker.estimation.observability import UNOBSERVABLE_RATIO

#: CRLB / prior variance at and above which a component is weak (unobservable: UNOBSERVABLE_RATIO)
WEAK_RATIO = 0.1


@attrs.frozen
class ComponentBound:
    """One bias component's √CRLB (``sd``), prior σ and ``status``: ``observable``, ``weak`` or ``unobservable``."""

    radar: str
    component: str
    sd: float
    prior_sd: float

    @property
    def status(self) -> str:
        ratio = self.sd**2 / self.prior_sd**2 if self.prior_sd > 0.0 else 1.0
        return "unobservable" if ratio >= UNOBSERVABLE_RATIO else "weak" if ratio >= WEAK_RATIO else "observable"


@attrs.frozen
class BoundInput:
    """The geometry of the measurements as columns in time order: ``time``, ``aircraft`` keys, ``radar`` (None
    for ADS-B), base Jacobians ``C`` (n, 2, 2), noise ``R`` (n, 2, 2), slant ranges ``rho`` and the aircraft's
    plane ``velocity`` (n, 2) at each; ``prior`` maps an aircraft to its prior covariance at its first one."""

    time: np.ndarray
    aircraft: np.ndarray
    radar: np.ndarray
    C: np.ndarray
    R: np.ndarray
    rho: np.ndarray
    velocity: np.ndarray
    prior: Mapping[Hashable, np.ndarray]


class _Joint:
    """The bound's covariance over the live aircraft and every radar's components (dense, the bound only)."""

    def __init__(self, config: EstimatorConfig, radars: list[str]) -> None:
        self.config = config
        self.models = {r: config.sensor(r) for r in radars}
        blocks = [model.prior() for model in self.models.values()]  # the radars first: aircraft are appended after
        self.start = dict(zip(self.models, np.cumsum([0] + [b.shape[0] for b in blocks[:-1]]).tolist()))
        self.P = block_diag(*blocks)
        self.aircraft: dict[Hashable, list] = {}  # key -> [start, epoch]
        self.bias_time: float | None = None

    def add(self, key: Hashable, time: float, cov: np.ndarray) -> None:
        n = self.P.shape[0]
        P = np.zeros((n + 4, n + 4))
        P[:n, :n], P[n:, n:] = self.P, cov
        self.P = P
        self.aircraft[key] = [n, time]

    def remove(self, key: Hashable) -> None:
        k, _ = self.aircraft.pop(key)
        keep = np.r_[0:k, k + 4:self.P.shape[0]]
        self.P = self.P[np.ix_(keep, keep)]
        for entry in self.aircraft.values():
            if entry[0] > k:
                entry[0] -= 4

    def predict(self, key: Hashable, time: float) -> int:
        """Predict aircraft ``key`` (CV, its own epoch) and every drifting bias (one bias epoch) to ``time``."""
        k, epoch = self.aircraft[key]
        A, Q = self.config.motion.transition(time - epoch)
        P = self.P
        P[k:k + 4, :] = A @ P[k:k + 4, :]
        P[:, k:k + 4] = P[:, k:k + 4] @ A.T
        P[k:k + 4, k:k + 4] += Q
        self.aircraft[key][1] = time
        if self.bias_time is not None:
            for r, model in self.models.items():
                b = self.start[r]
                P[b:b + model.size, b:b + model.size] += model.drift(time - self.bias_time)
        self.bias_time = time if self.bias_time is None else max(self.bias_time, time)
        return k

    def measure(self, k: int, radar: str | None, C: np.ndarray, R: np.ndarray, rho: float, v: np.ndarray,
                tau: float) -> None:
        """The covariance update by one measurement's H (the bound linearises τ at ``tau``, its true value)."""
        H = np.zeros((2, self.P.shape[0]))
        H[:, k:k + 2] = np.eye(2)
        if radar is not None:
            model, b = self.models[radar], self.start[radar]
            H[:, b:b + model.size] = model.jacobian(C, rho, v)
            if "time_offset" in model.names:
                H[:, k + 2:k + 4] = -tau * np.eye(2)
        PH = self.P @ H.T
        S = H @ PH + R
        self.P -= PH @ np.linalg.solve(S, PH.T)
        self.P = 0.5 * (self.P + self.P.T)


def bias_bound(geometry: BoundInput, config: EstimatorConfig, radars: list[str],
               true_time_offset: Mapping[str, float] | None = None) -> dict[str, list[ComponentBound]]:
    """The posterior CRLB of every radar's components at the end of ``geometry`` (see the module docstring);
    ``true_time_offset`` (s, per radar, default 0) is where ∂z/∂v = −τ I is evaluated."""
    joint = _Joint(config, radars)
    tau = dict(true_time_offset or {})
    last = {key: i for i, key in enumerate(geometry.aircraft)}
    for i, key in enumerate(geometry.aircraft):
        t = float(geometry.time[i])
        if key not in joint.aircraft:
            joint.add(key, t, np.asarray(geometry.prior[key], float))
        k = joint.predict(key, t)
        radar = geometry.radar[i]
        joint.measure(k, radar, geometry.C[i], geometry.R[i], float(geometry.rho[i]), geometry.velocity[i],
                      tau.get(radar, 0.0) if radar is not None else 0.0)
        if last[key] == i:
            joint.remove(key)
    out: dict[str, list[ComponentBound]] = {}
    for r, model in joint.models.items():
        b = joint.start[r]
        sd = np.sqrt(np.maximum(np.diag(joint.P)[b:b + model.size], 0.0))
        out[r] = [ComponentBound(r, c.name, float(s), c.prior_sd) for c, s in zip(model.components, sd)]
    return out

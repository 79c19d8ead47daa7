"""Track weight (the seed's ``RaschetVesaTreka``, left undefined in seed 000 §2.4).

The weight of a track is the negative log-likelihood of the plots given the track. Plot i of
radar j, converted to the plane, is z_i = p(t_i) + C_i ς_j + e_i with e_i ~ N(0, R_i),
R_i = D_i W_j D_iᵀ (seed 000 eq. 1.11, DESIGN §4). With the whitened residual
r̃_i = L_i⁻¹ (z_i − C_i ς_j − p(t_i)), L_i L_iᵀ = R_i, and d_i² = ‖r̃_i‖² (squared Mahalanobis distance)::

    weight = Σ_i ρ(d_i) + ½ Σ_i log det(2π R_i)

with ρ(d) = d²/2 (Gaussian, the default), or a robust loss that grows slower for outliers:
Huber ρ(d) = d²/2 for d ≤ c, c·d − c²/2 beyond; Cauchy ρ(d) = (c²/2) log(1 + d²/c²).
ς_j is a known radar bias (zero unless given). The constant term makes weights of different
tracks of the same plots comparable and lets the Gaussian weight serve in a BIC.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from radartracker_plugins.reconstruction.objects import PlotTrack

LOSSES = ("gauss", "huber", "cauchy")


class TrackWeight:
    """Callable weight of plane positions p (n, 2) at the plot times of ``plots``.

    ``loss`` is ``"gauss"``, ``"huber"`` or ``"cauchy"`` with scale ``c`` (in σ units);
    ``biases`` maps a radar id to its known bias [Δr, Δθ] (metres, radians).
    """

    def __init__(self, plots: PlotTrack, loss: str = "gauss", c: float = 3.0,
                 biases: Mapping[str, np.ndarray] | None = None) -> None:
        if loss not in LOSSES:
            raise ValueError(f"loss: expected one of {LOSSES}, got {loss!r}")
        if c <= 0:
            raise ValueError(f"c: robust scale must be > 0, got {c!r}")
        self.loss, self.c = loss, float(c)
        z = plots.z.copy()
        for radar, b in (biases or {}).items():
            sel = plots.radar == radar
            z[sel] -= plots.C[sel] @ np.asarray(b, float)
        self.z = z
        L = np.linalg.cholesky(plots.R)
        self.Linv = np.linalg.inv(L)
        self.const = 0.5 * float(np.sum(np.log(np.linalg.det(2 * np.pi * plots.R))))  # ½Σ log det(2πR)

    def subset(self, sel) -> "TrackWeight":
        """The weight of the plots selected by ``sel`` (a slice or mask) only."""
        sub = object.__new__(TrackWeight)
        sub.loss, sub.c, sub.z, sub.Linv = self.loss, self.c, self.z[sel], self.Linv[sel]
        sub.const = -float(np.sum(np.log(np.abs(np.linalg.det(sub.Linv))))) + len(sub.z) * np.log(2 * np.pi)
        return sub

    def distances2(self, p: np.ndarray) -> np.ndarray:
        """Squared Mahalanobis distances d_i² of the plots from positions ``p``."""
        r = self.z - p
        rt = np.einsum("nij,nj->ni", self.Linv, r)
        return np.einsum("ni,ni->n", rt, rt)

    def rho(self, d2: np.ndarray) -> np.ndarray:
        """Per-plot loss ρ(d) of squared distances."""
        if self.loss == "gauss":
            return 0.5 * d2
        c = self.c
        if self.loss == "huber":
            d = np.sqrt(d2)
            return np.where(d <= c, 0.5 * d2, c * d - 0.5 * c * c)
        return 0.5 * c * c * np.log1p(d2 / (c * c))

    def __call__(self, p: np.ndarray) -> float:
        return float(np.sum(self.rho(self.distances2(p)))) + self.const

"""Which bias components the data inform, and what is reported for those they do not (issue 30).

A component ς_k of radar j with prior N(0, σ₀²) is **unobservable** when the measurements add less than a
ninth of the prior's information, P_kk ≥ ``UNOBSERVABLE_RATIO``·σ₀² (the ratio the Cramér–Rao bound of
:mod:`radartracker.estimation.bound` uses), or when the radar is **isolated** in the coupling graph
(:meth:`radartracker.estimation.coupling.CouplingGraph.isolated`: none of its aircraft was ever measured by
another radar or ADS-B). An isolated radar's biases are seen only through the shape its errors give its own
aircraft's paths: a rotation about the radar (Δθ) not at all, a range offset Δr only through the curvature
it puts on straight paths — which every turn the estimator's motion model does not expect also puts there.
On one radar without ADS-B the estimate walked to Δr̂ = 4,256 ± 475 m for a true −52 m while its σ stayed
near the prior's 500 m (docs/design-notes.md).

Such a component is reported and used as its prior — ς̂_k = 0, P_kk = σ₀², no correlation with the other
components — and named in :attr:`BiasState.unobservable`; the estimator keeps its own value, so the
component is reported as estimated again once the data inform it.
"""

from __future__ import annotations

import numpy as np

from radartracker.domain import BiasState

#: posterior variance / prior variance at and above which a component is unobservable (the measurements
#: add less than 11 % of the prior's information)
UNOBSERVABLE_RATIO = 0.9


def held_at_prior(state: BiasState, prior: np.ndarray, isolated: bool) -> BiasState:
    """``state`` with its unobservable components (module docstring) at their prior: mean 0, variance the
    prior's diagonal ``prior`` (k × k), cross-covariances 0; ``state`` itself when every component is observable."""
    var, var0 = np.diag(state.cov), np.diag(prior)
    held = np.ones(len(var), bool) if isolated else var >= UNOBSERVABLE_RATIO * var0
    if not held.any():
        return state
    bias, cov = np.array(state.bias, float), np.array(state.cov, float)
    bias[held] = 0.0
    cov[held, :] = 0.0
    cov[:, held] = 0.0
    cov[held, held] = var0[held]
    names = tuple(name for name, h in zip(state.components, held.tolist()) if h)
    return BiasState(state.radar, state.time, bias, cov, state.components, names)

"""Hooke–Jeeves pattern search (seed 000 §2.5), a small general derivative-free minimiser.

Hooke & Jeeves (1961), "Direct search solution of numerical and statistical problems":

* exploratory move: for each coordinate i in turn try x + sᵢeᵢ, then x − sᵢeᵢ; keep any improvement;
* pattern move: after a successful exploration from base b to x, jump to x + (x − b) and explore
  around there; keep going while it improves;
* on failure multiply the steps by ``dh`` (the seed's 0.5); coordinates whose step is already
  below its final value are left alone. Stop when every step is below its final step
  (or after ``max_evals`` evaluations).
"""

from __future__ import annotations

from collections.abc import Callable

import attrs
import numpy as np


@attrs.frozen
class HJResult:
    """Minimiser ``x``, its value ``fun``, evaluations ``nfev``, step reductions ``nred``, and
    ``converged`` (all steps fell below their final values, rather than running out of evaluations)."""

    x: np.ndarray
    fun: float
    nfev: int
    nred: int
    converged: bool


def hooke_jeeves(f: Callable[[np.ndarray], float], x0, steps, final_steps, dh: float = 0.5,
                 max_evals: int = 200_000) -> HJResult:
    """Minimise ``f`` from ``x0`` with initial ``steps`` down to ``final_steps`` (per coordinate)."""
    x = np.array(x0, float)
    s = np.array(np.broadcast_to(steps, x.shape), float)
    fin = np.array(np.broadcast_to(final_steps, x.shape), float)
    if not 0.0 < dh < 1.0:
        raise ValueError(f"dh: step factor must be in (0, 1), got {dh!r}")
    if np.any(s <= 0) or np.any(fin <= 0):
        raise ValueError("steps and final_steps must be > 0")
    nfev = 0

    def fe(p: np.ndarray) -> float:
        nonlocal nfev
        nfev += 1
        return float(f(p))

    def explore(p: np.ndarray, fp: float) -> tuple[np.ndarray, float]:
        p = p.copy()
        for i in range(len(p)):
            if s[i] < fin[i]:
                continue
            old = p[i]
            for trial in (old + s[i], old - s[i]):
                p[i] = trial
                ft = fe(p)
                if ft < fp:
                    fp = ft
                    break
            else:
                p[i] = old
        return p, fp

    fb = fe(x)
    nred = 0
    while np.any(s >= fin) and nfev < max_evals:
        xn, fn = explore(x, fb)
        if fn < fb:
            while nfev < max_evals:
                base, x, fb = x, xn, fn
                xp = x + (x - base)
                xn, fn = explore(xp, fe(xp))
                if not fn < fb:
                    break
        else:
            s = np.where(s >= fin, s * dh, s)
            nred += 1
    return HJResult(x, fb, nfev, nred, bool(np.all(s < fin)))

"""Shared pieces of the conformance checks: the failure type, comparisons and noise draws."""

from __future__ import annotations

import sys
from typing import Any

import numpy as np
from scipy.stats import chi2

from radartracker.compiled import array_returns

TOL = 1e-9
H = np.hstack([np.eye(2), np.zeros((2, 2))])  # position observation of χ = [x, y, vx, vy]


class CheckFailed(AssertionError):
    """A plugin failed a conformance check; the message names the plugin, the check and the fault."""


def fail(owner: str, check: str, message: str) -> CheckFailed:
    return CheckFailed(f"{owner}: check '{check}' failed: {message}")


def close(a: Any, b: Any, tol: float = TOL) -> bool:
    """a ≈ b elementwise, relative to the largest magnitude of b (same shape required)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=tol, atol=tol * max(1.0, float(np.max(np.abs(b), initial=0.0)))))


def identical(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    """Bit-for-bit equality of two lists of arrays (NaN equals NaN)."""
    return len(a) == len(b) and all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b))


def noise_cov(rng: np.random.Generator, sd: float = 60.0) -> np.ndarray:
    """A random, well-conditioned 2×2 position noise covariance of about ``sd`` metres."""
    L = rng.normal(0.0, sd, (2, 2))
    return L @ L.T + (0.5 * sd) ** 2 * np.eye(2)


def chi2_inside(total: float, dof: int, p: float = 1e-3) -> tuple[bool, float, float]:
    """Whether ``total`` is inside the two-sided 1 − p interval of χ²(dof), and the interval."""
    lo, hi = chi2.ppf(p / 2, dof), chi2.ppf(1 - p / 2, dof)
    return lo <= total <= hi, lo, hi


def kalman_filter_class() -> type:
    """FilterPy's ``KalmanFilter`` (the oracle of the ``filterpy`` checks), or an ImportError saying how to get it."""
    try:
        from filterpy.kalman import KalmanFilter
    except ImportError as exc:
        raise ImportError("the 'filterpy' checks need FilterPy: pip install filterpy (or radartracker[test])") from exc
    return KalmanFilter


def run_checks(owner: str, runners: dict, checks: list[str], *args: Any) -> list[str]:
    """Run the named checks in order; an exception inside the plugin becomes a CheckFailed naming the check."""
    unknown = set(checks) - set(runners)
    if unknown:
        raise ValueError(f"unknown checks {sorted(unknown)}; known: {', '.join(runners)}")
    for name in checks:
        try:
            runners[name](*args, owner)
        except (CheckFailed, ImportError):  # ImportError: FilterPy, the oracle, is not installed
            raise
        except Exception as exc:
            raise fail(owner, name, f"raised {type(exc).__name__}: {exc}") from exc
    return list(checks)


def plugin_modules(cls: type) -> list:
    """The imported modules of ``cls``'s package: its module's package, or the module itself when it is a
    package or a top-level module."""
    module = sys.modules[cls.__module__]
    name = module.__name__
    prefix = name if hasattr(module, "__path__") else name.rpartition(".")[0] or name
    return [m for n, m in list(sys.modules.items()) if m is not None and (n == prefix or n.startswith(prefix + "."))]


def check_kernels(cls: type, owner: str) -> int:
    """The ``kernels`` check: no kernel (:func:`radartracker.compiled.kernel`, compiled without numba's
    runtime) of ``cls``'s package returns an array, in the signatures compiled by the checks before it.
    Returns the number of signatures looked at."""
    seen = 0
    for module in plugin_modules(cls):
        bad, n = array_returns(module)
        seen += n
        if bad:
            raise fail(owner, "kernels", f"a kernel compiled without numba's runtime returns an array, which "
                                         f"Python would hold without an owner: {'; '.join(bad)}")
    return seen

"""Comparison of estimates with the truth of a simulated scenario.

Truth positions are interpolated linearly in the system plane at the estimate times; truth
velocities are the finite-difference slopes of that interpolation. NEES is
(χ̂ − χ)ᵀ P⁻¹ (χ̂ − χ) of the 4-dimensional aircraft state.
"""

from __future__ import annotations

import attrs
import numpy as np

from radartracker.formats import TruthTable
from radartracker.geometry import SystemPlane


@attrs.frozen
class TruthPaths:
    """Per-target truth in the plane: times, positions and velocities."""

    paths: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]

    @classmethod
    def from_table(cls, truth: TruthTable, plane: SystemPlane) -> TruthPaths:
        x, y = plane.to_plane(truth.lat, truth.lon)
        paths = {}
        for target in np.unique(truth.target.astype(str)):
            idx = np.flatnonzero(truth.target == target)
            idx = idx[np.argsort(truth.time[idx], kind="stable")]
            t = truth.time[idx]
            p = np.stack([x[idx], y[idx]], axis=-1)
            v = np.gradient(p, t, axis=0) if len(t) > 1 else np.zeros_like(p)
            paths[target] = (t, p, v)
        return cls(paths)

    def state_at(self, target: str, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Truth [x, y, vx, vy] (N, 4) at times ``t`` and a mask of times inside the truth span."""
        if target not in self.paths:
            return np.full((len(t), 4), np.nan), np.zeros(len(t), bool)
        tt, p, v = self.paths[target]
        inside = (t >= tt[0]) & (t <= tt[-1])
        cols = [np.interp(t, tt, p[:, 0]), np.interp(t, tt, p[:, 1]),
                np.interp(t, tt, v[:, 0]), np.interp(t, tt, v[:, 1])]
        return np.stack(cols, axis=-1), inside


def state_errors(paths: TruthPaths, keys: np.ndarray, times: np.ndarray, states: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Estimate − truth (N, 4) for each recorded estimate, and the mask where truth exists."""
    err = np.full(states.shape, np.nan)
    ok = np.zeros(len(times), bool)
    for key in np.unique(keys.astype(str)):
        idx = np.flatnonzero(keys.astype(str) == key)
        truth, inside = paths.state_at(key, times[idx])
        err[idx] = states[idx] - truth
        ok[idx] = inside
    return err, ok


def nees(err: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared eᵀP⁻¹e per row."""
    return np.einsum("ni,ni->n", err, np.linalg.solve(cov, err[..., None])[..., 0])

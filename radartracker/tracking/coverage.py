"""Which radar's antenna swept which track during a frame, and which tracks any radar covers.

For radar r at plane position (x_r, y_r) and a track predicted at (x, y) (DESIGN §3, grid azimuths):

* range ρ = hypot(x − x_r, y − y_r); the track is *covered* if ρ ≤ ρ_max,r for some radar;
* grid azimuth from true north α = (atan2(x − x_r, y − y_r) − γ_r) mod 2π (γ_r: grid azimuth of north at
  the radar, the meridian convergence);
* the antenna points at α_r(t) = φ_r + 2πt/T_r; it *swept* the track during [t_a, t_b) if
  (α − α_r(t_a)) mod 2π < 2π (t_b − t_a)/T_r. Only tracks within 0.98 ρ_max,r count (the edge of
  coverage is where detection fails for reasons of its own).

One compiled pass over radars × tracks, written for the manager's frame (thousands of tracks, tens of
radars: the numpy version made ~30 array passes and temporaries per frame).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

TWO_PI = 2.0 * math.pi


@njit(cache=True)
def sweep(pos: np.ndarray, radar_xy: np.ndarray, north: np.ndarray, max_range: np.ndarray, start: np.ndarray,
          width: np.ndarray, phased: np.ndarray, swept: np.ndarray, covered: np.ndarray) -> None:
    """Fill ``swept`` (radars × tracks: radar ``r`` has a phase, ``phased[r]``, and its antenna swept the
    track while within 0.98 of its range) and ``covered`` (tracks within some radar's range).

    ``start[r]``: α_r(t_a); ``width[r]``: 2π (t_b − t_a)/T_r."""
    m, n = radar_xy.shape[0], pos.shape[0]
    covered[:] = False
    swept[:, :] = False
    for r in range(m):
        near = 0.98 * max_range[r]
        far = (max_range[r] * (1.0 + 1e-9)) ** 2  # beyond: out of range whatever the rounding of hypot
        for i in range(n):
            dx = pos[i, 0] - radar_xy[r, 0]
            dy = pos[i, 1] - radar_xy[r, 1]
            if dx * dx + dy * dy > far:
                continue
            rng = math.hypot(dx, dy)
            if rng <= max_range[r]:
                covered[i] = True
            hit = False
            if phased[r] and rng < near:
                az = (math.atan2(dx, dy) - north[r]) % TWO_PI
                hit = (az - start[r]) % TWO_PI < width[r]
            swept[r, i] = hit


@njit(cache=True)
def smooth_phases(phase: np.ndarray, terms: np.ndarray, rows: np.ndarray) -> None:
    """``phase[r]`` ← 0.98 ``phase[r]`` + e for each term e of radar r (``rows[j]``: term j's radar), in
    order: the antenna phases' recurrences, with CPython's complex × float, (a + ib)(0.98 + 0i), so the same
    bits as that Python loop."""
    for j in range(rows.shape[0]):
        r = rows[j]
        re, im = phase[r].real, phase[r].imag
        re, im = re * 0.98 - im * 0.0, re * 0.0 + im * 0.98
        phase[r] = complex(re + terms[j].real, im + terms[j].imag)

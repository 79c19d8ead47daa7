"""Which radar's antenna swept which track during a frame, and which tracks any radar covers.

For radar r at plane position (x_r, y_r) and a track predicted at (x, y) (DESIGN §3, grid azimuths):

* range ρ = hypot(x − x_r, y − y_r); the track is *covered* if ρ ≤ ρ_max,r for some radar;
* grid azimuth from true north α = (atan2(x − x_r, y − y_r) − γ_r) mod 2π (γ_r: grid azimuth of north at
  the radar, the meridian convergence);
* the antenna points at α_r(t) = φ_r + 2πt/T_r; it *swept* the track during [t_a, t_b) if
  (α − α_r(t_a)) mod 2π < 2π (t_b − t_a)/T_r. Only tracks within 0.98 ρ_max,r count (the edge of
  coverage is where detection fails for reasons of its own).

The antenna phase φ_r is estimated from the radar's plots, each giving e = exp(i(θ − 2πt/T_r)), smoothed
as p ← 0.98 p + e, φ_r = arg p (:class:`AntennaSweep`). Once the estimate is locked (|p| > 5, five
agreeing plots), a plot whose e is more than 0.2 rad from φ_r is not taken: a plot of a rotating antenna
agrees to within its azimuth noise, so one that does not is a reflection, a false plot or a spoofed
record, and a flood of those (a thousand plots at a wrong phase moved φ_r, marked tracks missed and cost
good plots) leaves the phase alone. If a whole revolution passes without a plot that agrees (the radar
restarted with another phase), the next plot starts the estimate again. The sweep itself is one
compiled pass over radars × tracks (:func:`sweep`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from radartracker.compiled import kernel
from radartracker.domain import Radar

TWO_PI = 2.0 * math.pi
LOCKED = 5.0  # |p| above which the phase estimate judges plots
AGREE = math.cos(0.2)  # a plot agrees with the phase within 0.2 rad


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


@kernel
def observe(rows: np.ndarray, t: np.ndarray, terms: np.ndarray, period: np.ndarray, phase: np.ndarray,
            agreed: np.ndarray) -> None:
    """p_r ← 0.98 p_r + e for each plot (radar ``rows[k]``, time ``t[k]``, e = ``terms[k]``) in order, in
    ``phase``; a plot more than 0.2 rad from a locked phase is not taken unless a revolution (``period``)
    passed since ``agreed``, the radar's last plot taken, when the estimate starts again from it."""
    for k in range(rows.shape[0]):
        r, e = rows[k], terms[k]
        p = phase[r]
        size = abs(p)
        if size > LOCKED and (e * p.conjugate()).real < AGREE * size:
            if t[k] - agreed[r] <= period[r]:
                continue
            p = 0j  # a revolution without an agreeing plot: start again
        phase[r] = 0.98 * p + e
        agreed[r] = t[k]


class AntennaSweep:
    """The radars' antenna phases, and which tracks each antenna swept during a frame (module docstring).

    ``xy``: the radars' plane positions (m×2), ``north``: the grid azimuth of true north at each (the
    meridian convergence, rad), in the order of ``radars``."""

    def __init__(self, radars: list[Radar], xy: np.ndarray, north: np.ndarray) -> None:
        self.row = {r.id: k for k, r in enumerate(radars)}
        self.xy, self.north = np.asarray(xy, float).reshape(len(radars), 2), np.asarray(north, float)
        self.period = np.array([r.period_s for r in radars], float)
        self.max_range = np.array([r.max_range_m for r in radars], float)
        self.phase = np.zeros(len(radars), complex)  # p_r
        self.phased = np.zeros(len(radars), bool)  # which radars have had a plot
        self.agreed = np.full(len(radars), -np.inf)  # time of each radar's last plot taken

    def observe(self, rows: np.ndarray, t: np.ndarray, theta: np.ndarray) -> None:
        """Plots of radars ``rows`` at times ``t`` with azimuths ``theta``, in order (module docstring: a plot
        that disagrees with a locked phase is not taken)."""
        terms = np.exp(1j * (theta - TWO_PI * t / self.period[rows]))
        observe(np.ascontiguousarray(rows, np.int64), np.ascontiguousarray(t, float), terms, self.period,
                self.phase, self.agreed)
        self.phased[rows] = True

    def sweep(self, positions: np.ndarray, t_a: float, t_b: float) -> tuple[np.ndarray, np.ndarray]:
        """(swept: radars × tracks, covered: tracks) for tracks at ``positions`` during [t_a, t_b)."""
        n = len(positions)
        start = np.angle(self.phase) + TWO_PI * t_a / self.period
        swept, covered = np.empty((len(self.period), n), bool), np.empty(n, bool)
        sweep(np.ascontiguousarray(positions, float), self.xy, self.north, self.max_range, start,
              TWO_PI * (t_b - t_a) / self.period, self.phased, swept, covered)
        return swept, covered

    def state_dict(self) -> dict:
        return {"phase_re": self.phase.real.tolist(), "phase_im": self.phase.imag.tolist(),
                "phased": self.phased.tolist(), "agreed": self.agreed.tolist()}

    def load_state_dict(self, state: dict) -> None:
        """The state of :meth:`state_dict` (one without ``agreed``, of schema 2: as if no plot had agreed yet, so
        a plot that disagrees starts the estimate again)."""
        re, im = np.asarray(state["phase_re"], float), np.asarray(state["phase_im"], float)
        phased = np.asarray(state["phased"], bool)
        m = len(self.period)
        agreed = np.asarray(state.get("agreed", [-np.inf] * m), float)
        if (re.shape != (m,) or im.shape != (m,) or phased.shape != (m,) or agreed.shape != (m,)
                or not (np.isfinite(re).all() and np.isfinite(im).all()) or np.isnan(agreed).any()):
            raise ValueError(f"antenna phases: {m} finite values expected per radar")
        self.phase, self.phased, self.agreed = re + 1j * im, phased, agreed

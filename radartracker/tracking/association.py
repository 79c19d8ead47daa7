"""Plot-to-track association: gating with the full innovation covariance and GNN assignment.

For plot k of radar j and track t predicted to the plot's time (χ̄_t, P̄_t), with the radar's bias
estimate (ς̂_j, P_ς) from the estimator plugin::

    ν = z_k − (p̄_t + C_k ς̂_j),   S = P̄_pp + C_k P_ς C_kᵀ + R_k,   d² = νᵀ S⁻¹ ν

A pair is admissible when d² ≤ gate (χ²₂ quantile). Global nearest neighbour: the assignment that
minimises Σ (d² + ln det S) over admissible pairs (``scipy.optimize.linear_sum_assignment``);
candidates are found first with a k-d tree on the predicted positions. The assignment is tiered
(:func:`assign_tiers`): confirmed tracks first, tentative ones on what no confirmed track claims.
With Mode C on both sides, d_h² = (h − h̄)²/(P̄_hh + r) of the track's :class:`AltitudeTrack`
gates the pair (χ²₁) and joins the cost. A plot converted at an assumed altitude carries that
uncertainty in R (:func:`altitude_spread`).
"""

from __future__ import annotations

import attrs
import numpy as np

from radartracker.geometry.plane import height_gradient

_INADMISSIBLE = 1e12


def gate_costs(z: np.ndarray, C: np.ndarray, R: np.ndarray, bias: np.ndarray, bias_cov: np.ndarray,
               pos: np.ndarray, pos_cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(d², d² + ln det S) of candidate pairs, given per pair the plot (z, C, R) and the prediction."""
    nu = z - pos - np.einsum("nij,j->ni", C, bias)
    S = pos_cov + C @ bias_cov @ np.swapaxes(C, 1, 2) + R
    det = S[:, 0, 0] * S[:, 1, 1] - S[:, 0, 1] * S[:, 1, 0]
    ok = det > 0
    det = np.where(ok, det, 1.0)
    # explicit 2×2 inverse: d² = (S11 ν0² − 2 S01 ν0 ν1 + S00 ν1²) / det
    d2 = (S[:, 1, 1] * nu[:, 0] ** 2 - (S[:, 0, 1] + S[:, 1, 0]) * nu[:, 0] * nu[:, 1] + S[:, 0, 0] * nu[:, 1] ** 2) / det
    d2 = np.where(ok, d2, np.inf)
    return d2, d2 + np.log(det)


def candidate_pairs(z: np.ndarray, pos: np.ndarray, radius: float, allowed: np.ndarray | None = None) -> np.ndarray:
    """(plot, track) index pairs within ``radius`` metres, optionally masked by ``allowed`` (K, T)."""
    if len(z) == 0 or len(pos) == 0:
        return np.empty((0, 2), int)
    from scipy.spatial import cKDTree  # here: scipy costs 0.3 s to import, a command that lists plugins none

    tree = cKDTree(pos)
    hits = tree.query_ball_point(z, radius)
    pairs = [(k, t) for k, ts in enumerate(hits) for t in ts if allowed is None or allowed[k, t]]
    return np.array(pairs, int).reshape(-1, 2)


def assign(pairs: np.ndarray, d2: np.ndarray, cost: np.ndarray, gate: float) -> list[tuple[int, int]]:
    """Global-nearest-neighbour assignment among gated pairs: list of (plot, track)."""
    keep = d2 <= gate
    pairs, cost = pairs[keep], cost[keep]
    if len(pairs) == 0:
        return []
    plots, p_idx = np.unique(pairs[:, 0], return_inverse=True)
    tracks, t_idx = np.unique(pairs[:, 1], return_inverse=True)
    n_p, n_t = len(plots), len(tracks)
    # one "leave unassigned" column per plot, priced as a pair on the gate boundary, so that a
    # plot is never forced onto a track just to make the matching larger
    M = np.full((n_p, n_t + n_p), _INADMISSIBLE)
    M[p_idx, t_idx] = cost
    log_det = np.full(n_p, np.inf)
    np.minimum.at(log_det, p_idx, cost - d2[keep])
    M[np.arange(n_p), n_t + np.arange(n_p)] = gate + log_det
    from scipy.optimize import linear_sum_assignment

    rows, cols = linear_sum_assignment(M)
    return [(int(plots[r]), int(tracks[c])) for r, c in zip(rows, cols) if c < n_t and M[r, c] < _INADMISSIBLE]


def assign_tiers(pairs: np.ndarray, d2: np.ndarray, cost: np.ndarray, gate: float, tier: np.ndarray,
                 exclusion: float | None = None) -> tuple[dict[int, int], np.ndarray]:
    """GNN in priority tiers: tracks of tier 0 (confirmed, coasting) are assigned the plots they gate
    first; tracks of tier 1 (tentative) compete only for the plots outside every tier-0 gate.

    ``tier`` holds one value per *track index*. Returns {plot: track} and, per plot index up to the
    largest in ``pairs``, whether it lies within d² ≤ ``exclusion`` (default: the gate) of a tier-0
    track: such a plot must not start or feed a tentative track, it belongs to an established
    aircraft whose prediction has fallen behind (a manoeuvre) or is a split plot of it.
    """
    exclusion = gate if exclusion is None else max(exclusion, gate)
    n_plots = int(pairs[:, 0].max()) + 1 if len(pairs) else 0
    first = tier[pairs[:, 1]] == 0 if len(pairs) else np.zeros(0, bool)
    in_gate = np.zeros(n_plots, bool)
    in_gate[pairs[first & (d2 <= exclusion), 0]] = True
    matches = dict(assign(pairs[first], d2[first], cost[first], gate))
    rest = ~first & ~in_gate[pairs[:, 0]] if len(pairs) else first
    matches.update(assign(pairs[rest], d2[rest], cost[rest], gate))
    return matches, in_gate


@attrs.define
class AltitudeTrack:
    """A track's Mode C altitude: Kalman filter of (h, ḣ) with white vertical acceleration.

    Prediction over Δt: h̄ = h + ḣ Δt, P̄ = A P Aᵀ + q_h [[Δt³/3, Δt²/2], [Δt²/2, Δt]]; a Mode C
    report h_k (variance ``MODE_C_VAR``: 100 ft quantisation, (30.48 m)²/12) corrects it. In
    gating, d_h² = (h_k − h̄)² / (P̄_hh + r) is χ²₁ for the track's own plots. The state is held in
    scalars (x = [h, v], P = [[p00, p01], [p01, p11]]): 2×2 numpy arrays per plot cost more than the
    arithmetic.
    """

    time: float
    h: float
    v: float
    p00: float
    p01: float
    p11: float

    @classmethod
    def start(cls, time: float, h: float) -> AltitudeTrack:
        return cls(time, float(h), 0.0, MODE_C_VAR, 0.0, VERTICAL_RATE_SD**2)

    @property
    def x(self) -> np.ndarray:
        """[h, ḣ]."""
        return np.array([self.h, self.v])

    @property
    def P(self) -> np.ndarray:
        """Covariance of [h, ḣ]."""
        return np.array([[self.p00, self.p01], [self.p01, self.p11]])

    def predicted(self, time: float) -> tuple[float, float, float, float, float]:
        """(h̄, ḣ̄, P̄_hh, P̄_hḣ, P̄_ḣḣ) at ``time``."""
        dt = time - self.time
        if dt < 0.0:  # max(dt, 0.0), NaN kept
            dt = 0.0
        p01, p11 = self.p01, self.p11
        return (self.h + self.v * dt, self.v, self.p00 + 2.0 * dt * p01 + dt * dt * p11 + VERTICAL_Q * dt**3 / 3,
                p01 + dt * p11 + VERTICAL_Q * dt**2 / 2, p11 + VERTICAL_Q * dt)

    def predict(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        h, v, p00, p01, p11 = self.predicted(time)
        return np.array([h, v]), np.array([[p00, p01], [p01, p11]])

    def update(self, time: float, h: float) -> None:
        """Correct the track with a Mode C report ``h`` at ``time`` (:meth:`predicted` written out)."""
        t0 = self.time
        dt = time - t0
        if dt < 0.0:
            dt = 0.0
        v, p01, p11 = self.v, self.p01, self.p11
        hp = self.h + v * dt
        p00 = self.p00 + 2.0 * dt * p01 + dt * dt * p11 + VERTICAL_Q * dt**3 / 3
        p01 = p01 + dt * p11 + VERTICAL_Q * dt**2 / 2
        p11 = p11 + VERTICAL_Q * dt
        s = p00 + MODE_C_VAR
        k0, k1, e = p00 / s, p01 / s, h - hp
        self.h, self.v = hp + k0 * e, v + k1 * e
        self.p00, self.p01, self.p11 = p00 - k0 * p00, 0.5 * ((p01 - k0 * p01) + (p01 - k1 * p00)), p11 - k1 * p01
        if not t0 > time:  # max(time, t0)
            self.time = time


MODE_C_VAR = 30.48**2 / 12  # 100 ft Mode C quantisation
ADSB_ALTITUDE_VAR = 7.62**2 / 12  # 25 ft ADS-B barometric altitude quantisation (DO-260B, Q bit set)
VERTICAL_RATE_SD = 20.0  # m/s, a new track's vertical rate (4000 ft/min)
VERTICAL_Q = 4.0  # m²/s³, white vertical acceleration
ALTITUDE_GATE = 10.83  # χ²₁ 99.9 %


def altitude_d2(h_plot: np.ndarray, tracks: list[AltitudeTrack | None], times: np.ndarray) -> np.ndarray:
    """d_h² of each (plot altitude, track altitude filter, time) pair; NaN where either is missing."""
    out = np.full(len(h_plot), np.nan)
    for n, (h, trk, t) in enumerate(zip(h_plot, tracks, times)):
        if trk is not None and np.isfinite(h):
            hp, _, p00, _, _ = trk.predicted(t)
            out[n] = (h - hp) ** 2 / (p00 + MODE_C_VAR)
    return out


def altitude_spread(C: np.ndarray, rho: np.ndarray, alt: np.ndarray, radar_height_m, sd_m) -> np.ndarray:
    """Covariance added to a plot converted at an *uncertain* altitude (σ_h = ``sd_m``, one or one per plot):
    g gᵀ σ_h², g = ∂z/∂h (:func:`~radartracker.geometry.plane.height_gradient`)."""
    g = height_gradient(C, rho, alt, radar_height_m)
    return np.reshape(np.asarray(sd_m, float) ** 2, (-1, 1, 1)) * g[:, :, None] * g[:, None, :]

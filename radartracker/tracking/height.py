"""Heights of tracks whose plots carry no altitude, estimated from the slant ranges of the radars that see them.

A plot without altitude is converted to the plane at an assumed height h_c. At fixed slant range ρ and azimuth
its plane position moves with the height along the radar's line of sight, z(h) ≈ z(h_c) + g (h − h_c),
g = ∂z/∂h (:func:`~radartracker.geometry.plane.height_gradient`; about 0.1 at 100 km for an airliner at
cruise), and with the radar's range bias b along the same line, c = ∂z/∂ρ (C_s's range column). A radar's
plots alone cannot tell a wrong height from a shifted position or a range bias; several radars can, but only
together with their range biases: each aircraft seen by radar j gives the along-beam offset b_j + k δh
(k = |g|/|c| varies with the range), and the biases are shared by every aircraft a radar sees. Hence two parts:

**Per track**, a :class:`HeightFilter`: a Kalman filter of s = [x, y, vx, vy, h, b_1 … b_m] (b_j the range
bias of each radar that has seen the track, prior N(0, σ_b²), σ_b the bias estimator's range prior; h prior
N(h₀, σ₀²) = (``primary_altitude_m``, ``primary_altitude_sd_m``)), fed the track's plots corrected for their
radar's azimuth bias only (range uncorrected):

    predict:  s̄ = F s, P̄ = F P Fᵀ + Q; F constant velocity, h and b constant;
              Q = q [[Δt³/3 I, Δt²/2 I], [Δt²/2 I, Δt I]] ⊕ q_h Δt ⊕ 0
    measure:  z = p − g (h − h_c) + c b_j + v,  H = [I₂ 0₂ −g 0 … c … 0],  ν = z − p̄ + g (h̄ − h_c) − c b̄_j,
              R = C_s W C_sᵀ + P_θθ c_θ c_θᵀ + ¾ σ_c⁴ g₂ g₂ᵀ
    correct:  K = P̄ Hᵀ S⁻¹, S = H P̄ Hᵀ + R, s = s̄ + K ν, P = P̄ − K S Kᵀ

(g₂ = ∂²z/∂h² ≈ −c/ρ: the variance of the neglected second-order term ½ g₂ δ² for a conversion height of
σ σ_c). The first plot starts it, p̂ = z + g (h₀ − h_c), P_pp = R + g gᵀ σ₀² + c cᵀ σ_b², P_ph = g σ₀²,
P_pb = −c σ_b².

**Jointly**, every ``solve_every_s`` (:func:`joint_heights`): each filter's information on (h, b) without its
prior on b, J = (P_hb)⁻¹ − diag(0, I/σ_b²), its h eliminated (Schur complement), summed over the tracks with the
prior on b put back once, gives the range biases b̂, P_b; each track's height ĥ = (i_h − J_hb b̂)/J_hh with
σ_h² = 1/J_hh + w P_b wᵀ, w = J_hb/J_hh. This is the first-order Gauss–Markov estimate of all heights and
range biases together; a height is *observable* when σ_h ≤ ``observable_sd_m``.

:class:`HeightEstimator` is the manager's stage. After association (:meth:`~HeightEstimator.refine`) it runs
the joint solve when a period ends and converts again, in one vectorised pass, the frame's plots without
altitude that association gave to a track with a height, at that height (the linearisation point); where the
height is observable those rows replace the frame's, with R = C_s W C_sᵀ + g gᵀ σ_h², so that screening, the
track filter and the bias estimator use them. When the life cycle has used a plot (:meth:`~HeightEstimator.took`)
its track's filter is updated or started. A filter's first plots were converted at the assumed height, up to
5 km from the aircraft's (a linearisation error ½ |g₂| δ² of about 150 m at 70 km, always of one sign): after
the first joint solve it starts again, from the same prior, with plots converted at its first height. A track
that reports an altitude (Mode C, ADS-B) has no height filter.
"""

from __future__ import annotations

import math
from operator import attrgetter
from typing import NamedTuple

import attrs
import numpy as np

from radartracker.compiled import kernel
from radartracker.domain import AdsbReport, Plot
from radartracker.geometry.plane import height_gradient

_RANGE = attrgetter("range_m")


@attrs.frozen
class HeightConfig:
    """The height estimate of tracks without altitude (module docstring): ``enabled``; ``q`` (m²/s³) the
    white horizontal acceleration of its filters; ``q_height`` (m²/s) the height's random walk;
    ``observable_sd_m``: the σ_h below which a
    height is used and reported; ``solve_every_s``: the period of the joint solve; ``gate``: the d² (χ²₂ 99.9 %)
    beyond which a plot does not update a height filter (a manoeuvre its constant velocity does not follow, a
    wrong plot), ``restart_after`` such plots in a row start it again; ``population_min``: the observable heights
    it takes to convert the other tracks' plots at their mean (:meth:`HeightEstimator._population`);
    ``prior_sd_velocity_mps``."""

    enabled: bool = True
    q: float = attrs.field(default=5.0, validator=attrs.validators.ge(0.0))
    q_height: float = attrs.field(default=100.0, validator=attrs.validators.ge(0.0))
    observable_sd_m: float = attrs.field(default=1000.0, validator=attrs.validators.gt(0.0))
    solve_every_s: float = attrs.field(default=10.0, validator=attrs.validators.gt(0.0))
    gate: float = attrs.field(default=13.82, validator=attrs.validators.gt(0.0))
    restart_after: int = attrs.field(default=3, validator=attrs.validators.ge(1))
    population_min: int = attrs.field(default=5, validator=attrs.validators.ge(2))
    prior_sd_velocity_mps: float = attrs.field(default=300.0, validator=attrs.validators.gt(0.0))


class PlotRow(NamedTuple):
    """A plot as a height filter uses it: z (2) corrected for its radar's azimuth bias only; R (2×2) with that
    bias's variance and the second-order term's, ¾ σ_c⁴ g₂ g₂ᵀ (σ_c the σ of the conversion height); g = ∂z/∂h;
    c = ∂z/∂ρ (C_s's range column); the conversion height h_c."""

    z: np.ndarray
    R: np.ndarray
    g: np.ndarray
    c: np.ndarray
    h_c: float


@attrs.define(eq=False)
class HeightFilter:
    """Kalman filter of s = [x, y, vx, vy, h, b₁ … b_m] (module docstring) at ``time``: ``radars`` the radar row
    of each range bias b_j; ``q``, ``q_height`` its noise; ``fix`` the track's height (ĥ, σ_h, time) of the last
    joint solve (:func:`joint_heights`), None before one."""

    time: float
    s: np.ndarray
    P: np.ndarray
    radars: list[int]
    q: float
    q_height: float
    fix: tuple[float, float, float] | None = None
    settled: bool = False
    misses: int = 0

    @classmethod
    def start(cls, time: float, row: PlotRow, radar: int, sd_b: float, h0: float, sd0: float,
              config: HeightConfig) -> HeightFilter:
        """From the first plot, of radar row ``radar`` (range bias b ~ N(0, ``sd_b``²)), converted at h_c, the
        height h ~ N(``h0``, ``sd0``²): p = z + g (h − h_c) − c b, p̂ = z + g (h₀ − h_c)."""
        z, R, g, c, h_c = row
        var, vb = sd0**2, sd_b**2
        P = np.zeros((6, 6))
        P[:2, :2] = R + var * np.outer(g, g) + vb * np.outer(c, c)
        P[:2, 4] = P[4, :2] = var * g
        P[:2, 5] = P[5, :2] = -vb * c
        P[2, 2] = P[3, 3] = config.prior_sd_velocity_mps**2
        P[4, 4], P[5, 5] = var, vb
        p = z + g * (h0 - h_c)
        return cls(float(time), np.array([p[0], p[1], 0.0, 0.0, h0, 0.0]), P, [radar], config.q, config.q_height)

    def height(self, time: float) -> tuple[float, float]:
        """(ĥ, σ_h) of the last joint solve predicted to ``time`` (never backwards); (NaN, ∞) before one."""
        if self.fix is None:
            return math.nan, math.inf
        h, sd, t = self.fix
        return h, math.sqrt(sd * sd + self.q_height * max(time - t, 0.0))

    def update(self, time: float, row: PlotRow, radar: int, sd_b: float, gate: float = math.inf) -> float:
        """Correct with a plot of radar row ``radar`` (a radar new to the track adds its b ~ N(0, ``sd_b``²));
        returns the normalised innovation d² = νᵀ S⁻¹ ν. Where d² > ``gate`` the filter is only predicted (and
        ``misses`` counts it; an accepted plot resets it); ValueError where S is not positive definite."""
        if radar not in self.radars:
            n = len(self.s)
            self.radars.append(radar)
            self.s = np.append(self.s, 0.0)
            P = np.zeros((n + 1, n + 1))
            P[:n, :n], P[n, n] = self.P, sd_b**2
            self.P = P
        _predict(self.s, self.P, max(time - self.time, 0.0), self.q, self.q_height)
        self.time = max(self.time, float(time))
        d2 = _correct(self.s, self.P, 5 + self.radars.index(radar), row.z, row.R, row.g, row.c, row.h_c, gate,
                      np.empty((len(self.s), 4)))
        if d2 < 0.0:
            raise ValueError("height: innovation covariance not positive definite")
        self.misses = self.misses + 1 if d2 > gate else 0
        return d2

    def state(self) -> list[float]:
        """[time, m, radar rows (m), ĥ, σ_h, time of the fix (NaN: none), settled (0 or 1), misses, s (5 + m),
        P ((5 + m)², row by row)], the snapshot's form."""
        fix = self.fix or (math.nan, math.nan, math.nan)
        return [self.time, len(self.radars), *self.radars, *fix, float(self.settled), float(self.misses),
                *self.s.tolist(), *self.P.ravel().tolist()]

    @classmethod
    def of_state(cls, values: list[float], radars: int, config: HeightConfig) -> HeightFilter:
        """The filter of :meth:`state`'s list, for a manager of ``radars`` radars (ValueError where it is not one:
        its sizes, radar rows or a covariance not positive definite)."""
        v = np.asarray(values, float)
        m = int(v[1]) if len(v) > 1 and np.isfinite(v[1]) and 0 < v[1] <= radars else -1
        n = 5 + m
        fixed = np.delete(v, [2 + m, 3 + m, 4 + m]) if m >= 1 else v  # the fix may be NaN (none yet)
        if m < 1 or v[1] != m or len(v) != 7 + m + n + n * n or not np.isfinite(fixed).all():
            raise ValueError("height: [time, m, radar rows, fix (3), settled, misses, s, P] of finite numbers expected")
        rows = v[2:2 + m]
        if np.any(rows != np.round(rows)) or np.any(rows < 0) or np.any(rows >= radars) or len(set(rows)) != m:
            raise ValueError("height: radar rows must be distinct rows of the manager's radars")
        P = v[7 + m + n:].reshape(n, n)
        if not np.allclose(P, P.T) or np.any(np.linalg.eigvalsh(0.5 * (P + P.T)) <= 0.0):
            raise ValueError("height: covariance not positive definite")
        fix = tuple(v[2 + m:5 + m].tolist())
        fix = fix if np.isfinite(fix).all() and fix[1] > 0.0 else None
        misses = int(v[6 + m]) if v[6 + m] == round(v[6 + m]) and v[6 + m] >= 0 else -1
        if misses < 0:
            raise ValueError("height: misses must be a count")
        return cls(float(v[0]), v[7 + m:7 + m + n].copy(), P.copy(), [int(r) for r in rows], config.q,
                   config.q_height, fix, bool(v[5 + m]), misses)


def _by_size(filters: list[HeightFilter]) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """The filters grouped by their number of radars m: (their positions in ``filters``, radar rows (g × m),
    the information J = (P_hb)⁻¹ (g × (1 + m) × (1 + m)), i = J (ĥ, b̂) (g × (1 + m))), one batched inverse a group."""
    sizes: dict[int, list[int]] = {}
    for k, f in enumerate(filters):
        sizes.setdefault(len(f.radars), []).append(k)
    out = []
    for members in sizes.values():
        P = np.stack([filters[k].P[4:, 4:] for k in members])
        J = np.linalg.inv(P)
        s = np.stack([filters[k].s[4:] for k in members])
        out.append((np.array(members), np.array([filters[k].radars for k in members]), J, np.einsum("gij,gj->gi", J, s)))
    return out


def joint_heights(filters: list[HeightFilter], radars: int, sd_b: float
                  ) -> tuple[np.ndarray, np.ndarray, list[tuple[float, float]]]:
    """The range biases b (``radars``) with their covariance, and each filter's (ĥ, σ_h), from every filter's
    information on its (h, b) with the biases' prior N(0, ``sd_b``²) taken out once per filter and put back once
    in all (module docstring): J = (P_hb)⁻¹ − diag(0, I/σ_b²), i = (P_hb)⁻¹ (ĥ, b̂); each track's h eliminated,
    Λ = I/σ_b² + Σ (J_bb − J_bh J_hb / J_hh), η = Σ (i_b − J_bh i_h / J_hh), b̂ = Λ⁻¹ η, P_b = Λ⁻¹; then
    ĥ = (i_h − J_hb b̂)/J_hh, σ_h² = 1/J_hh + w P_b wᵀ, w = J_hb/J_hh ((NaN, ∞) where J_hh ≤ 0)."""
    lam = np.eye(radars) / sd_b**2
    eta = np.zeros(radars)
    h_free, var = np.full(len(filters), math.nan), np.full(len(filters), math.inf)
    parts = []
    for members, idx, J, i in _by_size(filters):  # the filters of one size, their information stacked
        J[:, 1:, 1:] -= np.eye(idx.shape[1]) / sd_b**2
        ok = J[:, 0, 0] > 0.0
        members, idx, J, i = members[ok], idx[ok], J[ok], i[ok]
        jhh = J[:, 0, 0]
        w = J[:, 0, 1:] / jhh[:, None]
        np.add.at(lam, (idx[:, :, None], idx[:, None, :]), J[:, 1:, 1:] - J[:, 1:, :1] * w[:, None, :])
        np.add.at(eta, idx, i[:, 1:] - J[:, 1:, 0] * (i[:, 0] / jhh)[:, None])
        h_free[members], var[members] = i[:, 0] / jhh, 1.0 / jhh
        parts.append((members, idx, w))
    Pb = np.linalg.inv(lam)
    b = Pb @ eta
    h, sd = h_free, np.sqrt(var)
    for members, idx, w in parts:
        h[members] -= np.einsum("gk,gk->g", w, b[idx])
        sd[members] = np.sqrt(var[members] + np.einsum("gk,gkl,gl->g", w, Pb[idx[:, :, None], idx[:, None, :]], w))
    heights = [(float(a), float(s)) if math.isfinite(s) else (math.nan, math.inf) for a, s in zip(h, sd)]
    return b, Pb, heights


class HeightEstimator:
    """The frame's stage that estimates and feeds back the heights of tracks without altitude (module
    docstring). ``converter``: the manager's :class:`~radartracker.tracking.prepared.PlaneConverter`;
    ``bias(radar)``: (ς̂, P_ς) as the frame reads them; ``prior_m``, ``prior_sd_m``: the assumed height;
    ``range_bias_sd_m``: σ_b, the bias estimator's prior σ of a range bias (one prior for one quantity)."""

    def __init__(self, converter, config: HeightConfig, prior_m: float, prior_sd_m: float, bias,
                 range_bias_sd_m: float) -> None:
        self.converter, self.config, self.bias = converter, config, bias
        self.sd_b = float(range_bias_sd_m)
        self.prior_m, self.prior_sd_m = float(prior_m), float(prior_sd_m)
        self.rows: tuple[np.ndarray, ...] | None = None  # the frame's plots: guessed, radar, z, R, g, c, h_c

    def refine(self, frame, updates: list, tracks: list) -> None:
        """At the end of each ``solve_every_s`` period, the joint solve (:func:`joint_heights`) over ``tracks``;
        then keep the plane rows of the frame's plots converted at an assumed height, and convert those of them
        that association gave to a track with a height again, at that height ĥ; where it is observable write
        them into ``frame.meas`` with R = C_s W C_sᵀ + g gᵀ σ_h²."""
        if not self.config.enabled:
            self.rows = None
            return
        every = self.config.solve_every_s
        if math.floor(frame.end / every) > math.floor(frame.start / every):
            self._solve(tracks, frame.end)
        guessed = frame.guessed
        if not guessed.any():
            self.rows = None
            return
        n, meas, conv = len(guessed), frame.meas, self.converter
        z, C, radar = meas.z[:n].copy(), meas.C[:n].copy(), meas.radar[:n]
        h_c, sd_c = frame.height.copy(), np.full(n, self.prior_sd_m)
        at = frame.linearised_at  # the bias estimate each plot is converted at (radartracker.tracking.frame)
        rho = np.fromiter(map(_RANGE, frame.plots), float, n)
        todo = self._heights(updates, guessed, self._population(tracks))
        if todo:
            rows, h, sd = (np.array(v) for v in zip(*todo))
            z2, C2, _, ok = conv.convert(radar[rows], rho[rows], frame.azimuth[rows], h, at=at[rows])
            rows, h, sd = rows[ok], h[ok], sd[ok]
            z[rows], C[rows], h_c[rows], sd_c[rows] = z2[ok], C2[ok], h, sd
        rho = rho - at[:, 0]  # the slant range the plots were converted at, for g and g₂
        R = C @ conv.W[radar] @ np.swapaxes(C, 1, 2)
        g = height_gradient(C, rho, h_c, conv.height[radar])
        if todo:
            meas.z[rows], meas.C[rows] = z[rows], C[rows]
            meas.R[rows] = R[rows] + sd[:, None, None] ** 2 * g[rows, :, None] * g[rows, None, :]
        self.rows = (guessed, radar, *self._corrected(radar, z, C, R, rho, sd_c), g, C[:, :, 0].copy(), h_c)

    def _corrected(self, radar: np.ndarray, z: np.ndarray, C: np.ndarray, R: np.ndarray, rho: np.ndarray,
                   sd_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(z − c_θ Δθ̂, R + P_θθ c_θ c_θᵀ + ¾ σ_c⁴ g₂ g₂ᵀ): the plots corrected for their radars' azimuth biases
        only, g₂ = ∂²z/∂h² ≈ −c/ρ the second-order term (module docstring)."""
        ids = self.converter.ids
        b, var = np.zeros(len(ids)), np.zeros(len(ids))
        for r in np.unique(radar).tolist():
            bias, cov = self.bias(ids[r])
            b[r], var[r] = bias[1], cov[1, 1]
        ca = C[:, :, 1]
        g2 = -C[:, :, 0] / np.maximum(rho, 1.0)[:, None]
        Rc = R + var[radar][:, None, None] * ca[:, :, None] * ca[:, None, :]
        Rc += (0.75 * sd_c**4)[:, None, None] * g2[:, :, None] * g2[:, None, :]
        return z - ca * b[radar][:, None], Rc

    def _heights(self, updates: list, guessed: np.ndarray, pop: tuple[float, float] | None
                 ) -> list[tuple[int, float, float]]:
        """(row, height, σ) to convert the frame's plots at an assumed height again at: their track's height
        where observable, else the population's ``pop`` (:meth:`_population`) for a plot of a known track."""
        n, limit = len(guessed), self.config.observable_sd_m
        out = []
        for u in updates:
            if u.row >= n or not guessed[u.row] or u.track is None:
                continue
            f = u.track.height
            h, sd = (math.nan, math.inf) if f is None else f.height(u.time)
            if sd <= limit:
                out.append((u.row, h, sd))
            elif pop is not None:
                out.append((u.row, *pop))
        return out

    def _solve(self, tracks: list, now: float) -> None:
        """The joint solve over the tracks' height filters; each track's ``fix``, ``altitude_m`` and ``altitude_sd_m``."""
        owners = [tr for tr in tracks if tr.height is not None]
        if not owners:
            return
        cfg = self.config
        _, _, heights = joint_heights([tr.height for tr in owners], len(self.converter.ids), self.sd_b)
        for tr, (h, sd) in zip(owners, heights):
            tr.height.fix = (h, sd, now) if math.isfinite(sd) else None
            tr.altitude_m, tr.altitude_sd_m = (h, sd) if sd <= cfg.observable_sd_m else (None, None)

    def _population(self, tracks: list) -> tuple[float, float] | None:
        """The population's height: the mean ĥ of the tracks' observable heights of the last joint solve, with σ²
        their variance plus their mean σ_h², where there are ``population_min`` of them and that σ is below
        ``primary_altitude_sd_m``; else None."""
        limit = self.config.observable_sd_m
        seen = [tr.height.fix[:2] for tr in tracks if tr.height is not None and tr.height.fix is not None
                and tr.height.fix[1] <= limit]
        if len(seen) < self.config.population_min:
            return None
        h, sd = np.array(seen).T
        spread = math.sqrt(float(np.var(h) + np.mean(sd**2)))
        return (float(np.mean(h)), spread) if spread < self.prior_sd_m else None

    def took(self, tr, u) -> None:
        """The life cycle used measurement ``u`` on track ``tr``: a plot converted at an assumed height
        updates (or starts) the track's height filter; a reported altitude ends it."""
        src = u.source
        if isinstance(src, AdsbReport):
            if src.altitude_m is not None:
                tr.height = None
            return
        if not isinstance(src, Plot) or self.rows is None:
            return
        if tr.vertical is not None or tr.n_adsb:  # the track has reported altitudes
            tr.height = None
            return
        guessed, radar, z, R, g, c, h_c = self.rows
        k = u.row
        if not guessed[k]:
            return
        row = PlotRow(z[k], R[k], g[k], c[k], float(h_c[k]))
        sd_b, filt = self.sd_b, tr.height
        restart = filt is not None and (filt.misses >= self.config.restart_after
                                        or not filt.settled and filt.fix is not None)
        if filt is None or restart:  # (re)start: see the module docstring
            tr.height = HeightFilter.start(src.time, row, int(radar[k]), sd_b, self.prior_m, self.prior_sd_m,
                                           self.config)
            if filt is not None:
                tr.height.fix, tr.height.settled = filt.fix, True
        else:
            try:
                filt.update(src.time, row, int(radar[k]), sd_b, self.config.gate)
            except ValueError:
                tr.height = None


@kernel
def _predict(s: np.ndarray, P: np.ndarray, dt: float, q: float, q_height: float) -> None:
    """s ← F s, P ← F P Fᵀ + Q in place (module docstring; F adds Δt·v to the position)."""
    if dt <= 0.0:
        return
    n = s.shape[0]
    s[0] += dt * s[2]
    s[1] += dt * s[3]
    for k in range(n):
        P[0, k] += dt * P[2, k]
        P[1, k] += dt * P[3, k]
    for k in range(n):
        P[k, 0] += dt * P[k, 2]
        P[k, 1] += dt * P[k, 3]
    for a in range(2):
        P[a, a] += q * dt**3 / 3
        P[a, a + 2] += q * dt**2 / 2
        P[a + 2, a] += q * dt**2 / 2
        P[a + 2, a + 2] += q * dt
    P[4, 4] += q_height * dt


@kernel
def _correct(s: np.ndarray, P: np.ndarray, j: int, z: np.ndarray, R: np.ndarray, g: np.ndarray, c: np.ndarray,
             h_c: float, gate: float, work: np.ndarray) -> float:
    """The measurement update of the module docstring in place, H = [I₂ 0 −g 0 … c (column j) … 0]:
    P Hᵀ into ``work[:, :2]``, K = P Hᵀ S⁻¹ into ``work[:, 2:]``, s ← s + K ν, P ← P − K (P Hᵀ)ᵀ (symmetrised).
    Returns d² = νᵀ S⁻¹ ν (nothing changed where it exceeds ``gate``), or −1 (nothing changed) where S is not
    positive definite."""
    n = s.shape[0]
    g0, g1, c0, c1 = g[0], g[1], c[0], c[1]
    r00, r01, r11 = R[0, 0], 0.5 * (R[0, 1] + R[1, 0]), R[1, 1]
    for i in range(n):
        work[i, 0] = P[i, 0] - P[i, 4] * g0 + P[i, j] * c0
        work[i, 1] = P[i, 1] - P[i, 4] * g1 + P[i, j] * c1
    d = s[4] - h_c
    nu0 = z[0] - s[0] + g0 * d - c0 * s[j]
    nu1 = z[1] - s[1] + g1 * d - c1 * s[j]
    s00 = work[0, 0] - g0 * work[4, 0] + c0 * work[j, 0] + r00
    s01 = work[0, 1] - g0 * work[4, 1] + c0 * work[j, 1] + r01
    s10 = work[1, 0] - g1 * work[4, 0] + c1 * work[j, 0] + r01
    s11 = work[1, 1] - g1 * work[4, 1] + c1 * work[j, 1] + r11
    b = 0.5 * (s01 + s10)
    det = s00 * s11 - b * b
    if not (det > 0.0 and s00 > 0.0):
        return -1.0
    i00, i01, i11 = s11 / det, -b / det, s00 / det
    d2 = nu0 * (i00 * nu0 + i01 * nu1) + nu1 * (i01 * nu0 + i11 * nu1)
    if d2 > gate:
        return d2
    for i in range(n):
        work[i, 2] = work[i, 0] * i00 + work[i, 1] * i01
        work[i, 3] = work[i, 0] * i01 + work[i, 1] * i11
    for i in range(n):
        s[i] += work[i, 2] * nu0 + work[i, 3] * nu1
    for i in range(n):
        for k in range(n):
            P[i, k] -= work[i, 2] * work[k, 0] + work[i, 3] * work[k, 1]
    for i in range(n):
        for k in range(i + 1, n):
            P[i, k] = P[k, i] = 0.5 * (P[i, k] + P[k, i])
    return d2

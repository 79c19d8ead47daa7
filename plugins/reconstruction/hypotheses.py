"""Multi-hypothesis reconstruction of one flight (seed 000 §2, DESIGN §7).

1. **Change detection.** A tuned RTS smoother with an outlier gate (:mod:`.smoother`) gives velocities; on a uniform
   grid the controls follow from the model: u = v φ̇, w = v̇ (seed eq. 2.1), moving-averaged over
   dt_min.
2. **Segmentations.** For every segment count K the least-squares piecewise-constant fit of
   (u, w) with segments ≥ dt_min is found exactly by dynamic programming (Bellman 1961; Jackson
   et al. 2005). The starting count K₀ minimises a noise-aware BIC of the signal
   (:func:`noise_aware_count`: whitened by a robust noise estimate, with the effective number of
   independent samples). Starts: K₀, always 1, 2 and 3 segments (whatever the budget), K₀/1.5 and
   1.5·K₀ (switch times, and (u, w) as the pieces' means).
   Then moves from the best hypothesis by score that has one left: a **split** of its
   worst-fitting segments to 1.5× as many (the same track; if the window pass loses the start's
   fit, the start is refined by least squares alone, so the weight never rises) — climbing on
   from the child while its weight drops by at least a quarter of what BIC charges for its new
   parameters — or a **merge** of its most alike neighbours to 1/1.5 as many (refitted). Split is
   tried first when the hypothesis's normalised χ² exceeds 1. The search stops after two moves in
   a row that do not improve the best score, or at ``hypotheses`` fits in all (1–3 segments aside).
3. **Optimisation** of each hypothesis by Hooke–Jeeves and a least-squares refinement (:mod:`.fit`).
4. **Selection** by the Bayesian information criterion on the plots:
   score = 2·weight + complexity · p · ln n, with p = 3K + 3 parameters (initial x, y, φ, v;
   K pairs (u, w); K − 1 switch times) and n plots. All hypotheses are kept, ranked by score.
"""

from __future__ import annotations

import attrs
import numpy as np

from radartracker_plugins.reconstruction.biases import debias
from radartracker_plugins.reconstruction.config import ReconstructionConfig
from radartracker_plugins.reconstruction.fit import fit_hypothesis, jump_prior
from radartracker_plugins.reconstruction.integrate import geo_track, sample
from radartracker_plugins.reconstruction.objects import (
    ControlSegment, ControlTrack, GeoPoint, GeoTrack, PlotTrack)
from radartracker_plugins.reconstruction.smoother import gated_rts
from radartracker_plugins.reconstruction.weight import TrackWeight

_MAX_GRID = 1000  # grid points for change detection (the DP is O(K N²))


@attrs.frozen
class Hypothesis:
    """One optimised hypothesis: its control track, weight (NLL), score (BIC), cost, and where its
    start came from (the change-point segmentation, or a split of a better hypothesis)."""

    control: ControlTrack
    weight: float
    score: float
    n_params: int
    nfev: int
    origin: str = ""
    chi2: float = float("nan")  # normalised residual χ²: Σ d_i² / (2n − p), ≈ 1 when the model and R hold


@attrs.frozen(eq=False)
class Reconstruction:
    """A flight's reconstruction: the selected hypothesis, all hypotheses ranked by score,
    the geometric track of the best one, the tuned smoother's q (m²/s³), the starting count K₀
    and its criterion per K (:func:`noise_aware_count`). ``plots`` are the plots fitted (known
    radar biases already removed)."""

    key: str
    plots: PlotTrack
    hypotheses: tuple[Hypothesis, ...]
    geo: GeoTrack
    smoother_q: float
    k0: int = 0
    count_criterion: tuple[float, ...] = ()

    @property
    def best(self) -> Hypothesis:
        return self.hypotheses[0]

    @property
    def control(self) -> ControlTrack:
        return self.geo.control


def control_signals(t: np.ndarray, xs: np.ndarray, grid_dt: float, window: float) -> tuple[np.ndarray, np.ndarray]:
    """Grid times and (u, w) (N, 2) from smoothed states ``xs`` = [x, y, vx, vy] at times ``t``."""
    tg = np.arange(t[0], t[-1] + 1e-9, grid_dt)
    vx, vy = np.interp(tg, t, xs[:, 2]), np.interp(tg, t, xs[:, 3])
    v = np.maximum(np.hypot(vx, vy), 1.0)
    phi = np.unwrap(np.arctan2(vx, vy))
    sig = np.column_stack([v * np.gradient(phi, grid_dt), np.gradient(v, grid_dt)])
    m = max(1, int(round(window / grid_dt)))
    if m > 1 and len(tg) > m:
        kernel = np.ones(m) / m
        pad = np.pad(sig, ((m // 2, m - 1 - m // 2), (0, 0)), mode="edge")
        sig = np.column_stack([np.convolve(pad[:, j], kernel, mode="valid") for j in range(2)])
    return tg, sig


def segmentations(sig: np.ndarray, min_len: int, k_max: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """Least-squares optimal split of ``sig`` (N, d) into K = 1…k_max pieces of ≥ ``min_len`` samples.

    Returns the residual sums of squares SSE_K and, per K, the start indices of pieces 2…K.
    """
    N = len(sig)
    k_max = max(1, min(k_max, N // min_len))
    S1 = np.vstack([np.zeros(sig.shape[1]), np.cumsum(sig, axis=0)])
    S2 = np.concatenate([[0.0], np.cumsum((sig * sig).sum(axis=1))])
    i, j = np.arange(N + 1)[:, None], np.arange(N + 1)[None, :]
    length = np.maximum(j - i, 1)
    d1 = S1[None, :, :] - S1[:, None, :]
    cost = S2[None, :] - S2[:, None] - (d1 * d1).sum(axis=2) / length
    cost[(j - i) < min_len] = np.inf
    D = cost[0].copy()
    back, sse = [], [D[N]]
    for _ in range(1, k_max):
        tot = D[:, None] + cost
        arg = np.argmin(tot, axis=0)
        D = tot[arg, np.arange(N + 1)]
        back.append(arg)
        sse.append(D[N])
    starts = [np.array([], int)]
    for K in range(2, k_max + 1):
        idx, end = [], N
        for k in range(K - 1, 0, -1):
            end = back[k - 1][end]
            idx.append(end)
        starts.append(np.array(idx[::-1], int))
    return np.array(sse), starts


def noise_aware_count(sig: np.ndarray, g: float, tau: float, min_len: int, k_fit: int) -> tuple[int, np.ndarray, list]:
    """(K₀, criterion per K, segmentation starts) of the control signal ``sig`` on a grid of ``g`` s.

    The signal's noise is correlated over ``tau`` seconds (the smoother's memory), so it holds about
    N_eff = N·g/τ independent samples. Each channel's noise σ_c is estimated robustly from
    differences at lag τ (1.4826·MAD/√2, insensitive to the few control jumps), the signal is
    whitened by it, and K₀ minimises the known-variance BIC of the whitened signal::

        crit(K) = SSE_K · N_eff / N + 3K · ln N_eff

    (3 parameters per segment: the two means and a switch time). The scale-free form
    N·ln(SSE_K/N) assumes independent samples and, on a smoother's correlated output, buys
    a segment for every wiggle (22 on a straight flight).
    """
    N = len(sig)
    lag = int(min(max(1, round(tau / g)), max(1, N // 2)))
    d = sig[lag:] - sig[:-lag] if N > lag else np.diff(sig, axis=0)
    sd = 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0) / np.sqrt(2)
    sd = np.where(sd > 0, sd, np.maximum(sig.std(axis=0), 1e-9))
    sse, starts = segmentations(sig / sd, min_len, k_fit)
    n_eff = max(N * g / tau, 2.0)
    K_all = np.arange(1, len(sse) + 1)
    crit = sse * n_eff / N + 3 * K_all * np.log(n_eff)
    return int(K_all[np.argmin(crit)]), crit, starts


def hypothesis_starts(plots: PlotTrack, cfg: ReconstructionConfig):
    """(start(K) → starting control track with K segments, the detected K₀, the largest K, the smoother's q,
    the starting-count criterion per K)."""
    xs, q, keep = gated_rts(plots.t, plots.z, plots.R)
    t = plots.t[keep]
    dur = t[-1] - t[0]
    g = max(cfg.dt_min / 2, dur / _MAX_GRID)
    tg, sig = control_signals(t, xs, g, cfg.dt_min)
    k_fit = max(1, min(cfg.max_segments, int(dur // cfg.dt_min), int(plots.duration // cfg.dt_min)))
    # the smoother's memory: a CV smoother with white-acceleration density q and measurement noise
    # density r (m²·s) averages over about (r/q)^¼ seconds; never less than the moving average
    r_density = float(np.sqrt(np.mean(np.linalg.det(plots.R[keep])))) * dur / max(len(t) - 1, 1)
    tau = max(cfg.dt_min, (r_density / q) ** 0.25)
    # one grid step more than dt_min, so no starting switch sits on the minimum-duration constraint
    k0, crit, starts = noise_aware_count(sig, g, tau, int(np.ceil(cfg.dt_min / g)) + 1, k_fit)
    N = len(sig)
    back = t[0] - plots.t[0]  # the first plot may have been gated out
    first = GeoPoint(plots.t[0], xs[0, 0] - back * xs[0, 2], xs[0, 1] - back * xs[0, 3],
                     np.arctan2(xs[0, 2], xs[0, 3]), max(np.hypot(xs[0, 2], xs[0, 3]), cfg.v_min))
    ta, tb = plots.t[0], plots.t[-1]

    def start(K: int) -> ControlTrack:
        cuts = np.concatenate([[0], starts[K - 1], [N]])
        times = np.concatenate([[ta], tg[starts[K - 1]] - g / 2, [tb]])
        times[1:-1] = np.clip(times[1:-1], ta + cfg.dt_min * np.arange(1, K), tb - cfg.dt_min * np.arange(K - 1, 0, -1))
        return ControlTrack(first, [ControlSegment(np.clip(sig[a:b, 0].mean(), -cfg.max_u, cfg.max_u),
                                                   np.clip(sig[a:b, 1].mean(), -cfg.max_w, cfg.max_w), times[k], times[k + 1])
                                    for k, (a, b) in enumerate(zip(cuts[:-1], cuts[1:]))])

    return start, k0, len(crit), q, crit


def split(ct: ControlTrack, K: int, weight: TrackWeight, times: np.ndarray, dt_min: float) -> ControlTrack:
    """``ct`` with segments halved (same controls, so the same track) until it has K segments.

    The segment whose plots fit worst — largest Σ d² − 2·n (Mahalanobis excess over its expectation)
    — is halved first; segments shorter than 2·dt_min are not split.
    """
    d2 = weight.distances2(sample(ct, times)[:, :2])
    seg = ct.segment_index(times)
    items = [[float(np.sum(d2[seg == k]) - 2 * np.sum(seg == k)), s] for k, s in enumerate(ct)]
    while len(items) < K:
        ok = [i for i, (_, s) in enumerate(items) if s.duration >= 2 * dt_min]
        if not ok:
            break
        i = max(ok, key=lambda j: items[j][0])
        ex, s = items[i]
        mid = 0.5 * (s.t_start + s.t_end)
        items[i:i + 1] = [[ex / 2, attrs.evolve(s, t_end=mid)], [ex / 2, attrs.evolve(s, t_start=mid)]]
    return ControlTrack(ct.initial, [s for _, s in items])


def merge(ct: ControlTrack, K: int) -> ControlTrack:
    """``ct`` with neighbouring segments merged until K remain.

    Each step merges the pair that changes the controls least — Ward's criterion
    d₁d₂/(d₁ + d₂)·(Δu² + Δw²), the growth of Σ duration·|control − mean|² — into one segment with the
    duration-weighted mean controls. Unlike a split this changes the track: the child is refitted.
    """
    segs = list(ct)
    while len(segs) > max(K, 1):
        def cost(i):
            a, b = segs[i], segs[i + 1]
            return a.duration * b.duration / (a.duration + b.duration) * ((a.u - b.u) ** 2 + (a.w - b.w) ** 2)
        i = min(range(len(segs) - 1), key=cost)
        a, b = segs[i], segs[i + 1]
        d = a.duration + b.duration
        segs[i:i + 2] = [ControlSegment((a.u * a.duration + b.u * b.duration) / d,
                                        (a.w * a.duration + b.w * b.duration) / d, a.t_start, b.t_end)]
    return ControlTrack(ct.initial, segs)


def height_profile(plots: PlotTrack):
    """Heights along the flight: running median (5 plots) of the known plot heights, interpolated."""
    ok = np.isfinite(plots.h)
    if not ok.any():
        return lambda tt: np.zeros_like(np.asarray(tt, float))
    t, h = plots.t[ok], plots.h[ok]
    if len(h) >= 5:
        pad = np.pad(h, 2, mode="edge")
        h = np.median(np.lib.stride_tricks.sliding_window_view(pad, 5), axis=1)
    return lambda tt: np.interp(tt, t, h)


def reconstruct(plots: PlotTrack, cfg: ReconstructionConfig | None = None, biases=None) -> Reconstruction:
    """Reconstruct one flight from its plots (see the module docstring); ``biases``: radar id →
    known bias [Δr, Δθ] or :class:`~.biases.BiasEstimate`, removed first (:func:`~.biases.debias`)."""
    cfg = cfg or ReconstructionConfig()
    if plots.duration < cfg.dt_min:
        raise ValueError(f"{plots.key}: flight of {plots.duration:.1f} s is shorter than dt_min")
    if biases:
        plots = debias(plots, biases)
    t0 = float(plots.t[0])  # fit in time since the first plot: epoch seconds would swamp the steps
    rel = attrs.evolve(plots, t=plots.t - t0)
    start, k0, k_max, q, crit = hypothesis_starts(rel, cfg)
    search = _Search(TrackWeight(plots, cfg.loss, cfg.loss_c), rel.t, t0, cfg)
    # starts: K₀, the simple answers (1–3 segments, always, outside the budget), K₀'s neighbours
    for K in dict.fromkeys([k0, 1, 2, 3, round(k0 / 1.5), round(k0 * 1.5)]):
        if 1 <= K <= k_max and (K <= 3 or len(search.found) < cfg.hypotheses):
            search.run(start(K), "segmentation")
    _climb(search, k_max)
    hyps = sorted((h for h, _ in search.found), key=lambda hy: hy.score)
    geo = geo_track(hyps[0].control, cfg.grid_dt, height_profile(plots))
    return Reconstruction(plots.key, plots, tuple(hyps), geo, q, k0, tuple(float(c) for c in crit))


def _objective(weight: TrackWeight, ct: ControlTrack, t: np.ndarray, cfg: ReconstructionConfig) -> float:
    """The plots' NLL of the track ``ct`` sampled at ``t``, plus the jump prior's when it is on (MAP)."""
    return weight(sample(ct, t)[:, :2]) + jump_prior(ct, cfg)


def _hypothesis(best: ControlTrack, wgt: float, nfev: int, origin: str, weight: TrackWeight, t: np.ndarray,
                t0: float, cfg: ReconstructionConfig) -> Hypothesis:
    """The hypothesis of a fitted track (in time since ``t0``): p = 3K + 3 parameters,
    score = 2·weight + complexity · p · ln n (BIC), χ² = Σ d_i² / max(2n − p, 1)."""
    n, n_par = len(t), 3 * len(best) + 3
    chi2 = float(np.sum(weight.distances2(sample(best, t)[:, :2]))) / max(2 * n - n_par, 1)
    return Hypothesis(best.shifted(t0), wgt, 2 * wgt + cfg.complexity * n_par * np.log(n), n_par, nfev, origin, chi2)


class _Search:
    """The hypotheses fitted so far for one flight (:attr:`found`, each with its track in time since the
    first plot) and the fit of one more."""

    def __init__(self, weight: TrackWeight, t: np.ndarray, t0: float, cfg: ReconstructionConfig) -> None:
        self.weight, self.t, self.t0, self.cfg = weight, t, t0, cfg
        self.found: list[tuple[Hypothesis, ControlTrack]] = []

    def run(self, ct: ControlTrack, origin: str, floor: float = np.inf) -> Hypothesis:
        """Fit a hypothesis from the start ``ct``; when its objective is above ``floor`` (the window pass
        lost the start's fit) the start is also refined alone and the better of the two kept."""
        cfg = self.cfg
        best, _, nfev = fit_hypothesis(ct, self.t, self.weight, cfg)
        wgt = _objective(self.weight, best, self.t, cfg)
        if wgt > floor and cfg.refine:
            alt, _, n2 = fit_hypothesis(ct, self.t, self.weight, cfg, windows=False)
            nfev += n2
            if (w2 := _objective(self.weight, alt, self.t, cfg)) < wgt:
                best, wgt = alt, w2
        hyp = _hypothesis(best, wgt, nfev, origin, self.weight, self.t, self.t0, cfg)
        self.found.append((hyp, best))
        return hyp


def _climb(search: _Search, k_max: int) -> None:
    """Moves from the best hypothesis by score that still has one untried, until the budget is spent or
    two moves in a row did not improve the best score: split its worst-fitting segments to 1.5× as many
    (the same track, so the weight can only drop) or merge the most alike neighbours to 1/1.5 as many
    (refitted); split first when its χ² says the plots are not yet explained. A split child whose weight
    drops by more than a quarter of BIC's charge for its new parameters is split again next."""
    cfg, found, n = search.cfg, search.found, len(search.t)
    tried: set[tuple[int, str]] = set()
    follow: tuple[Hypothesis, ControlTrack] | None = None
    stale = 0  # moves in a row that did not improve the best score; the search stops at two
    while len(found) < cfg.hypotheses and stale < 2:
        best_score = min(h.score for h, _ in found)
        move = _next_move(found, follow, tried, k_max)
        if move is None:
            break
        h, ct, mv, K = move
        tried.add((id(h), mv))
        follow = None
        if mv == "merge":
            child = search.run(merge(ct, K), f"merge of {len(ct)}")
        else:
            child_ct = split(ct, K, search.weight, search.t, cfg.dt_min)
            if len(child_ct) == len(ct):
                continue
            child = search.run(child_ct, f"split of {len(ct)}", floor=h.weight)
        stale = 0 if child.score < best_score else stale + 1
        if mv == "merge":
            continue
        if h.weight - child.weight > cfg.complexity * (child.n_params - h.n_params) * np.log(n) / 8:
            follow = found[-1]


def _next_move(found: list[tuple[Hypothesis, ControlTrack]], follow: tuple[Hypothesis, ControlTrack] | None,
               tried: set[tuple[int, str]], k_max: int) -> tuple[Hypothesis, ControlTrack, str, int] | None:
    """(hypothesis, its track, "split" or "merge", target segment count) of the next move: the followed
    split child first, then by score; a move already tried, or to a segment count already fitted (a fit
    spent for little), is not made. None: no move is left."""
    fitted = {len(ct) for _, ct in found}
    queue = [(*follow, ("split",))] if follow else []
    queue += [(h, ct, ("split", "merge") if h.chi2 > 1.0 else ("merge", "split"))
              for h, ct in sorted(found, key=lambda f: f[0].score)]
    for h, ct, order in queue:
        K = len(ct)
        k_split, k_merge = min(k_max, max(K + 1, round(1.5 * K))), max(1, min(K - 1, round(K / 1.5)))
        for mv in order:
            target = k_split if mv == "split" else k_merge
            if (id(h), mv) not in tried and target != K and target not in fitted:
                return h, ct, mv, target
    return None


def refit(rec: Reconstruction, plots: PlotTrack, cfg: ReconstructionConfig) -> Reconstruction:
    """``rec`` with its selected hypothesis refitted by least squares alone to ``plots`` (the same
    flight's plots, e.g. corrected with new bias estimates); the other hypotheses are dropped."""
    t0 = float(plots.t[0])
    rel = attrs.evolve(plots, t=plots.t - t0)
    weight = TrackWeight(rel, cfg.loss, cfg.loss_c)
    best, _, nfev = fit_hypothesis(rec.control.shifted(-t0), rel.t, weight, cfg, windows=False)
    wgt = _objective(weight, best, rel.t, cfg)
    hyp = _hypothesis(best, wgt, nfev, "refit", weight, rel.t, t0, cfg)
    geo = geo_track(hyp.control, cfg.grid_dt, height_profile(plots))
    return Reconstruction(plots.key, plots, (hyp,), geo, rec.smoother_q, rec.k0, rec.count_criterion)


__all__ = ["Hypothesis", "Reconstruction", "reconstruct", "hypothesis_starts",
           "segmentations", "control_signals", "height_profile", "split", "merge",
           "noise_aware_count", "refit"]

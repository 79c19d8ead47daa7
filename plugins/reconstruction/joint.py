"""Radar biases estimated jointly with the trajectories of every flight of a scenario.

The coupled idea applied to reconstruction: one criterion over all flights f and radars j,

    J(tracks, ς) = Σ_f Σ_{i ∈ f} ½ (z_i − C_i ς_{j(i)} − p_f(t_i))ᵀ R_i⁻¹ (…) + Σ_j ½ ς_jᵀ Σ₀⁻¹ ς_j

(a weak prior Σ₀ = diag(:data:`PRIOR_SD`²) keeps a radar that shares no aircraft with others
bounded), minimised by alternating (Gauss–Seidel) blocks:

1. every flight reconstructed with the current biases removed (the full hypothesis search first,
   then least-squares refits of the selected hypothesis, :func:`~.hypotheses.refit`);
2. every radar's bias, given the tracks, by generalised least squares — the exact block minimum:
   A_j = Σ_i C_iᵀ R_i⁻¹ C_i + Σ₀⁻¹, ς_j = A_j⁻¹ Σ_i C_iᵀ R_i⁻¹ (z_i − p_f(t_i)), cov ς_j ≈ A_j⁻¹
   (conditional on the tracks, so it understates the uncertainty);

until no bias moves by more than 0.5 m / 0.001°, or :data:`MAX_ROUNDS` rounds; then a final full
search with the last biases. J never rises from one block to the next. A bias direction that the
geometry cannot tell from a shift of every track (e.g. one radar only) is held by the prior alone.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from concurrent.futures import Executor

import numpy as np

from radartracker_plugins.reconstruction.biases import BiasEstimate, debias
from radartracker_plugins.reconstruction.config import ReconstructionConfig
from radartracker_plugins.reconstruction.engine import Failure, batches, run_many
from radartracker_plugins.reconstruction.hypotheses import Reconstruction, refit
from radartracker_plugins.reconstruction.integrate import sample
from radartracker_plugins.reconstruction.objects import PlotTrack

PRIOR_SD = np.array([1000.0, math.radians(1.0)])  # m, rad: weak, far wider than real radar biases
MAX_ROUNDS = 4
TOL = np.array([0.5, math.radians(0.001)])


def solve_biases(tracks: list[PlotTrack], recs: dict[str, Reconstruction]) -> dict[str, BiasEstimate]:
    """Per radar, the GLS bias given the reconstructed tracks (raw plots, not debiased)."""
    A: dict[str, np.ndarray] = {}
    b: dict[str, np.ndarray] = {}
    for pt in tracks:
        rec = recs.get(pt.key)
        if rec is None:
            continue
        r = pt.z - sample(rec.control, pt.t)[:, :2]
        Rinv = np.linalg.inv(pt.R)
        CtRi = pt.C.transpose(0, 2, 1) @ Rinv
        for radar in set(pt.radar):
            sel = pt.radar == radar
            A[radar] = A.get(radar, np.diag(1.0 / PRIOR_SD**2)) + np.sum(CtRi[sel] @ pt.C[sel], axis=0)
            b[radar] = b.get(radar, np.zeros(2)) + np.einsum("nij,nj->i", CtRi[sel], r[sel])
    out = {}
    for radar in A:
        cov = np.linalg.inv(A[radar])
        out[str(radar)] = BiasEstimate(cov @ b[radar], cov)
    return out


def _refit_batch(pairs: list[tuple[Reconstruction, PlotTrack]], cfg: ReconstructionConfig) -> list[Reconstruction]:
    return [refit(rec, pt, cfg) for rec, pt in pairs]


def estimate_jointly(tracks: list[PlotTrack], cfg: ReconstructionConfig, ex: Executor | None, batch_plots: int = 500,
                     progress: bool = False) -> tuple[Iterator[Reconstruction | Failure], dict]:
    """(results of the final search, a summary: biases with sd per radar, rounds, the largest last change)."""
    recs: dict[str, Reconstruction] = {}
    failed: list[Failure] = []
    for res in run_many(tracks, cfg, ex, batch_plots, progress):
        if isinstance(res, Failure):
            failed.append(res)
        else:
            recs[res.key] = res
    biases = {radar: BiasEstimate(np.zeros(2)) for radar in {r for pt in tracks for r in pt.radar}}
    by_key = {pt.key: pt for pt in tracks}
    rounds, change = 0, np.inf
    for rounds in range(1, MAX_ROUNDS + 1):
        new = solve_biases(tracks, recs)
        change = max(float(np.max(np.abs(new[r].value - biases[r].value) / TOL)) for r in new)
        biases.update(new)
        corrected = {k: debias(by_key[k], {r: e.value for r, e in biases.items()}) for k in recs}
        if change <= 1.0:
            break
        work = batches([corrected[k] for k in recs], batch_plots)
        pairs = [[(recs[pt.key], pt) for pt in batch] for batch in work]
        if ex is None:
            done = [_refit_batch(p, cfg) for p in pairs]
        else:
            done = [f.result() for f in [ex.submit(_refit_batch, p, cfg) for p in pairs]]
        recs = {r.key: r for batch in done for r in batch}
    summary = {"rounds": rounds, "converged": bool(change <= 1.0),
               "biases": {r: {"range_bias_m": round(float(e.value[0]), 2),
                              "azimuth_bias_deg": round(math.degrees(float(e.value[1])), 5),
                              "sd_range_m": round(float(np.sqrt(e.cov[0, 0])), 2),
                              "sd_azimuth_deg": round(math.degrees(float(np.sqrt(e.cov[1, 1]))), 5)}
                          for r, e in sorted(biases.items())}}
    final = [debias(pt, {r: e.value for r, e in biases.items()}) for pt in tracks if pt.key in recs]

    def results() -> Iterator[Reconstruction | Failure]:
        yield from failed
        yield from run_many(final, cfg, ex, batch_plots, progress)

    return results(), summary

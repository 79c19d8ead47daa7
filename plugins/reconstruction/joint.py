"""Radar biases estimated jointly with the trajectories of every flight of a scenario.

The coupled idea applied to reconstruction: one criterion over all flights f and radars j,

    J(tracks, ς) = Σ_f Σ_{i ∈ f} ½ (z_i − C_i ς_{j(i)} − p_f(t_i))ᵀ R_i⁻¹ (…) + Σ_j ½ ς_jᵀ Σ₀⁻¹ ς_j

(a weak prior Σ₀ = diag(:data:`PRIOR_SD`²) keeps a radar that shares no aircraft with others
bounded), minimised in rounds of two steps. With more components (``components``: a range gain, a time
offset; :func:`joint_model`) C_i ς_j becomes B_i ς_j, B_i = [c_ρ, c_θ, ρ_i c_ρ, −v(t_i)]
(:meth:`radartracker.api.SensorModel.jacobians`), the velocity v(t_i) the flight's reconstruction of the round
before (a Gauss–Newton linearisation, as the filters take their predicted velocity), their priors
:data:`radartracker.api.EXTRA_PRIOR_SD`:

1. every flight reconstructed with the current biases removed (the full hypothesis search first,
   then least-squares refits of the selected hypothesis, :func:`~.hypotheses.refit`);
2. the biases by the joint Gauss–Newton step with every track's parameters projected out
   (:func:`bias_step`; alternating exact block minima instead — GLS of the biases given the
   tracks — crept: 4 rounds reached 33 of 80 m of a range bias on the ``manoeuvres`` scenario);

until no bias moves by more than :data:`TOL` (0.5 m, 0.001°, 1 ppm, 1 ms), or :data:`MAX_ROUNDS` rounds; then a
final full
search with the last biases. A bias direction that the geometry cannot tell from a shift of every
track (e.g. one radar only) is held by the prior alone — and there it wanders: on the ``demo`` scenario
seen by its radar R1 alone the estimate went to 106 m, −0.13° (truth 120 m, +0.15°; sd 12 m, 0.47°) and
the truth RMSE rose from 295 m (biases left in) to 511 m. So the CLI estimates only the radars of
:func:`shared_radars` (``radars``) and leaves the others' plots as they are.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable, Iterator
from concurrent.futures import Executor

import attrs
import numpy as np

from radartracker.api import EXTRA_PRIOR_SD, BiasComponent, ComponentBound, SensorModel
from radartracker_plugins.reconstruction.biases import BiasEstimate, debias
from radartracker_plugins.reconstruction.config import ReconstructionConfig
from radartracker_plugins.reconstruction.engine import Failure, batches, run_many
from radartracker_plugins.reconstruction.fit import ControlObjective
from radartracker_plugins.reconstruction.hypotheses import Reconstruction, refit
from radartracker_plugins.reconstruction.integrate import sample
from radartracker_plugins.reconstruction.objects import PlotTrack
from radartracker_plugins.reconstruction.weight import TrackWeight

PRIOR_SD = np.array([1000.0, math.radians(1.0)])  # m, rad: weak, far wider than real radar biases
MAX_ROUNDS = 4
#: the change of each component below which the rounds stop (SI units: m, rad, 1, s)
TOL = {"range_offset": 0.5, "azimuth_offset": math.radians(0.001), "range_gain": 1e-6, "time_offset": 1e-3}
#: a component's figures in the summary: (key of its value, key of its sd, scale from SI, decimals)
SUMMARY = {"range_offset": ("range_bias_m", "sd_range_m", 1.0, 2),
           "azimuth_offset": ("azimuth_bias_deg", "sd_azimuth_deg", math.degrees(1.0), 5),
           "range_gain": ("range_gain_ppm", "sd_range_gain_ppm", 1e6, 2),
           "time_offset": ("time_offset_ms", "sd_time_offset_ms", 1e3, 2)}


def joint_model(components: Collection[str] = ()) -> SensorModel:
    """The sensor model the joint mode estimates for every radar: the range and azimuth offsets with the weak
    :data:`PRIOR_SD`, and ``components`` (``range_gain``, ``time_offset``) with
    :data:`radartracker.api.EXTRA_PRIOR_SD`."""
    return SensorModel.default(*PRIOR_SD).with_components(*(BiasComponent(n, EXTRA_PRIOR_SD[n]) for n in components))


def velocities(rec: Reconstruction, models: Iterable[SensorModel]) -> np.ndarray | None:
    """The reconstructed plane velocity (n × 2, m/s) at each of the flight's plot times, v (sin φ, cos φ), where
    one of ``models`` has a time offset (whose column −v needs it); else None."""
    if not any("time_offset" in model.names for model in models):
        return None
    s = sample(rec.control, rec.plots.t)
    return np.column_stack([s[:, 3] * np.sin(s[:, 2]), s[:, 3] * np.cos(s[:, 2])])


def corrected(pt: PlotTrack, biases: dict[str, BiasEstimate], rec: Reconstruction) -> PlotTrack:
    """``pt`` with the values of ``biases`` removed, a time offset's column at the velocities of ``rec`` (its
    reconstruction); their covariance is not added to R: the rounds estimate that error jointly."""
    values = {r: BiasEstimate(e.value, model=e.model) for r, e in biases.items()}
    return debias(pt, values, velocities(rec, (e.model for e in biases.values())))


def shared_radars(tracks: list[PlotTrack]) -> set[str]:
    """The radars that saw at least one aircraft together with another radar: the ones whose biases the
    flights can tell apart from a shift of the tracks (a radar seen alone leaves its azimuth bias — a rotation
    of every track about it — to the prior)."""
    out: set[str] = set()
    for pt in tracks:
        seen = {str(r) for r in set(pt.radar)}
        if len(seen) > 1:
            out |= seen
    return out


def bias_step(tracks: list[PlotTrack], recs: dict[str, Reconstruction], biases: dict[str, BiasEstimate],
              cfg: ReconstructionConfig, estimated: Collection[str] | None = None) -> dict[str, BiasEstimate]:
    """The Gauss–Newton step of the joint problem for the biases, the tracks' parameters projected out.

    For flight f with whitened residuals r_f = L⁻¹(z − Cς − p(θ_f)), J_θ = ∂r_f/∂θ_f (the fit's own
    chain-rule Jacobian) and G_f = ∂r_f/∂ς = −L⁻¹C (two columns per radar), eliminating Δθ_f (Schur
    complement; variable projection, Golub & Pereyra 1973) leaves::

        (Σ_f G_fᵀ (I − Π_f) G_f + Σ₀⁻¹) Δς = −Σ_f G_fᵀ (I − Π_f) r_f − Σ₀⁻¹ ς,   Π_f = J_θ (J_θᵀ J_θ)⁺ J_θᵀ

    Only the part of a bias that no track can absorb is estimated from the flights — the plain
    conditional GLS (Π = 0) creeps along the directions a track can absorb. The covariance is the
    inverse of that matrix (the tracks' uncertainty included). Only the radars in ``estimated`` (all when
    None) get a step; the others keep their biases in ``biases``.
    """
    seen = {str(r) for pt in tracks for r in pt.radar}
    radars = sorted(r for r in seen if estimated is None or r in estimated)
    models = {r: biases[r].model for r in radars}
    ends = np.cumsum([model.size for model in models.values()]).tolist()
    cols = {r: slice(end - models[r].size, end) for r, end in zip(radars, ends)}  # each radar's entries of ς
    m = ends[-1] if ends else 0
    prior = np.zeros((m, m))
    for r, c in cols.items():
        prior[c, c] = np.linalg.inv(models[r].prior())
    s0 = np.concatenate([biases[r].value for r in radars])
    A, b = prior.copy(), -prior @ s0
    for pt in tracks:
        rec = recs.get(pt.key)
        if rec is None:
            continue
        r, J, G = _flight_terms(pt, rec, models, cols, m, cfg)
        U, sv, _ = np.linalg.svd(J, full_matrices=False)
        U = U[:, sv > sv[0] * 1e-10]
        Gp = G - U @ (U.T @ G)
        A += Gp.T @ Gp
        b -= Gp.T @ r
    cov = np.linalg.inv(A)
    step = cov @ b
    return {r: BiasEstimate(biases[r].value + step[c], cov[c, c], models[r]) for r, c in cols.items()}


def _flight_terms(pt: PlotTrack, rec: Reconstruction, models: dict[str, SensorModel], cols: dict[str, slice], m: int,
                  cfg: ReconstructionConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(r_f, J_θ, G_f) of one flight (:func:`bias_step`): its whitened residuals at its fit, their Jacobian in the
    track's parameters and in the biases of ``models`` (columns ``cols``), G = −L⁻¹ B."""
    fixed = rec.plots  # the plots as fitted, current biases removed
    t0 = float(fixed.t[0])
    rel = attrs.evolve(fixed, t=fixed.t - t0)
    ct = rec.control.shifted(-t0)
    obj = ControlObjective(TrackWeight(rel, cfg.loss, cfg.loss_c), rel.t, 0.0, ct.t_end, len(ct), cfg)
    theta = obj.pack((ct.initial.x, ct.initial.y, ct.initial.phi, ct.initial.v), ct.u, ct.w,
                     np.array([s.t_start for s in ct] + [ct.t_end]))
    r = obj.residuals(theta)[:-1]
    J = obj.jacobian(theta)[:-1]
    G = np.zeros((len(r), m))
    v = velocities(rec, models.values())
    for radar in {str(x) for x in set(pt.radar)} & set(cols):
        sel = np.flatnonzero(pt.radar == radar)
        B = models[radar].jacobians(pt.C[sel], pt.rho[sel], None if v is None else v[sel])
        LB = -np.einsum("nij,njk->nik", obj.weight.Linv[sel], B)  # ∂r/∂ς of each plot (2 × m_j)
        for j in range(2):
            G[2 * sel + j, cols[radar]] = LB[:, j, :]
    return r, J, G


def _refit_batch(pairs: list[tuple[Reconstruction, PlotTrack]], cfg: ReconstructionConfig) -> list[Reconstruction]:
    return [refit(rec, pt, cfg) for rec, pt in pairs]


def joint_rounds(tracks: list[PlotTrack], recs: dict[str, Reconstruction], cfg: ReconstructionConfig,
                 ex: Executor | None = None, batch_plots: int = 500, radars: Collection[str] | None = None,
                 components: Collection[str] = ()
                 ) -> tuple[dict[str, Reconstruction], dict[str, BiasEstimate], int, float]:
    """Rounds of (bias step, refits) from ``recs`` (each flight's fit at zero biases) until no bias moves by
    more than :data:`TOL` or :data:`MAX_ROUNDS`: (refitted recs, biases with covariance, rounds, the last
    change in units of TOL). The biases are those of the last :func:`bias_step`, with its covariance, in the
    components of :func:`joint_model` (``components``); only those of ``radars`` (all when None) are
    estimated, the others stay zero."""
    model = joint_model(components)
    tol = np.array([TOL[n] for n in model.names])
    biases = {radar: BiasEstimate(np.zeros(model.size), model=model) if radars is None or radar in radars
              else BiasEstimate(np.zeros(2)) for radar in {r for pt in tracks for r in pt.radar}}
    if radars is not None and not set(radars) & set(biases):
        return recs, biases, 0, 0.0
    by_key = {pt.key: pt for pt in tracks}
    rounds, change = 0, np.inf
    for rounds in range(1, MAX_ROUNDS + 1):
        new = bias_step(tracks, recs, biases, cfg, radars)
        change = max(float(np.max(np.abs(new[r].value - biases[r].value) / tol)) for r in new)
        biases.update(new)
        if change <= 1.0:
            break
        fixed = {k: corrected(by_key[k], biases, recs[k]) for k in recs}
        work = batches([fixed[k] for k in recs], batch_plots)
        pairs = [[(recs[pt.key], pt) for pt in batch] for batch in work]
        if ex is None:
            done = [_refit_batch(p, cfg) for p in pairs]
        else:
            done = [f.result() for f in [ex.submit(_refit_batch, p, cfg) for p in pairs]]
        recs = {r.key: r for batch in done for r in batch}
    return recs, biases, rounds, change


def estimate_jointly(tracks: list[PlotTrack], cfg: ReconstructionConfig, ex: Executor | None, batch_plots: int = 500,
                     progress: bool = False, radars: Collection[str] | None = None, components: Collection[str] = ()
                     ) -> tuple[Iterator[Reconstruction | Failure], dict]:
    """(results of the final search, a summary: biases with sd per radar, rounds, whether converged, and the
    radars whose biases were not estimated). Only the biases of ``radars`` (all when None) are estimated, in
    the components of :func:`joint_model` (``components``)."""
    recs: dict[str, Reconstruction] = {}
    failed: list[Failure] = []
    for res in run_many(tracks, cfg, ex, batch_plots, progress):
        if isinstance(res, Failure):
            failed.append(res)
        else:
            recs[res.key] = res
    recs, biases, rounds, change = joint_rounds(tracks, recs, cfg, ex, batch_plots, radars, components)
    held = sorted(str(r) for r in biases if radars is not None and r not in radars)
    for r in held:
        del biases[r]
    summary = {"rounds": rounds, "converged": bool(change <= 1.0), "not_estimated": held,
               "biases": {r: _summary(e) for r, e in sorted(biases.items())},
               "observability": {r: _observability(r, e) for r, e in sorted(biases.items())}}
    final = [corrected(pt, biases, recs[pt.key]) for pt in tracks if pt.key in recs]

    def results() -> Iterator[Reconstruction | Failure]:
        yield from failed
        yield from run_many(final, cfg, ex, batch_plots, progress)

    return results(), summary


def _summary(e: BiasEstimate) -> dict[str, float]:
    """A radar's estimate for the summary: each component and its sd in the units of :data:`SUMMARY`
    (``range_bias_m``, ``sd_range_m``, …, ``range_gain_ppm``, ``sd_range_gain_ppm``, ``time_offset_ms``, …)."""
    values, sds = {}, {}
    for k, name in enumerate(e.model.names):
        key, sd_key, scale, digits = SUMMARY[name]
        values[key] = round(float(e.value[k]) * scale, digits)
        sds[sd_key] = round(float(np.sqrt(e.cov[k, k])) * scale, digits)
    return values | sds


def _observability(radar: str, e: BiasEstimate) -> dict[str, str]:
    """Each component's status (:class:`radartracker.api.ComponentBound`): its σ, from the joint problem's
    information with the prior (its Cramér–Rao bound), against the prior's σ."""
    return {c.name: ComponentBound(radar, c.name, float(np.sqrt(e.cov[k, k])), c.prior_sd).status
            for k, c in enumerate(e.model.components)}

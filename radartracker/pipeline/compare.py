"""Run several estimators on the same scenario and compare them (accuracy, consistency, cost).

Each estimator goes through :func:`radartracker.pipeline.run.run` with the same settings. Scores:

* bias RMSE — over radars, of the final range / azimuth bias error (truth from the scenario);
* aircraft position / velocity RMSE and mean NEES over every recorded estimate (4 dof, expected 4;
  :mod:`radartracker.pipeline.evaluate` defines the truth interpolation);
* bias NEES — mean over radars of the final (ς̂ − ς)ᵀ P_s⁻¹ (ς̂ − ς) (2 dof, expected 2): how honest
  each estimator's bias covariance is;
* time per measurement — the replay's wall time over the measurements used.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import attrs
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from radartracker.io.atomic import write_text  # noqa: E402
from radartracker.io.tables import ScenarioData  # noqa: E402
from radartracker.pipeline.config import RunConfig  # noqa: E402
from radartracker.pipeline.figures import save  # noqa: E402
from radartracker.pipeline.result import RunResult, strict  # noqa: E402
from radartracker.pipeline.run import run  # noqa: E402

DEFAULT_ESTIMATORS = ("decoupled", "blom", "coupled")


@attrs.frozen
class Score:
    """One estimator's scores on one scenario (or pooled over several, see :func:`pool`)."""

    estimator: str
    bias_rmse_range_m: float
    bias_rmse_azimuth_deg: float
    position_rmse_m: float
    velocity_rmse_mps: float
    mean_nees: float
    bias_nees: float
    us_per_measurement: float
    radars: int
    estimates: int
    runs: int = 1


def score(result: RunResult) -> Score:
    """Scores of one run (NaN where the scenario has no truth)."""
    truth_b = result.data.truth_biases or {}
    eb = [(b.bias - np.asarray(truth_b[r]), b.cov) for r, b in result.final_biases.items() if r in truth_b]
    err_b = np.array([e for e, _ in eb]).reshape(-1, 2)
    nees_b = [float(e @ np.linalg.solve(P, e)) for e, P in eb]
    rms = lambda a: float(np.sqrt(np.mean(a**2))) if a.size else math.nan  # noqa: E731
    metrics = result.evaluation["truth"] if result.evaluation else {}
    n_meas = sum(v for k, v in result.counts.items() if k.endswith("_used"))
    return Score(
        estimator=result.estimator_name,
        bias_rmse_range_m=rms(err_b[:, 0]),
        bias_rmse_azimuth_deg=math.degrees(rms(err_b[:, 1])),
        position_rmse_m=metrics.get("position_rmse_m", math.nan),
        velocity_rmse_mps=metrics.get("velocity_rmse_mps", math.nan),
        mean_nees=metrics.get("mean_nees", math.nan),
        bias_nees=float(np.mean(nees_b)) if nees_b else math.nan,
        us_per_measurement=1e6 * result.seconds / max(n_meas, 1),
        radars=len(eb),
        estimates=int(metrics.get("estimates_compared", 0)),
    )


def pool(scores: list[Score]) -> Score:
    """Scores of one estimator pooled over runs: RMSEs from summed squares, NEES and time averaged."""
    def rms(field: str, weight: str) -> float:
        w = np.array([getattr(s, weight) for s in scores], float)
        v = np.array([getattr(s, field) for s in scores], float)
        return float(np.sqrt(np.sum(w * v**2) / np.sum(w)))

    def avg(field: str, weight: str) -> float:
        w = np.array([getattr(s, weight) for s in scores], float)
        return float(np.sum(w * [getattr(s, field) for s in scores]) / np.sum(w))

    return Score(
        estimator=scores[0].estimator,
        bias_rmse_range_m=rms("bias_rmse_range_m", "radars"),
        bias_rmse_azimuth_deg=rms("bias_rmse_azimuth_deg", "radars"),
        position_rmse_m=rms("position_rmse_m", "estimates"),
        velocity_rmse_mps=rms("velocity_rmse_mps", "estimates"),
        mean_nees=avg("mean_nees", "estimates"),
        bias_nees=avg("bias_nees", "radars"),
        us_per_measurement=float(np.mean([s.us_per_measurement for s in scores])),
        radars=sum(s.radars for s in scores),
        estimates=sum(s.estimates for s in scores),
        runs=sum(s.runs for s in scores),
    )


def markdown_table(scores: list[Score]) -> str:
    """The comparison as a Markdown table."""
    head = ("| estimator | bias RMSE range (m) | bias RMSE azimuth (deg) | position RMSE (m) "
            "| velocity RMSE (m/s) | mean NEES (4) | bias NEES (2) | µs per plot | runs |")
    lines = [head, "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for s in scores:
        lines.append(f"| {s.estimator} | {s.bias_rmse_range_m:.1f} | {s.bias_rmse_azimuth_deg:.4f} | "
                     f"{s.position_rmse_m:.1f} | {s.velocity_rmse_mps:.2f} | {s.mean_nees:.2f} | "
                     f"{s.bias_nees:.2f} | {s.us_per_measurement:.0f} | {s.runs} |")
    return "\n".join(lines)


def run_comparison(data: ScenarioData, estimators: list[str] | tuple[str, ...] = DEFAULT_ESTIMATORS,
                   config: RunConfig | None = None, progress: bool = True) -> dict[str, RunResult]:
    """Run ``data`` through each estimator with otherwise the same settings. Each is warmed up first
    (:func:`~radartracker.pipeline.warmup.warm_up`: its kernels compiled or loaded from numba's cache), so
    that its time per measurement is its own and not partly the first run's compiling."""
    from radartracker.pipeline.warmup import warm_up

    results = {}
    for name in estimators:
        cfg = attrs.evolve(config or RunConfig(), estimator=name)
        warm_up(cfg, labelled=data.plots.has_truth_labels, notice=progress)
        results[name] = run(data, cfg, progress=progress)
    return results


def _bias_error_series(result: RunResult, rid: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    b = result.biases
    idx = b.radar == rid
    truth = np.asarray((result.data.truth_biases or {})[rid])
    sd = np.sqrt(np.stack([b.cov[idx, 0, 0], b.cov[idx, 1, 1]], axis=-1))
    return b.time[idx], b.value[idx] - truth, sd


def plot_bias_errors(results: dict[str, RunResult], path: Path | str) -> None:
    """Bias error (estimate − truth) of every radar over time, one column per estimator, with ±2σ."""
    names = list(results)
    fig, axes = plt.subplots(2, len(names), figsize=(4.2 * len(names), 6), sharex=True, sharey="row", squeeze=False)
    any_result = results[names[0]]
    bt = any_result.biases.time
    t0 = float(bt[0]) if len(bt) else 0.0
    radars = [r for r in any_result.final_biases if r in (any_result.data.truth_biases or {})]
    for col, name in enumerate(names):
        for j, rid in enumerate(radars):
            t, e, sd = _bias_error_series(results[name], rid)
            for row, scale in enumerate((1.0, math.degrees(1.0))):
                ax = axes[row, col]
                line, = ax.plot(t - t0, e[:, row] * scale, lw=1, label=rid)
                ax.fill_between(t - t0, -2 * sd[:, row] * scale, 2 * sd[:, row] * scale, color=line.get_color(), alpha=0.12)
        axes[0, col].set_title(name)
        axes[1, col].set_xlabel("time since start (s)")
    axes[0, 0].set_ylabel("range bias error (m)")
    axes[1, 0].set_ylabel("azimuth bias error (deg)")
    for ax in axes.ravel():
        ax.axhline(0.0, color="k", lw=0.6)
    t_half = t0 + 0.5 * (bt[-1] - t0) if len(bt) else t0
    for row, scale in enumerate((1.0, math.degrees(1.0))):  # zoom on the second half: the prior spans far more
        late = [np.abs(e[t >= t_half, row]) for r in results.values() for rid in radars
                for t, e, _ in [_bias_error_series(r, rid)]]
        late = np.concatenate(late) if late else np.zeros(1)
        lim = 3.0 * scale * float(np.percentile(late, 95)) if late.size else 1.0
        axes[row, 0].set_ylim(-lim - 1e-12, lim + 1e-12)
    axes[0, 0].legend(fontsize=8, loc="upper right")
    fig.suptitle(f"{any_result.data.name}: bias estimation error with ±2σ (shaded) per estimator")
    fig.tight_layout()
    save(fig, path, dpi=100)


def rmse_vs_time(result: RunResult, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(aircraft position RMSE, bias range RMSE over radars) in each time bin."""
    err, ok = result.estimate_errors()
    d2 = np.sum(err[:, :2] ** 2, axis=1)
    pos = np.full(len(edges) - 1, np.nan)
    bias = np.full(len(edges) - 1, np.nan)
    b = np.digitize(result.tracks.time, edges) - 1
    radars = [r for r in result.final_biases if r in (result.data.truth_biases or {})]
    for k in range(len(edges) - 1):
        sel = ok & (b == k)
        if sel.any():
            pos[k] = math.sqrt(float(np.mean(d2[sel])))
        last = []
        for rid in radars:
            t, e, _ = _bias_error_series(result, rid)
            i = np.searchsorted(t, edges[k + 1], side="right") - 1
            if i >= 0:
                last.append(e[i, 0])
        if last:
            bias[k] = math.sqrt(float(np.mean(np.square(last))))
    return pos, bias


def plot_rmse_vs_time(results: dict[str, RunResult], path: Path | str, bins: int = 40) -> None:
    """Aircraft position RMSE and bias range RMSE (over radars) against time, one line per estimator."""
    first = next(iter(results.values()))
    t = first.tracks.time
    edges = np.linspace(t.min(), t.max() + 1e-9, bins + 1)
    mid = 0.5 * (edges[1:] + edges[:-1]) - edges[0]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for name, res in results.items():
        pos, bias = rmse_vs_time(res, edges)
        axes[0].plot(mid, pos, marker=".", label=name)
        axes[1].plot(mid, bias, marker=".", label=name)
    axes[0].set_ylabel("aircraft position RMSE (m)")
    axes[1].set_ylabel("range bias RMSE over radars (m)")
    for ax in axes:
        ax.set_yscale("log")
        ax.set_xlabel("time since start (s)")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle(f"{first.data.name}: RMSE vs time")
    fig.tight_layout()
    save(fig, path, dpi=100)


COMPARISON_FILES = ("*comparison.md", "*scores.json", "*bias_error.png", "*rmse_vs_time.png")


def write_comparison(results: dict[str, RunResult], out: Path | str, prefix: str = "", *,
                     stage: Callable[[str], Path] | None = None) -> list[Score]:
    """Write ``{prefix}comparison.md``, ``scores.json`` (strict JSON) and the two figures into ``out``
    (each to ``stage(name)`` when given: :func:`radartracker.io.atomic.replace_outputs`)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = stage or (lambda name: out / name)
    scores = [score(r) for r in results.values()]
    write_text(path(f"{prefix}comparison.md"), markdown_table(scores) + "\n")
    write_text(path(f"{prefix}scores.json"),
               json.dumps(strict([attrs.asdict(s) for s in scores]), indent=1, allow_nan=False) + "\n")
    if _has_truth(results):
        plot_bias_errors(results, path(f"{prefix}bias_error.png"))
        plot_rmse_vs_time(results, path(f"{prefix}rmse_vs_time.png"))
    return scores


def _has_truth(results: dict[str, RunResult]) -> bool:
    """Whether the scenario carries the truth the figures need."""
    data = next(iter(results.values())).data
    return data.truth is not None and bool(data.truth_biases)

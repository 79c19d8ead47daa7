"""A long recording assessed a time slice at a time, each (slice, radar) one task, in this process or on Dask.

The replay (:func:`radartracker.pipeline.run.run`) estimates the biases sequentially over the whole
recording, once, before the slices: every slice matches its plots with the same end-of-run Δr̂, Δθ̂, so the
slices are independent of one another and nothing sequential is left to carry between them.

* **Slices.** From the first plot, every :attr:`SliceConfig.slice_s` seconds; the first is open to the left
  and the last to the right, so every plot lies in exactly one slice [t₀, t₁), by its time.
* **Margin.** A slice's task gets the radar's plots and the reference (:meth:`Reference.window`) over
  [t₀ − m, t₁ + m), m = :func:`margin_s` = 3 T_max (the longest antenna period): its sweeps (plots within
  T/2 of each other), its detections (a plot within T/2 of a crossing) and its crossings (the crossing of
  revolution n lies within [t_N + nT, t_N + (n+1)T]) see across the boundary; only what starts inside the
  slice is counted (:mod:`radartracker.assessment.tally`). t_N and each radar's span, which need all its
  plots, are computed before the slices, in this process.
* **Sums.** Each task returns a :class:`~radartracker.assessment.tally.RadarTally`; they are added in slice
  order (not the order the tasks finish in), so the result does not depend on the number of workers: counts
  exactly, moments of the residuals to round-off (relative ≤ 1e-9 against one slice, :data:`TOLERANCE`).
* **Dask.** ``workers`` N: a :class:`~distributed.LocalCluster` of N single-threaded worker processes bound
  to 127.0.0.1 (no network beyond this machine), closed at the end; ``scheduler``: an existing cluster's
  address, whose workers must have this package installed. Each slice's reference is scattered once and
  shared by its radars' tasks.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from typing import Any

import attrs
import numpy as np

from radartracker.assessment.matching import MatchConfig, match_radar, north_time
from radartracker.assessment.radar import FT
from radartracker.assessment.reference import Reference
from radartracker.assessment.tally import RadarTally, tally
from radartracker.cluster import dask_client
from radartracker.domain import Radar
from radartracker.geometry.plane import RadarFrame
from radartracker.io.tables import PlotTable, ScenarioData
from radartracker.progress import progress_bar

TOLERANCE = 1e-9  # relative: a figure of slices against one pass (moments merged in another order)


@attrs.frozen
class SliceConfig:
    """How the work is split and where it runs: the slice length (s; the default keeps a recording of up to
    an hour one slice), the LocalCluster's size (None: this process, no Dask) or an existing Dask scheduler's
    address (``tcp://host:8786``)."""

    slice_s: float = attrs.field(default=3600.0, validator=attrs.validators.gt(0.0))
    workers: int | None = attrs.field(default=None, validator=attrs.validators.optional(attrs.validators.ge(1)))
    scheduler: str | None = None


@attrs.frozen
class RadarSlice:
    """One task: a radar's plots over a slice and its margin, with what the whole recording fixes (t_N, the
    span of all its plots, the bias Δr̂ m, Δθ̂ rad) and the slice [t₀, t₁) to count."""

    radar: Radar
    plots: PlotTable
    antenna: tuple[float, tuple[float, float]]
    bias: tuple[float, float]
    keep: tuple[float, float]


def margin_s(radars: list[Radar]) -> float:
    """m = 3 T_max (module docstring)."""
    return 3.0 * max((r.period_s for r in radars), default=0.0)


def slice_bounds(t_first: float, t_last: float, slice_s: float) -> list[tuple[float, float]]:
    """The slices [t₀, t₁) covering the plots (module docstring): the first open left, the last open right."""
    k = max(1, math.ceil((t_last - t_first) / slice_s))
    edges = [t_first + i * slice_s for i in range(1, k)]
    return list(zip([-math.inf, *edges], [*edges, math.inf]))


def assess_slice(job: RadarSlice, reference: Reference, configs: tuple[MatchConfig, float]) -> RadarTally:
    """One task: the radar's plots matched to the slice's reference and summed over the slice."""
    r = job.radar
    frame = RadarFrame(r.lat, r.lon, r.height_m, reference.plane)
    p = job.plots
    match = match_radar(r, frame, p.time, p.range_m, p.azimuth_rad, job.bias, reference, configs[0],
                        antenna=job.antenna, keep=job.keep)
    addresses = {k: t.icao24 for k, t in reference.tracks.items()}
    return tally(p, match, job.bias, r.period_s, addresses, configs[1], job.keep)


def _jobs(data: ScenarioData, biases: dict[str, tuple[float, float]], slice_s: float
          ) -> list[tuple[tuple[float, float], list[RadarSlice]]]:
    """The tasks of every slice, slice by slice (module docstring)."""
    t = data.plots.time
    if not len(t):
        return [((-math.inf, math.inf), [])]
    m = margin_s(data.radars)
    bounds = slice_bounds(float(t.min()), float(t.max()), slice_s)
    out = []
    per_radar = []
    for radar in data.radars:
        idx = np.flatnonzero(data.plots.radar == radar.id)
        if not len(idx):
            continue
        ti = t[idx]
        order = idx[np.argsort(ti, kind="stable")]
        antenna = (north_time(ti, data.plots.azimuth_rad[idx], radar.period_s), (float(ti.min()), float(ti.max())))
        per_radar.append((radar, order, t[order], antenna))
    for keep in bounds:
        jobs = []
        for radar, order, ts, antenna in per_radar:
            a, b = np.searchsorted(ts, keep[0] - m, "left"), np.searchsorted(ts, keep[1] + m, "left")
            jobs.append(RadarSlice(radar, data.plots.take(order[a:b]), antenna, biases[radar.id], keep))
        out.append((keep, jobs))
    return out


@contextlib.contextmanager
def _client(config: SliceConfig, given: Any, quiet: bool) -> Iterator[Any]:
    """``given`` if not None, else the client of ``config``'s cluster (:func:`dask_client`: None without one)."""
    if given is not None:
        yield given
        return
    with dask_client(config.workers, config.scheduler, quiet=quiet) as made:
        yield made


def tally_radars(data: ScenarioData, reference: Reference, biases: dict[str, tuple[float, float]],
                 match: MatchConfig, mode_c_tolerance_ft: float, config: SliceConfig, *,
                 progress: bool = True, client: Any = None) -> dict[str, RadarTally]:
    """Every radar's sums over the recording (module docstring), one progress bar over all the tasks; on
    ``client`` (a ``distributed`` client the caller holds) if given, else on the cluster ``config`` names."""
    work = _jobs(data, biases, config.slice_s)
    m = margin_s(data.radars)
    configs = (match, mode_c_tolerance_ft * FT)
    results: dict[tuple[int, str], RadarTally] = {}
    bar = progress_bar(total=sum(len(j) for _, j in work), desc="assessing (slice, radar)", unit="task",
                       disable=not progress)
    try:
        with _client(config, client, quiet=not progress) as client:
            futures = {}
            for i, (keep, jobs) in enumerate(work):
                ref = reference if len(work) == 1 else reference.window(keep[0] - m, keep[1] + m)
                if client is None:
                    for job in jobs:
                        results[i, job.radar.id] = assess_slice(job, ref, configs)
                        bar.update(1)
                    continue
                shared = client.scatter(ref, hash=False)
                futures |= {client.submit(assess_slice, job, shared, configs, pure=False): (i, job.radar.id)
                            for job in jobs}
            if client is not None:
                from distributed import as_completed

                for fut in as_completed(list(futures)):
                    results[futures[fut]] = fut.result()
                    bar.update(1)
    finally:
        bar.close()
    out: dict[str, RadarTally] = {}
    for (_, radar), t in sorted(results.items(), key=lambda kv: kv[0][0]):
        out[radar] = out[radar].merge(t) if radar in out else t
    return out

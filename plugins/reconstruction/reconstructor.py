"""The ``multi-hypothesis`` reconstructor plugin object (entry point ``radartracker.reconstructors``)."""

from __future__ import annotations

from collections.abc import Collection, Iterator, Mapping
from concurrent.futures import Executor
from typing import NamedTuple

import numpy as np

from radartracker.api import ScenarioData
from radartracker_plugins.reconstruction.biases import BiasEstimate
from radartracker_plugins.reconstruction.config import ReconstructionConfig
from radartracker_plugins.reconstruction.engine import Failure, run_many
from radartracker_plugins.reconstruction.hypotheses import Reconstruction, reconstruct
from radartracker_plugins.reconstruction.objects import PlotTrack
from radartracker_plugins.reconstruction.quality import assess
from radartracker_plugins.reconstruction.tracks import scenario_tracks


class Flight(NamedTuple):
    """One aircraft of a scenario reconstructed (:meth:`MultiHypothesisReconstructor.flights`): its key (truth
    label or Mode S address), the geometric track's times (s), plane x, y and height (m) in the scenario's
    system plane, and the verdict of its quality flags (``plausible``, or why not; a flight that could not be
    reconstructed: empty arrays and the reason)."""

    key: str
    time: np.ndarray
    x: np.ndarray
    y: np.ndarray
    h: np.ndarray
    verdict: str


class MultiHypothesisReconstructor:
    """The reconstructor plugin: one flight with :meth:`reconstruct`, many with :meth:`reconstruct_many`, a
    scenario's aircraft with :meth:`flights`."""

    name = "multi-hypothesis"

    def __init__(self, config: ReconstructionConfig | None = None) -> None:
        self.config = config if config is not None else ReconstructionConfig()

    def reconstruct(self, plots: PlotTrack, biases: Mapping[str, np.ndarray] | None = None) -> Reconstruction:
        """Reconstruct one flight; ``biases`` are known radar biases [Δr, Δθ] to remove."""
        return reconstruct(plots, self.config, biases)

    def reconstruct_many(self, tracks: list[PlotTrack], executor: Executor | None = None,
                         batch_plots: int = 500, progress: bool = False) -> Iterator[Reconstruction | Failure]:
        """Reconstruct many flights on ``executor`` (this process when None), as they finish."""
        return run_many(tracks, self.config, executor, batch_plots, progress)

    def flights(self, data: ScenarioData, biases: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None, *,
                exclude: Collection[str] = (), min_plots: int = 10, groups: np.ndarray | None = None,
                executor: Executor | None = None, progress: bool = False) -> Iterator[Flight]:
        """Every aircraft of ``data`` whose plots carry a truth label or a Mode S address — or, given ``groups``,
        each plot's aircraft key by the caller's grouping (None: no aircraft) — but those named in
        ``exclude``, with at least ``min_plots`` plots, reconstructed with the radar biases ``biases`` (radar →
        (ς̂ = [Δr m, Δθ rad], its 2×2 covariance)) removed: z̃ = z − C ς̂, R̃ = R + C Σ Cᵀ (:func:`.biases.debias`).
        Yields one :class:`Flight` per aircraft as it finishes, in the scenario's system plane."""
        tracks, _, _ = scenario_tracks(data, min_plots, groups)
        skip = set(exclude)
        tracks = [pt for pt in tracks if pt.key not in skip]
        known = {r: BiasEstimate(b, cov) for r, (b, cov) in (biases or {}).items()}
        for res in run_many(tracks, self.config, executor, progress=progress, biases=known or None):
            if isinstance(res, Failure):
                empty = np.empty(0)
                yield Flight(res.key, empty, empty, empty, empty, f"not reconstructed: {res.reason}")
                continue
            geo = res.geo
            yield Flight(res.key, geo.time, np.asarray(geo.x), np.asarray(geo.y), np.asarray(geo.h),
                         assess(res, self.config)["verdict"])

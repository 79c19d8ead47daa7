"""The ``multi-hypothesis`` reconstructor plugin object (entry point ``radartracker.reconstructors``)."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from concurrent.futures import Executor

import numpy as np

from radartracker_plugins.reconstruction.config import ReconstructionConfig
from radartracker_plugins.reconstruction.engine import Failure, run_many
from radartracker_plugins.reconstruction.hypotheses import Reconstruction, reconstruct
from radartracker_plugins.reconstruction.objects import PlotTrack


class MultiHypothesisReconstructor:
    """The reconstructor plugin: one flight with :meth:`reconstruct`, many with :meth:`reconstruct_many`."""

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

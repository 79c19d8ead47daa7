"""The pipeline: a scenario through association, track filters and bias estimator into one result.

``result = run(data, RunConfig(...))`` (:mod:`radartracker.pipeline.run`), then
``write_outputs(result, folder)`` (:mod:`radartracker.pipeline.writer`); docs/architecture.md.
"""

from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.run import run
from radartracker.pipeline.writer import write_outputs

__all__ = ["RunConfig", "run", "write_outputs"]

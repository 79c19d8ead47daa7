"""Compiled kernels ready before a run's clock starts.

numba compiles a kernel the first time it is called and keeps it in a disk cache; only the first run
after installing (or upgrading) compiles, for some seconds, and later runs load the cache in a fraction
of a second. Without a warm-up, that first run stalls inside its first measurements, with the progress
bar showing an ETA of hours. :func:`warm_up` runs a tiny built-in traffic scenario through the same
path as the run that follows (association, estimator, motion model and their options) so that every
kernel is compiled or loaded before the real inputs, and the service before it listens; when it
compiles, it says so (:func:`radartracker.compiled.compile_notice`). :func:`before_progress_bar` says
when a run with a progress bar needs one.
"""

from __future__ import annotations

import contextlib
import logging
import sys
import time

import numpy as np

from radartracker.compiled import cache_is_cold, compile_notice
from radartracker.errors import RadarTrackerError
from radartracker.pipeline.config import RunConfig

log = logging.getLogger(__name__)


def warm_up(config: RunConfig, *, labelled: bool = False, notice: bool = True) -> float:
    """Run the built-in ``tracking`` scenario for 120 s (tracks start, are confirmed, coast and are
    dropped) through ``config`` (with truth labels when the run's data has them: ``labelled``, so that
    ``auto`` chooses the same association), then end an aircraft in a fresh estimator of the run's
    plugin (its marginalisation); returns the CPU seconds it took. With ``notice``, a line on stderr
    says that the kernels are being compiled, when numba's disk cache lacks them, and one more how long
    that took."""
    started = time.process_time()
    with compile_notice() if notice else contextlib.nullcontext():
        try:
            _exercise(config, labelled)
        except RadarTrackerError as exc:  # a setting this tiny scenario cannot take: the run itself will say so
            log.debug("warm-up skipped: %s", exc)
    return time.process_time() - started


def before_progress_bar() -> bool:
    """Whether a run that shows a progress bar warms up first: on a terminal always (from a warm cache that
    takes under a second, and the bar's rate is the run's from its first input); elsewhere (a notebook, a
    log) when numba's disk cache is cold, so that the compiling is said and kept out of the bar's rate
    instead of stalling it at its first inputs with an ETA of hours. Cold is told by the kernels of the
    TrackManager's coverage and of the estimators' screening, which no step before the run (reading the
    inputs, loading the plugins) compiles: none is cached after a fresh install, an upgrade or an emptied
    cache."""
    from radartracker.estimation import screening
    from radartracker.tracking import coverage

    return sys.stderr.isatty() or cache_is_cold(coverage, screening)


def _exercise(config: RunConfig, labelled: bool) -> None:
    """The tiny run, then one aircraft added, updated and ended in a fresh estimator of the run's plugin."""
    from radartracker.estimation.base import PlaneMeasurement
    from radartracker.pipeline.config import resolve
    from radartracker.pipeline.run import run
    from radartracker.registry import make_estimator
    from radartracker.simulation.scenarios import build_scenario
    from radartracker.registry import default_estimator

    data = build_scenario("tracking", seed=3, duration=120.0).run()
    if not labelled:
        data.plots.target = np.full(len(data.plots), None, dtype=object)
        data.truth = None
    run(data, config, progress=False)
    from radartracker.io import columnar

    columnar.warm_up()  # the streamed reader's checks of a block's columns
    name = config.estimator or default_estimator()
    cfg = resolve(config, data, name)
    radar = data.radars[0].id
    est = make_estimator(name, cfg.estimator_settings(), [radar], cfg.estimator_options)
    est.add_aircraft(0, 0.0, np.array([1e4, 1e4, 100.0, 0.0]), np.diag([1e6, 1e6, 1e4, 1e4]))
    for t in (4.0, 8.0):
        est.update(PlaneMeasurement(t, 0, radar, np.array([1e4 + 100 * t, 1e4]), np.eye(2), 1e4 * np.eye(2)))
    est.remove_aircraft(0)

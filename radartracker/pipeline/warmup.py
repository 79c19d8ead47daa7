"""Compiled kernels ready before a run's clock starts.

numba compiles a kernel the first time it is called and keeps it in a disk cache; only the first run
after installing (or upgrading) compiles, for some seconds, and later runs load the cache in a fraction
of a second. Without a warm-up, that first run stalls inside its first measurements, with the progress
bar showing an ETA of hours. :func:`warm_up` runs a tiny built-in traffic scenario through the same
path as the run that follows (association, estimator, motion model and their options) so that every
kernel is compiled or loaded before the real inputs, and the service before it listens.
"""

from __future__ import annotations

import logging
import sys
import threading
import time

import numpy as np

from radartracker.errors import RadarTrackerError
from radartracker.pipeline.config import RunConfig

log = logging.getLogger(__name__)

NOTICE_AFTER_S = 3.0  # say what is happening when the warm-up takes longer than loading a warm disk cache does


def warm_up(config: RunConfig, *, labelled: bool = False, notice: bool = True) -> float:
    """Run the built-in ``tracking`` scenario for 120 s (tracks start, are confirmed, coast and are
    dropped) through ``config`` (with truth labels when the run's data has them: ``labelled``, so that
    ``auto`` chooses the same association), then end an aircraft in a fresh estimator of the run's
    plugin (its marginalisation); returns the CPU seconds it took. With ``notice``, a line on stderr
    says that the kernels are being compiled when that takes more than :data:`NOTICE_AFTER_S`."""
    started = time.process_time()
    timer = threading.Timer(NOTICE_AFTER_S, lambda: print(
        "compiling the numba kernels (once after installing; later runs load them from the disk cache)...",
        file=sys.stderr, flush=True))
    if notice:
        timer.start()
    try:
        _exercise(config, labelled)
    except RadarTrackerError as exc:  # a setting this tiny scenario cannot take: the run itself will say so
        log.debug("warm-up skipped: %s", exc)
    finally:
        timer.cancel()
    return time.process_time() - started


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

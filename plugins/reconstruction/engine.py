"""Many flights in parallel: flights batched into tasks on a ``concurrent.futures`` executor.

* ``serial``: in this process (tests, debugging);
* ``process`` (default): a local :class:`~concurrent.futures.ProcessPoolExecutor`;
* ``dask``: a ``dask.distributed`` client's executor — a :class:`~distributed.LocalCluster` of
  single-threaded worker processes on 127.0.0.1 (:func:`radartracker.api.dask_client`), or the cluster at ``scheduler`` (``tcp://host:8786``), the
  scale-out engine for thousands of flights (DESIGN §10).

Flights are packed, longest first, into batches of about ``batch_plots`` plots, so a task is
long enough to hide scheduling overhead and short enough to balance. A flight that cannot be
reconstructed (e.g. shorter than dt_min) is reported as a failure, not a crash.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Iterator
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed

import attrs
from tqdm import tqdm

from radartracker.api import dask_client
from radartracker_plugins.reconstruction.config import ReconstructionConfig
from radartracker_plugins.reconstruction.hypotheses import Reconstruction, reconstruct
from radartracker_plugins.reconstruction.objects import PlotTrack

ENGINES = ("serial", "process", "dask")


@attrs.frozen
class Failure:
    """A flight that could not be reconstructed, and why."""

    key: str
    reason: str


def reconstruct_batch(tracks: list[PlotTrack], cfg: ReconstructionConfig, biases=None) -> list[Reconstruction | Failure]:
    """Reconstruct a batch of flights (one executor task); ``biases``: known radar biases."""
    out: list[Reconstruction | Failure] = []
    for pt in tracks:
        try:
            out.append(reconstruct(pt, cfg, biases))
        except ValueError as exc:
            out.append(Failure(pt.key, str(exc)))
    return out


def batches(tracks: Iterable[PlotTrack], batch_plots: int) -> list[list[PlotTrack]]:
    """Tracks packed longest first into batches of about ``batch_plots`` plots."""
    out: list[list[PlotTrack]] = []
    size = 0
    for pt in sorted(tracks, key=len, reverse=True):
        if not out or size + len(pt) > batch_plots:
            out.append([])
            size = 0
        out[-1].append(pt)
        size += len(pt)
    return out


@contextlib.contextmanager
def executor(engine: str = "process", workers: int | None = None, scheduler: str | None = None,
             quiet: bool = False) -> Iterator[Executor | None]:
    """The executor of ``engine`` (None for ``serial``), shut down on exit; ``quiet``: Dask logs errors only."""
    if engine not in ENGINES:
        raise ValueError(f"engine: expected one of {ENGINES}, got {engine!r}")
    if engine == "serial":
        yield None
    elif engine == "process":
        with ProcessPoolExecutor(max_workers=workers) as ex:
            yield ex
    else:
        with dask_client(workers, scheduler, quiet) as client:
            yield client.get_executor()


def run_many(tracks: list[PlotTrack], cfg: ReconstructionConfig, ex: Executor | None,
             batch_plots: int = 500, progress: bool = True, biases=None) -> Iterator[Reconstruction | Failure]:
    """Reconstruct every track on ``ex`` (in this process when None), yielding results as they finish."""
    work = batches(tracks, batch_plots)
    bar = tqdm(total=len(tracks), unit="flight", disable=not progress, desc="reconstruct")
    try:
        if ex is None:
            for batch in work:
                for res in reconstruct_batch(batch, cfg, biases):
                    bar.update(1)
                    yield res
            return
        futures = [ex.submit(reconstruct_batch, batch, cfg, biases) for batch in work]
        for fut in as_completed(futures):
            for res in fut.result():
                bar.update(1)
                yield res
    finally:
        bar.close()

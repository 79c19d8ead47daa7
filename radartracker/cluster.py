"""The Dask cluster a command's work runs on: an existing scheduler's, or a LocalCluster on this machine.

A LocalCluster's scheduler and workers listen on 127.0.0.1 only (the project's rule: no network beyond this
machine unless a scheduler address is given), have no dashboard, and are closed when the work ends.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator
from typing import Any


@contextlib.contextmanager
def dask_client(workers: int | None, scheduler: str | None = None, quiet: bool = False) -> Iterator[Any]:
    """A ``distributed`` client of ``scheduler`` (``tcp://host:8786``), else of a LocalCluster of ``workers``
    single-threaded processes on 127.0.0.1 (``quiet``: its logs errors only), else None (no Dask: the work
    runs in this process). Closed on exit."""
    if not scheduler and not workers:
        yield None
        return
    from distributed import Client, LocalCluster

    if scheduler:
        with Client(scheduler) as client:
            yield client
        return
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None, silence_logs=logging.ERROR if quiet else logging.WARNING) as cluster, \
            Client(cluster) as client:
        yield client

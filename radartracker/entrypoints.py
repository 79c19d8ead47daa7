"""The installed distributions' entry points, read once per state of the import path.

``importlib.metadata.entry_points`` reads the metadata of every installed distribution (a tenth of a
second with a hundred of them), and a process looks several groups up (the CLI's commands, the
estimators, motion models...): the answer is kept per :func:`path_state`. Kept apart from
:mod:`radartracker.registry` (which imports the tracker to build what it finds) so that the command
line can find its sub-commands without importing anything else.
"""

from __future__ import annotations

import functools
import os
import sys
from importlib.metadata import EntryPoint, entry_points


def path_state() -> tuple:
    """``sys.path`` and the modification time of each of its folders: installing or removing a package there
    (a dist-info folder made or deleted) or changing the path changes it. What is read from the installed
    distributions' metadata (entry points) is kept per state; a file edited in place inside an installed
    dist-info (no folder on the path modified) is not seen until the path changes."""
    state = []
    for p in sys.path:
        try:
            state.append((p, os.stat(p or ".").st_mtime_ns))
        except (OSError, TypeError, ValueError):
            state.append((p, None))
    return tuple(state)


def installed(group: str) -> dict[str, EntryPoint]:
    """The entry points of ``group`` by name (a later one of the same name wins, as ``entry_points`` lists them)."""
    return dict(_entry_points(group, path_state()))


@functools.lru_cache(maxsize=16)
def _entry_points(group: str, state: tuple) -> dict[str, EntryPoint]:
    """``group``'s entry points, read once per ``state`` of the path."""
    return {ep.name: ep for ep in entry_points(group=group)}

"""Checkpoints in the state folder: ``DIR/checkpoint-NNNNNN/`` holding the manager's snapshot
(:meth:`TrackManager.snapshot`) and ``service.json`` (the service's own counters).

A checkpoint is written into ``.checkpoint-NNNNNN.partial`` and renamed into place (``os.replace``
of a folder is atomic), so a crash at any instant leaves either the previous or the new checkpoint,
never half of one; a ``.partial`` folder of a failed write is removed. The two newest are kept, and
numbers go on past 999 999 (seven digits and more, ordered as numbers).

A restart resumes from the newest checkpoint that reads back whole (:func:`resume`): a damaged
snapshot or ``service.json`` (read as untrusted input, like any file) is skipped, named, for the one
before it, so one flipped bit no longer stops every restart while an intact older checkpoint exists.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

from radartracker.errors import RadarTrackerError, SnapshotError
from radartracker.io.atomic import write_text
from radartracker.io.limits import read_json
from radartracker.registry import restore_manager
from radartracker.tracking.manager import TrackManager

_NAME = re.compile(r"checkpoint-(\d{6,})$")
_PARTIAL = re.compile(r"\.checkpoint-\d{6,}\.partial$")
KEEP = 2
MAX_COUNT = 2**63 - 1  # a counter in service.json: a non-negative integer a Counter can add to


def write_json_atomic(path: Path, obj: object) -> None:
    """Write ``obj`` as JSON, atomically (:mod:`radartracker.io.atomic`)."""
    write_text(path, json.dumps(obj, indent=1, default=str))


def checkpoints(state_dir: Path) -> list[tuple[int, Path]]:
    """(sequence number, folder) of the complete checkpoints, oldest first."""
    if not state_dir.is_dir():
        return []
    out = [(int(m.group(1)), p) for p in state_dir.iterdir() if (m := _NAME.match(p.name)) and p.is_dir()]
    return sorted((n, p) for n, p in out if (p / "manager.snapshot").is_file() and (p / "service.json").is_file())


def write_checkpoint(state_dir: Path, seq: int, mgr: TrackManager, service_state: dict) -> Path:
    """Checkpoint number ``seq`` of ``mgr`` and ``service_state``; older ones beyond :data:`KEEP` removed.
    A write that fails (a full disk) leaves no ``.partial`` folder behind and raises."""
    final = state_dir / f"checkpoint-{seq:06d}"
    tmp = state_dir / f".checkpoint-{seq:06d}.partial"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        tmp.mkdir(parents=True)
        mgr.snapshot(tmp / "manager.snapshot")
        write_json_atomic(tmp / "service.json", service_state)
        os.replace(tmp, final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    for _, old in checkpoints(state_dir)[:-KEEP]:
        shutil.rmtree(old, ignore_errors=True)
    return final


def read_service_state(path: Path) -> dict:
    """``service.json``: an object whose ``counts`` maps names to non-negative integers (SnapshotError
    naming the file otherwise: a truncated file, a missing or a string count were tracebacks)."""
    try:
        state = read_json(path)
    except RadarTrackerError as exc:
        raise SnapshotError(str(path), str(exc)) from None
    counts = state.get("counts") if isinstance(state, dict) else None
    if not isinstance(counts, dict):
        raise SnapshotError(str(path), "no 'counts' object")
    for name, n in counts.items():
        if type(n) is not int or not 0 <= n <= MAX_COUNT:
            raise SnapshotError(str(path), f"count {name!r} is {n!r}, not a non-negative integer")
    return state


def read_checkpoint(folder: Path) -> tuple[TrackManager, dict]:
    """The manager and the service state of one checkpoint folder (SnapshotError if either is damaged)."""
    state = read_service_state(folder / "service.json")
    return restore_manager(folder / "manager.snapshot"), state


def resume(state_dir: Path) -> tuple[tuple[int, Path, TrackManager, dict] | None, list[str]]:
    """The newest checkpoint that reads back whole, as (number, folder, manager, service state), or
    None; and a line for each newer one skipped, saying why. ``.partial`` leftovers are removed."""
    if state_dir.is_dir():
        for p in state_dir.iterdir():
            if _PARTIAL.match(p.name):
                shutil.rmtree(p, ignore_errors=True)
    skipped = []
    for seq, folder in reversed(checkpoints(state_dir)):
        try:
            return (seq, folder, *read_checkpoint(folder)), skipped
        except (RadarTrackerError, OSError) as exc:
            skipped.append(f"{folder.name}: {exc}")
    return None, skipped

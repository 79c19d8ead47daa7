"""Checkpoints in the state folder: ``DIR/checkpoint-NNNNNN/`` holding the manager's snapshot
(:meth:`TrackManager.snapshot`) and ``service.json`` (the service's own counters).

A checkpoint is written into ``.checkpoint-NNNNNN.partial`` and renamed into place (``os.replace``
of a folder is atomic), so a crash at any instant leaves either the previous or the new checkpoint,
never half of one. The two newest are kept.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

from radartracker.io.atomic import write_text
from radartracker.registry import restore_manager
from radartracker.tracking.manager import TrackManager

_NAME = re.compile(r"checkpoint-(\d{6})$")
KEEP = 2


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
    """Checkpoint number ``seq`` of ``mgr`` and ``service_state``; older ones beyond :data:`KEEP` removed."""
    final = state_dir / f"checkpoint-{seq:06d}"
    tmp = state_dir / f".checkpoint-{seq:06d}.partial"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    mgr.snapshot(tmp / "manager.snapshot")
    write_json_atomic(tmp / "service.json", service_state)
    os.replace(tmp, final)
    for _, old in checkpoints(state_dir)[:-KEEP]:
        shutil.rmtree(old, ignore_errors=True)
    return final


def read_checkpoint(folder: Path) -> tuple[TrackManager, dict]:
    """The manager and the service state of one checkpoint folder."""
    state = json.loads((folder / "service.json").read_text(encoding="utf-8"))
    return restore_manager(folder / "manager.snapshot"), state

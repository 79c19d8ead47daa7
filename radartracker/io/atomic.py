"""Atomic output files and output folders that hold one run.

Each output file is written under a temporary name in its own folder, flushed to disk and then
renamed over its final name (``os.replace``, atomic within one file system on POSIX and Windows):
a reader, a Ctrl-C or a full disk leaves either the previous complete file or the new complete
file, never a partial one. The temporary file is removed when the write fails.

A folder made of several files that only make sense together (a scenario folder, a recording, a
``convert`` output) is built whole by :func:`atomic_folder` in a hidden sibling, every file flushed
to disk, then renamed into place: the folder appears complete or not at all. A run killed with
SIGKILL leaves only that hidden ``.NAME.partial-*`` sibling, which no command reads.

:func:`prepare_output_folder` runs *before* the computation: it creates the folder, proves it can
be written, and refuses a folder that already holds files unless ``overwrite`` — which first
removes the earlier run's files (and nothing that a run does not write).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, Any

from radartracker.errors import ConfigurationError

TMP_SUFFIX = ".tmp"


@contextmanager
def atomic_path(path: Path | str) -> Iterator[Path]:
    """A temporary path beside ``path`` for a library that writes by file name; renamed on success."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=TMP_SUFFIX, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        with suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


@contextmanager
def atomic_open(path: Path | str, mode: str = "w", **kwargs: Any) -> Iterator[IO]:
    """``open(path, mode)`` whose content appears at ``path`` only once complete (see module docstring)."""
    with atomic_path(path) as tmp:
        with open(tmp, mode, **kwargs) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())


@contextmanager
def atomic_folder(path: Path | str) -> Iterator[Path]:
    """A new temporary folder beside ``path`` that becomes ``path`` (which must not exist) on success.

    Everything written inside is flushed to disk before the rename; on failure the folder is removed.
    """
    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{path} already exists; choose a new folder")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.partial-", dir=path.parent))
    try:
        yield tmp
        _sync_tree(tmp)
        if path.exists():  # os.rename would silently replace an empty folder made meanwhile
            raise FileExistsError(f"{path} appeared while it was being written; the result is not moved there")
        os.rename(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _sync_tree(folder: Path) -> None:
    """fsync every file under ``folder`` (the rename must not reach the disk before their content)."""
    for root, _, files in os.walk(folder):
        for name in files:
            fd = os.open(os.path.join(root, name), os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)


def write_text(path: Path | str, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_open(path, "w", encoding="utf-8", newline="") as f:
        f.write(text)


def prepare_output_folder(out: Path | str, outputs: Iterable[str], *, overwrite: bool = False) -> Path:
    """Create ``out``, check that it can be written, and make sure it holds no earlier results.

    ``outputs`` are the file names a run may write (``*.png`` style patterns allowed). A folder with
    files is refused unless ``overwrite``; then the earlier run's files (those names, and temporary
    files a killed run left behind) are removed first, and anything else in the folder is refused.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigurationError(f"output folder {out} is a file")
    out.mkdir(parents=True, exist_ok=True)
    patterns = list(outputs)
    present = sorted(p for p in out.iterdir())
    if present and not overwrite:
        names = ", ".join(p.name for p in present[:3]) + (", ..." if len(present) > 3 else "")
        raise ConfigurationError(f"output folder {out} is not empty ({names}); "
                                 "choose a new folder or pass --overwrite to replace the earlier run")
    if present:
        ours = [p for p in present if p.is_file() and (any(p.match(pat) for pat in patterns)
                                                        or (p.name.startswith(".") and p.name.endswith(TMP_SUFFIX)))]
        foreign = [p.name for p in present if p not in ours]
        if foreign:
            raise ConfigurationError(f"output folder {out} holds files a run does not write ({', '.join(foreign[:3])}); "
                                     "--overwrite removes only an earlier run's outputs: choose another folder")
        for p in ours:
            p.unlink()
    try:
        with tempfile.TemporaryFile(dir=out) as probe:
            probe.write(b"radartracker")
    except OSError as exc:
        raise ConfigurationError(f"output folder {out} cannot be written: {exc.strerror or exc}") from exc
    return out

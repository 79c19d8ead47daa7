"""Atomic output files and output folders that hold one run.

Each output file is written under a temporary name in its own folder, flushed to disk and then
renamed over its final name (``os.replace``, atomic within one file system on POSIX and Windows):
a reader, a Ctrl-C or a full disk leaves either the previous complete file or the new complete
file, never a partial one. The temporary file is removed when the write fails.

:func:`prepare_output_folder` runs *before* the computation: it creates the folder, proves it can
be written, and refuses a folder that already holds files unless ``overwrite`` — which first
removes the earlier run's files (and nothing that a run does not write).
"""

from __future__ import annotations

import os
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

"""Atomic output files and output folders that hold one run.

Each output file is written under a temporary name in its own folder, flushed to disk and then
renamed over its final name (``os.replace``, atomic within one file system on POSIX and Windows):
a reader, a Ctrl-C or a full disk leaves either the previous complete file or the new complete
file, never a partial one. The temporary file is removed when the write fails.

A folder made of several files that only make sense together (a scenario folder, a recording, a
``convert`` output) is built whole by :func:`atomic_folder` in a hidden sibling, every file flushed
to disk, then renamed into place: the folder appears complete or not at all. A run killed with
SIGKILL leaves only that hidden ``.NAME.partial-PID-*`` sibling (or ``.NAME.PID-*.tmp`` file), which
no command reads; the first atomic write into that folder by a later process removes it once
process PID has ended.

:func:`prepare_output_folder` runs *before* the computation: it creates the folder, proves it can
be written, and refuses a folder that already holds files unless ``overwrite`` — which removes the
earlier run's files (and nothing that a run does not write), either at once or, with
``keep_earlier``, only when :func:`replace_outputs` puts the new run's files in their place, so
that a run that fails leaves the earlier one intact.

Temporary files and folders get the permissions ``open``/``mkdir`` would give (not ``mkstemp``'s
owner-only ones), so an output is as readable as a file written directly.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, Any

from radartracker.errors import ConfigurationError

TMP_SUFFIX = ".tmp"
_UMASK = os.umask(0o022)  # read once (os.umask is the only way), restored at once
os.umask(_UMASK)


def _mkstemp(folder: Path, name: str) -> Path:
    """An empty temporary file ``.NAME.PID-XXXXXXXX.tmp`` in ``folder`` with the mode ``open`` would give."""
    _remove_stale(folder, once=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.{os.getpid()}-", suffix=TMP_SUFFIX, dir=folder)
    try:
        if hasattr(os, "fchmod"):  # POSIX; elsewhere mkstemp's mode is the usual one
            os.fchmod(fd, 0o666 & ~_UMASK)
    finally:
        os.close(fd)
    return Path(tmp)


@contextmanager
def atomic_path(path: Path | str) -> Iterator[Path]:
    """A temporary path beside ``path`` for a library that writes by file name; flushed to disk and renamed
    on success."""
    path = Path(path)
    tmp = _mkstemp(path.parent, path.name)
    try:
        yield Path(tmp)
        fd = os.open(tmp, os.O_RDONLY)  # what the library wrote, on disk before the rename (as atomic_open's)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        with suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def staging_path(folder: Path | str, name: str) -> Path:
    """A new empty temporary file in ``folder`` for ``name``'s content, to be put in place by
    :func:`replace_outputs` (``stage(name, path)``) or removed."""
    return _mkstemp(Path(folder), name)


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
    _remove_stale(path.parent)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.partial-{os.getpid()}-", dir=path.parent))
    try:
        os.chmod(tmp, 0o777 & ~_UMASK)
        yield tmp
        _sync_tree(tmp)
        if path.exists():  # os.rename would silently replace an empty folder made meanwhile
            raise FileExistsError(f"{path} appeared while it was being written; the result is not moved there")
        os.rename(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


# the names atomic_path (a file) and atomic_folder (a folder) give, with the writer's pid; mkstemp adds 8 characters
_STALE_FILE = re.compile(r"\..+\.(\d{1,9})-[a-z0-9_]{8}" + re.escape(TMP_SUFFIX))
_STALE_FOLDER = re.compile(r"\..+\.partial-(\d{1,9})-[a-z0-9_]{8}")
_swept: set[str] = set()


def _remove_stale(folder: Path, *, once: bool = False) -> None:
    """Remove what killed writers left in ``folder``; ``once``: only at the first call of this process
    for that folder (a run may write thousands of files into one folder, each would rescan it)."""
    key = os.path.abspath(folder)
    if (once and key in _swept) or os.name != "posix":  # no harmless liveness probe elsewhere (Windows)
        return
    _swept.add(key)
    with suppress(OSError):  # tidying up is best effort: it never makes the write itself fail
        for entry in os.scandir(folder):
            is_dir = entry.is_dir(follow_symlinks=False)
            m = (_STALE_FOLDER if is_dir else _STALE_FILE).fullmatch(entry.name)
            if m is None or _running(int(m.group(1))):
                continue
            if is_dir:
                shutil.rmtree(entry.path, ignore_errors=True)
            else:
                with suppress(OSError):
                    os.unlink(entry.path)


def _running(pid: int) -> bool:
    """Whether process ``pid`` exists on this machine (another user's counts; a reused pid errs on keeping)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


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


@contextmanager
def replace_outputs(out: Path | str, outputs: Iterable[str], *, last: str) -> Iterator[Callable[[str], Path]]:
    """Write one run's files into ``out`` (prepared with ``keep_earlier``) so that a failure keeps the earlier run.

    The block gets ``stage(name)``: a temporary path beside ``out/name`` to write that file to
    (``stage(name, written)`` adopts a temporary file already written in ``out``, from :func:`staging_path`). When
    it ends without an exception, the staged files are flushed to disk; then ``last`` (the file that
    marks a finished run) is removed, the others are renamed into place, the earlier run's files
    (``outputs`` patterns) that this run did not write are removed, and ``last`` is renamed last:
    a kill during those few renames leaves a folder without ``last``, never two runs that look like
    one. When the block raises, the staged files are removed and the folder is as it was.
    """
    out = Path(out)
    staged: dict[str, Path] = {}

    def stage(name: str, written: Path | None = None) -> Path:
        if name in staged:
            raise ValueError(f"{name} staged twice")
        staged[name] = _mkstemp(out, name) if written is None else Path(written)
        return staged[name]

    try:
        yield stage
        for tmp in staged.values():
            fd = os.open(tmp, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        written = set(staged)
        with suppress(FileNotFoundError):
            os.unlink(out / last)
        for name in [n for n in staged if n != last]:
            os.replace(staged.pop(name), out / name)
        patterns = list(outputs)
        for p in out.iterdir():
            if p.is_file() and p.name != last and any(p.match(pat) for pat in patterns) and p.name not in written:
                p.unlink()
        if last in staged:
            os.replace(staged.pop(last), out / last)
    finally:
        for tmp in staged.values():  # what was not renamed into place
            with suppress(FileNotFoundError):
                os.unlink(tmp)


def prepare_output_folder(out: Path | str, outputs: Iterable[str], *, overwrite: bool = False,
                          keep_earlier: bool = False) -> Path:
    """Create ``out``, check that it can be written, and make sure it holds no earlier results.

    ``outputs`` are the file names a run may write (``*.png`` style patterns allowed). A folder with
    files is refused unless ``overwrite``; then anything but an earlier run's files (those names,
    and temporary files a killed run left behind) is refused, and the earlier run's files are
    removed now — or, with ``keep_earlier``, by :func:`replace_outputs` once the new run's are written.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigurationError(f"output folder {out} is a file")
    out.mkdir(parents=True, exist_ok=True)
    _remove_stale(out)  # a killed run's temporary files do not make the folder "not empty"
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
            if not keep_earlier or p.name.endswith(TMP_SUFFIX):
                p.unlink()
    try:
        with tempfile.TemporaryFile(dir=out) as probe:
            probe.write(b"radartracker")
    except OSError as exc:
        raise ConfigurationError(f"output folder {out} cannot be written: {exc.strerror or exc}") from exc
    return out


@contextmanager
def removed_if_failed(folder: Path | str) -> Iterator[None]:
    """``folder``, and those of its parents that do not exist yet, removed again if the block raises and leaves
    them empty: a command that fails (bad input, a refused option, Ctrl-C) leaves no empty output folder of
    its own making behind. A folder that existed before stays as it was, with whatever it holds; so does one
    the block left files in (:func:`prepare_output_folder` and the writers remove what a failed run wrote)."""
    folder = Path(folder).absolute()
    new = [p for p in (folder, *folder.parents) if not p.exists()]  # the deepest first
    try:
        yield
    except BaseException:
        for p in new:
            try:
                p.rmdir()  # an empty folder only
            except OSError:
                break
        raise

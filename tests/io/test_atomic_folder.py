"""atomic_folder and replace_outputs: a folder appears whole or not at all, a group of files replaces an
earlier run's only once complete, what a killed writer left is removed once it has ended, and outputs
get the permissions a plain ``open``/``mkdir`` gives."""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import sys
import textwrap

import pytest

from radartracker.errors import ConfigurationError
from radartracker.io.atomic import atomic_folder, atomic_open, prepare_output_folder, replace_outputs, write_text


def _tree(folder):
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _dead_pid() -> int:
    """The pid of a process that has ended (reaped), for names a killed writer would have left."""
    proc = subprocess.Popen([sys.executable, "-c", ""])
    proc.wait()
    return proc.pid


def test_folder_appears_whole_only_when_the_block_ends(tmp_path):
    out = tmp_path / "scen"
    with atomic_folder(out) as tmp:
        (tmp / "a.csv").write_text("a")
        (tmp / "sub").mkdir()
        (tmp / "sub" / "b.csv").write_text("b")
        assert not out.exists()  # nothing at the final name while it is being written
        assert tmp.parent == out.parent and tmp.name.startswith(".scen.partial-")
    assert _tree(out) == {"a.csv": b"a", "sub/b.csv": b"b"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scen"]


@pytest.mark.parametrize("exc", [OSError(28, "No space left on device"), KeyboardInterrupt()])
def test_failure_leaves_neither_the_folder_nor_its_sibling(tmp_path, exc):
    with pytest.raises(type(exc)):
        with atomic_folder(tmp_path / "deep" / "scen") as tmp:
            (tmp / "a.csv").write_text("half")
            raise exc
    assert list((tmp_path / "deep").iterdir()) == []


def test_existing_folder_is_refused_and_untouched(tmp_path):
    out = tmp_path / "scen"
    out.mkdir()
    (out / "radars.csv").write_text("earlier")
    with pytest.raises(FileExistsError, match="already exists"):
        with atomic_folder(out):
            pytest.fail("the block must not run")
    assert _tree(out) == {"radars.csv": b"earlier"}


def test_folder_made_meanwhile_is_not_replaced(tmp_path):
    out = tmp_path / "scen"
    with pytest.raises(FileExistsError, match="appeared while"):
        with atomic_folder(out) as tmp:
            (tmp / "a.csv").write_text("new")
            out.mkdir()  # another process, between our check and our rename (an empty folder: rename would succeed)
    assert list(out.iterdir()) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scen"]


def test_leftovers_of_an_ended_writer_are_removed_and_a_live_ones_kept(tmp_path):
    dead, alive = _dead_pid(), os.getppid()  # our parent runs for as long as we do
    stale_dir = tmp_path / f".scen.partial-{dead}-abcd_123"
    stale_dir.mkdir()
    (stale_dir / "plots.csv").write_text("half a scenario")
    stale_file = tmp_path / f".tracks.csv.{dead}-x1y2z3w4.tmp"
    stale_file.write_text("half a file")
    live_dir = tmp_path / f".other.partial-{alive}-abcd_123"
    live_dir.mkdir()
    mine = [tmp_path / ".notes", tmp_path / f".plan.{dead}-v2.tmp", tmp_path / "scen.partial-1-abcdefgh",
            tmp_path / f".big.{'9' * 30}-abcdefgh.tmp"]  # no pid: os.kill would overflow
    for p in mine:  # a user's files that merely look alike: never touched
        p.write_text("mine")
    with atomic_folder(tmp_path / "scen") as tmp:
        (tmp / "plots.csv").write_text("whole")
    assert not stale_dir.exists() and not stale_file.exists()
    assert live_dir.is_dir() and all(p.read_text() == "mine" for p in mine)
    assert (tmp_path / "scen" / "plots.csv").read_text() == "whole"


def test_a_killed_writer_leaves_only_its_hidden_sibling_which_the_next_run_removes(tmp_path):
    code = textwrap.dedent(f"""
        import sys, time
        from radartracker.io.atomic import atomic_folder
        with atomic_folder({str(tmp_path / "rec")!r}) as tmp:
            (tmp / "plots.txt").write_text("x" * 100000)
            print("writing", flush=True)
            time.sleep(60)
    """)
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline() == "writing\n"
        proc.send_signal(signal.SIGKILL)  # no handler, no finally: what a crash or the OOM killer does
    finally:
        proc.wait(timeout=30)
    left = [p.name for p in tmp_path.iterdir()]
    assert len(left) == 1 and left[0].startswith(f".rec.partial-{proc.pid}-")  # no folder "rec", partial or whole
    with atomic_folder(tmp_path / "rec") as tmp:
        (tmp / "plots.txt").write_text("complete")
    assert [p.name for p in tmp_path.iterdir()] == ["rec"]


def test_outputs_get_the_mode_a_plain_open_gives(tmp_path):
    """mkstemp/mkdtemp make owner-only entries; an output must be as readable as one written directly."""
    (tmp_path / "plain.txt").write_text("x")
    (tmp_path / "plain").mkdir()
    write_text(tmp_path / "atomic.txt", "x")
    with atomic_folder(tmp_path / "folder"):
        pass
    prepare_output_folder(tmp_path / "out", ["*.csv"])
    with replace_outputs(tmp_path / "out", ["*.csv"], last="s.csv") as stage:
        write_text(stage("s.csv"), "x")
    mode = lambda p: stat.S_IMODE(p.stat().st_mode)  # noqa: E731
    assert mode(tmp_path / "atomic.txt") == mode(tmp_path / "out" / "s.csv") == mode(tmp_path / "plain.txt")
    assert mode(tmp_path / "folder") == mode(tmp_path / "plain")


def _earlier_run(out):
    prepare_output_folder(out, OUTPUTS)
    for name, text in {"fixes.csv": "earlier fixes", "summary.json": "earlier summary"}.items():
        write_text(out / name, text)
    return _tree(out)


OUTPUTS = ("fixes.csv", "tracks.csv", "summary.json")


def test_replace_outputs_keeps_the_earlier_run_when_the_new_one_fails(tmp_path):
    out = tmp_path / "out"
    before = _earlier_run(out)
    prepare_output_folder(out, OUTPUTS, overwrite=True, keep_earlier=True)
    assert _tree(out) == before  # checked, not yet removed
    with pytest.raises(OSError, match="No space"):
        with replace_outputs(out, OUTPUTS, last="summary.json") as stage:
            with atomic_open(stage("tracks.csv"), "w") as f:
                f.write("new tracks, complete")
            with open(stage("summary.json"), "w") as f:
                f.write("new sum")
                raise OSError(28, "No space left on device")
    assert _tree(out) == before and [p.name for p in out.iterdir() if p.name.startswith(".")] == []


def test_replace_outputs_swaps_in_the_new_run_whole(tmp_path):
    out = tmp_path / "out"
    _earlier_run(out)
    (out / ".fixes.csv.999999999-abcdefgh.tmp").write_text("left by a killed run")
    prepare_output_folder(out, OUTPUTS, overwrite=True, keep_earlier=True)
    with replace_outputs(out, OUTPUTS, last="summary.json") as stage:
        write_text(stage("tracks.csv"), "new tracks")
        write_text(stage("summary.json"), "new summary")
        assert (out / "summary.json").read_text() == "earlier summary"  # nothing replaced before the end
    assert _tree(out) == {"summary.json": b"new summary", "tracks.csv": b"new tracks"}  # earlier fixes.csv gone


def test_keep_earlier_still_refuses_what_a_run_does_not_write(tmp_path):
    out = tmp_path / "out"
    _earlier_run(out)
    (out / "notes.txt").write_text("mine")
    with pytest.raises(ConfigurationError, match="notes.txt"):
        prepare_output_folder(out, OUTPUTS, overwrite=True, keep_earlier=True)
    with pytest.raises(ConfigurationError, match="not empty"):
        prepare_output_folder(out, OUTPUTS, keep_earlier=True)
    assert (out / "notes.txt").read_text() == "mine" and (out / "fixes.csv").read_text() == "earlier fixes"

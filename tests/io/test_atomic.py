"""Atomic outputs: a failure mid-write leaves the previous file intact and no partial or temporary file;
output folders are checked before the computation and never mix two runs."""

from __future__ import annotations

import pytest

from radartracker.cli import main
from radartracker.errors import ConfigurationError
from radartracker.io.atomic import atomic_open, prepare_output_folder, write_text
from radartracker.io.scenario import write_scenario
from radartracker.simulation.scenarios import build_scenario


def test_failure_mid_write_keeps_the_previous_file(tmp_path):
    path = tmp_path / "tracks.csv"
    write_text(path, "old, complete\n")
    with pytest.raises(OSError, match="disk full"):
        with atomic_open(path, "w") as f:
            f.write("new, partial")
            raise OSError(28, "disk full")
    assert path.read_text() == "old, complete\n"
    assert [p.name for p in tmp_path.iterdir()] == ["tracks.csv"]  # the temporary file is gone
    with atomic_open(path, "w") as f:
        f.write("new")
        assert path.read_text() == "old, complete\n"  # not visible before it is complete
    assert path.read_text() == "new"


def test_output_folder_refused_when_not_empty_unless_overwrite(tmp_path):
    out = tmp_path / "out"
    prepare_output_folder(out, ["*.csv", "summary.json"])
    (out / "tracks.csv").write_text("earlier run")
    (out / ".summary.json.x1.tmp").write_text("left by a killed run")
    with pytest.raises(ConfigurationError, match="not empty.*--overwrite"):
        prepare_output_folder(out, ["*.csv", "summary.json"])
    prepare_output_folder(out, ["*.csv", "summary.json"], overwrite=True)
    assert list(out.iterdir()) == []
    (out / "notes.txt").write_text("mine")
    with pytest.raises(ConfigurationError, match="notes.txt"):
        prepare_output_folder(out, ["*.csv"], overwrite=True)
    assert (out / "notes.txt").read_text() == "mine"  # never deleted


def test_unwritable_output_found_before_the_computation(tmp_path, monkeypatch, capsys):
    write_scenario(tmp_path / "scen", build_scenario("seed", seed=1, duration=60.0).run())
    monkeypatch.setattr("radartracker.pipeline.run.run", None)  # reaching the computation would be a TypeError
    (tmp_path / "file").write_text("x")
    assert main(["replay", str(tmp_path / "scen"), "--out", str(tmp_path / "file" / "out")]) == 2
    assert "file" in capsys.readouterr().err
    assert main(["replay", str(tmp_path / "scen"), "--out", "/proc/radartracker-test"]) == 2


def test_replay_interrupted_while_writing_leaves_the_earlier_outputs(tmp_path, monkeypatch):
    write_scenario(tmp_path / "scen", build_scenario("seed", seed=1, duration=60.0).run())
    out = tmp_path / "out"
    assert main(["--quiet", "replay", str(tmp_path / "scen"), "--out", str(out), "--estimator", "decoupled"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def rows_then_fail(*args, **kwargs):
        yield "1.0,1,partial\n"
        raise KeyboardInterrupt

    monkeypatch.setattr("radartracker.pipeline.writer.event_tables", rows_then_fail)
    from radartracker.io.sources import read_source
    from radartracker.pipeline.config import RunConfig
    from radartracker.pipeline.run import run
    from radartracker.pipeline.writer import write_outputs

    result = run(read_source(tmp_path / "scen"), RunConfig(estimator="decoupled", q=9.0), progress=False)
    with pytest.raises(KeyboardInterrupt):
        write_outputs(result, out)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_a_file_written_by_name_is_on_disk_before_it_is_renamed(tmp_path, monkeypatch):
    """atomic_path (a library writing by file name, e.g. the coupling graph) syncs what was written before
    the rename, as atomic_open does: the final name never points at a file still in the page cache."""
    import os

    from radartracker.io import atomic

    calls = []
    real_fsync, real_replace = os.fsync, os.replace
    monkeypatch.setattr(atomic.os, "fsync", lambda fd: (calls.append(("fsync", os.readlink(f"/proc/self/fd/{fd}"))),
                                                        real_fsync(fd))[1])
    monkeypatch.setattr(atomic.os, "replace", lambda a, b: (calls.append(("replace", str(a))), real_replace(a, b))[1])
    with atomic.atomic_path(tmp_path / "out.graphml") as tmp:
        tmp.write_text("<graphml/>")
    assert [c[0] for c in calls] == ["fsync", "replace"] and calls[0][1] == calls[1][1]
    assert (tmp_path / "out.graphml").read_text() == "<graphml/>"


@pytest.mark.parametrize("streamed", [True, False])
def test_a_disk_that_fills_during_replay_overwrite_keeps_the_earlier_run(tmp_path, monkeypatch, capsys, streamed):
    """ENOSPC while the new run's files are written (here: its summary, after its tables): every file of the
    earlier run is still there, config.json included, and no temporary file is left; the command ends with
    one line naming the cause."""
    import errno
    import pathlib

    import numpy as np

    from radartracker.simulation.scenarios import build_scenario as scenario

    data = scenario("seed", seed=1, duration=60.0).run()
    if streamed:  # no labels: the replay streams the folder
        data.plots.target = np.full(len(data.plots), None, dtype=object)
    write_scenario(tmp_path / "scen", data)
    out = tmp_path / "out"
    assert main(["--quiet", "replay", str(tmp_path / "scen"), "--out", str(out), "--estimator", "decoupled"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert "config.json" in before
    real = pathlib.Path.write_text

    def full(self, text, *a, **k):
        if self.name.startswith(".summary.json"):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, text, *a, **k)

    monkeypatch.setattr(pathlib.Path, "write_text", full)
    capsys.readouterr()
    assert main(["--quiet", "replay", str(tmp_path / "scen"), "--out", str(out), "--estimator", "decoupled",
                 "--overwrite", "--q", "9"]) != 0
    assert "No space left on device" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before

"""Every command that writes a scenario, a recording or a converted folder: a failure mid-write (a full
disk, simulated by a writer that raises after part of the output) or a SIGKILL leaves no partial
output, and an earlier output at the same place survives byte for byte."""

from __future__ import annotations

import errno
import signal
import subprocess
import sys
import textwrap

import pytest

import radartracker.io.arrowwrite as arrowwrite
from radartracker.cli import main
from radartracker.io.asterix import write_asterix
from radartracker.io.recording import write_recording
from radartracker.io.scenario import write_scenario
from radartracker.simulation.scenarios import build_scenario

from tests.io.test_convert import FILES, OPTS, _records


@pytest.fixture(scope="module")
def tiny_data():
    return build_scenario("demo", seed=3, duration=20.0).run()


def _tree(folder):
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _disk_full():
    return OSError(errno.ENOSPC, "No space left on device")


@pytest.fixture
def scenario_fails_on_third_file(monkeypatch):
    """The scenario's CSV writer writes two files, then half of the third and fails (the disk filled up)."""
    real, calls = arrowwrite.pacsv.write_csv, []

    def write(table, f, options=None):
        calls.append(f.name)
        if len(calls) < 3:
            return real(table, f, options)
        f.write(b"1,2,")
        raise _disk_full()

    monkeypatch.setattr(arrowwrite.pacsv, "write_csv", write)
    return calls


def _one_error_line(capsys, *words):
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and all(w in err[0] for w in words), err


def test_simulate_interrupted_leaves_no_scenario(tmp_path, capsys, scenario_fails_on_third_file):
    assert main(["simulate", str(tmp_path / "scen"), "--scenario", "demo", "--duration", "20"]) == 2
    _one_error_line(capsys, "simulate: error:", "No space left")
    assert len(scenario_fails_on_third_file) == 3 and list(tmp_path.iterdir()) == []


def test_simulate_over_an_earlier_scenario_keeps_it(tmp_path, capsys, tiny_data):
    write_scenario(tmp_path / "scen", tiny_data)
    before = _tree(tmp_path / "scen")
    assert main(["simulate", str(tmp_path / "scen"), "--scenario", "demo", "--duration", "20"]) == 2
    _one_error_line(capsys, "already exists")
    assert _tree(tmp_path / "scen") == before


def test_asterix_import_interrupted_leaves_no_scenario_and_keeps_an_earlier_one(tmp_path, capsys, tiny_data,
                                                                              scenario_fails_on_third_file):
    write_asterix(tmp_path / "rec.ast", tiny_data)
    inputs = _tree(tmp_path)
    assert main(["asterix-import", str(tmp_path / "rec.ast"), "--out", str(tmp_path / "scen")]) == 2
    _one_error_line(capsys, "asterix-import: error:", "No space left")
    assert _tree(tmp_path) == inputs and sorted(p.name for p in tmp_path.iterdir()) == sorted(inputs)
    (tmp_path / "scen").mkdir()
    (tmp_path / "scen" / "plots.csv").write_text("an earlier import")
    assert main(["asterix-import", str(tmp_path / "rec.ast"), "--out", str(tmp_path / "scen")]) == 2
    assert _tree(tmp_path / "scen") == {"plots.csv": b"an earlier import"}


def test_demo_interrupted_leaves_no_scenario_and_refuses_an_earlier_run(tmp_path, capsys,
                                                                       scenario_fails_on_third_file):
    assert main(["--quiet", "demo", "--out", str(tmp_path / "d")]) == 2
    _one_error_line(capsys, "demo: error:", "No space left")
    assert not (tmp_path / "d").exists()  # made to be checked before the run, removed again when it failed
    (tmp_path / "d" / "replay").mkdir(parents=True)
    (tmp_path / "d" / "replay" / "tracks.csv").write_text("an earlier demo")
    assert main(["--quiet", "demo", "--out", str(tmp_path / "d")]) == 2
    _one_error_line(capsys, "not empty")
    assert _tree(tmp_path / "d") == {"replay/tracks.csv": b"an earlier demo"}


def test_asterix_export_interrupted_leaves_neither_file_nor_sidecar(tmp_path, capsys, monkeypatch, tiny_data):
    import radartracker.io.asterix as asterix_io

    write_scenario(tmp_path / "scen", tiny_data)
    real, blocks = asterix_io.datablocks, []

    def datablocks(*args, **kwargs):
        blocks.append(1)
        if len(blocks) > 2:  # some data blocks are in the file already
            raise _disk_full()
        return real(*args, **kwargs)

    monkeypatch.setattr(asterix_io, "datablocks", datablocks)
    assert main(["asterix-export", str(tmp_path / "scen"), "--out", str(tmp_path / "rec.ast")]) == 2
    _one_error_line(capsys, "asterix-export: error:", "No space left")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scen"]


def test_asterix_export_over_an_earlier_recording_keeps_it_and_its_sidecar(tmp_path, capsys, tiny_data):
    write_scenario(tmp_path / "scen", tiny_data)
    write_asterix(tmp_path / "rec.ast", tiny_data, adsb_sac_sic=(9, 9))
    before = _tree(tmp_path)
    assert main(["asterix-export", str(tmp_path / "scen"), "--out", str(tmp_path / "rec.ast")]) == 2
    _one_error_line(capsys, "rec.ast already exists")
    assert _tree(tmp_path) == before and sorted(p.name for p in tmp_path.iterdir()) == ["rec.ast", "rec.ast.radars.csv",
                                                                                         "scen"]


def test_write_recording_interrupted_leaves_no_recording(tmp_path, capsys, monkeypatch, tiny_data):
    import radartracker.io.recording as recording_io

    write_scenario(tmp_path / "scen", tiny_data)
    real = recording_io.scenario_records

    def records(data):
        for k, rec in enumerate(real(data)):
            if k == 20:
                partial = next(tmp_path.glob(".rec.partial-*"))
                assert sum(len((partial / n).read_bytes().splitlines()) for n in FILES) > 3  # rows on disk
                raise _disk_full()
            yield rec

    class FlushEveryLine(recording_io.RecordingWriter):  # so that the partial rows are on disk
        def __init__(self, folder):
            super().__init__(folder, buffer_lines=1)

        def _put(self, name, line):
            super()._put(name, line)
            self._fh[name].flush()

    monkeypatch.setattr(recording_io, "scenario_records", records)
    monkeypatch.setattr(recording_io, "RecordingWriter", FlushEveryLine)
    assert main(["write-recording", "--scenario", str(tmp_path / "scen"), "--out", str(tmp_path / "rec")]) == 2
    _one_error_line(capsys, "write-recording: error:", "No space left")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scen"]


def test_convert_killed_mid_write_leaves_no_output_and_the_rerun_matches_an_uninterrupted_one(tmp_path):
    """The big converter in a real process, SIGKILLed once it has written output files."""
    write_recording(tmp_path / "rec", _records(7))
    code = textwrap.dedent(f"""
        import time
        import radartracker.io.convert as conv
        from tests.io.test_convert import OPTS
        real = conv._write_bucket
        def write_bucket(*args, **kwargs):
            real(*args, **kwargs)
            print("written", flush=True)
            time.sleep(60)
        conv._write_bucket = write_bucket
        conv.convert({str(tmp_path / "rec")!r}, {str(tmp_path / "new")!r}, OPTS)
    """)
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline() == "written\n"
        partial = [p for p in tmp_path.iterdir() if p.name.startswith(".new.partial-")]
        assert len(partial) == 1 and list(partial[0].rglob("*.new4"))  # output files exist, in hiding
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert not (tmp_path / "new").exists()
    from radartracker.io.convert import convert

    convert(tmp_path / "rec", tmp_path / "new", OPTS)  # the next run removes the killed one's sibling
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new", "rec"]
    convert(tmp_path / "rec", tmp_path / "fresh" / "new", OPTS)
    rerun, fresh = _tree(tmp_path / "new"), _tree(tmp_path / "fresh" / "new")
    assert rerun.pop("report.json") and fresh.pop("report.json")  # differ only in the seconds taken
    assert rerun == fresh and any(name.endswith(".new4") for name in rerun)


@pytest.mark.parametrize("streamed", [True, False])
def test_replay_overwrite_that_fails_keeps_the_earlier_run(tmp_path, capsys, monkeypatch, tiny_data, streamed):
    """``replay --overwrite`` keeps the earlier run's files until this run's replace them: a failure during the
    computation (streamed: after part of the tables was written; read whole: in the evaluation) leaves the
    earlier run byte for byte, a success leaves only this run's files (the earlier figures go)."""
    from radartracker.pipeline.result import RunResult
    from radartracker.tracking.manager import TrackManager

    scen, out = tmp_path / "scen", tmp_path / "out"
    write_scenario(scen, tiny_data)
    how = ["--association", "manager"] if streamed else []
    assert main(["replay", str(scen), "--out", str(out), "--quiet", "--plots", *how]) == 0
    earlier = _tree(out)
    assert "biases.png" in earlier and "config.json" in earlier

    def fail(*args, **kwargs):
        raise _disk_full()

    monkeypatch.setattr(TrackManager if streamed else RunResult, "flush" if streamed else "summary", fail)
    capsys.readouterr()
    assert main(["replay", str(scen), "--out", str(out), "--quiet", "--overwrite", "--q", "9", *how]) == 2
    _one_error_line(capsys, "No space left")
    assert _tree(out) == earlier
    monkeypatch.undo()
    assert main(["replay", str(scen), "--out", str(out), "--quiet", "--overwrite", "--q", "9", *how]) == 0
    now = _tree(out)
    assert set(now) == set(earlier) - {"biases.png", "tracks.png"} and now["config.json"] != earlier["config.json"]

"""The streaming replay (inputs read block by block, tables written as they come) gives the same files,
byte for byte, as reading the scenario whole and writing at the end; whatever it cannot stream it reads
whole; a failed run leaves no partial table."""

from __future__ import annotations

import json

import numpy as np
import pytest

from radartracker.cli import main
from radartracker.domain import AdsbReport, Plot
from radartracker.errors import FormatError
from radartracker.geometry.plane import SystemPlane
from radartracker.io.scenario import open_scenario, read_scenario, write_scenario
from radartracker.pipeline import recorder, stream
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline import run as run_module
from radartracker.pipeline.run import counted, replay_folder, run, streamable
from radartracker.pipeline.stream import NotTimeOrdered, iter_files, scenario_stream
from radartracker.pipeline.writer import OutputStream, prepare, write_outputs
from radartracker.simulation.scenarios import build_scenario

TABLES = ("tracks.csv", "events.csv", "biases.csv", "coupling.graphml", "config.json")
MANAGER = RunConfig(association="manager", estimator="coupled-sparse")


@pytest.fixture(scope="module")
def unlabelled(tmp_path_factory):
    data = build_scenario("tracking", seed=5, duration=150.0).run()
    data.plots.target = np.full(len(data.plots), None, object)  # as a recording: no labels, no truth
    data.truth = None
    folder = tmp_path_factory.mktemp("stream") / "scen"
    write_scenario(folder, data)
    return folder


@pytest.fixture(scope="module")
def whole(unlabelled, tmp_path_factory):
    """The reference: the folder read whole, run, written at the end."""
    out = prepare(tmp_path_factory.mktemp("whole") / "out")
    write_outputs(run(read_scenario(unlabelled), MANAGER, progress=False), out)
    return out


def _summary(path):
    s = json.loads((path / "summary.json").read_text())
    s.pop("seconds"), s.pop("seconds_per_measurement")
    return s


def _same(a, b):
    for name in TABLES:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert _summary(a) == _summary(b)


def test_scenario_stream_is_the_stable_time_sort_of_plots_then_adsb():
    """Against the straightforward construction: one stable sort, one item per index."""
    d = build_scenario("demo", seed=2, duration=120.0).run()
    p, a = d.plots, d.adsb
    opt = (lambda v: None if np.isnan(v) else float(v))
    want = [Plot(float(p.time[i]), p.radar[i], float(p.range_m[i]), float(p.azimuth_rad[i]), opt(p.altitude_m[i]),
                 p.mode_s[i], p.mode_3a[i], p.target[i]) if i < len(p) else
            AdsbReport(float(a.time[i - len(p)]), a.icao24[i - len(p)], float(a.lat[i - len(p)]),
                       float(a.lon[i - len(p)]), opt(a.altitude_m[i - len(p)]), int(a.nacp[i - len(p)]))
            for i in np.argsort(np.concatenate([p.time, a.time]), kind="stable")]
    got = scenario_stream(d)
    assert got == want and len(got) > 500 and any(isinstance(x, AdsbReport) for x in got)


@pytest.mark.parametrize("prefetch", [False, True])
def test_items_from_the_files_are_those_of_the_tables(unlabelled, prefetch):
    data = read_scenario(unlabelled)
    want = scenario_stream(data)
    got = list(iter_files(open_scenario(unlabelled, block_bytes=4096), prefetch=prefetch))
    assert len(got) == len(want) == len(data.plots) + len(data.adsb) > 500
    assert got == want


@pytest.mark.parametrize("chunk", [1, 7, 100])
def test_items_are_made_chunk_at_a_time_in_the_same_order(unlabelled, monkeypatch, chunk):
    """Blocks of both files merged and their items made CHUNK at a time (plots and reports within a chunk):
    the items and order of the stable sort, in lists of at most CHUNK."""
    monkeypatch.setattr(stream, "CHUNK", chunk)
    want = scenario_stream(read_scenario(unlabelled))
    files = open_scenario(unlabelled, block_bytes=20000)
    lists = list(stream._merged(stream._ordered(files.plot_blocks(), "p"), stream._ordered(files.adsb_blocks(), "a")))
    assert [x for items in lists for x in items] == want
    assert max(map(len, lists)) == chunk < len(want)
    assert any({type(x) for x in items} == {Plot, AdsbReport} for items in lists) == (chunk > 1)


@pytest.mark.parametrize("block_bytes,flush_every", [(4096, 100), (1 << 20, None)])
def test_streamed_run_writes_the_same_bytes(unlabelled, whole, tmp_path, monkeypatch, block_bytes, flush_every):
    monkeypatch.setattr(recorder, "FLUSH_EVERY", flush_every or recorder.FLUSH_EVERY)
    out = prepare(tmp_path / "out")
    files = open_scenario(unlabelled, block_bytes=block_bytes)
    sink = OutputStream(out, SystemPlane(*files.data.reference))
    result = run(files.data, MANAGER, progress=False, inputs=iter_files(files), sink=sink, total=files.rows)
    write_outputs(result, out, streamed=sink)
    assert result.streamed and len(result.events) == 0  # nothing kept: no truth to evaluate against
    _same(out, whole)


def test_the_cli_streams_a_folder_and_config_reproduces_it(unlabelled, whole, tmp_path):
    assert streamable(unlabelled, RunConfig())  # auto: plots.csv has no target column
    out = tmp_path / "a"
    assert main(["--quiet", "replay", str(unlabelled), "--out", str(out), "--estimator", "coupled-sparse"]) == 0
    _same(out, whole)
    again = tmp_path / "b"
    assert main(["--quiet", "replay", str(unlabelled), "--config", str(out / "config.json"), "--out", str(again)]) == 0
    _same(again, whole)


def test_the_progress_bar_moves_on_by_each_piece_once_used():
    moves = []

    class Bar:
        def update(self, n):
            moves.append(n)

    items, used = list(range(1000)), []
    for piece in counted(iter(items), Bar(), every=256):
        assert sum(moves) == len(used)  # the pieces before, not this one
        used += piece
    assert used == items and moves == [256, 256, 256, 232]


def test_a_replay_with_its_progress_bar_writes_the_same_bytes_and_counts_every_input(unlabelled, whole, tmp_path,
                                                                                      monkeypatch):
    closed = []

    class Bar(run_module.tqdm):
        def close(self):
            if not self.disable:  # a closed bar is disabled; tqdm closes again when it is collected
                closed.append((self.n, self.total))
            super().close()

    monkeypatch.setattr(run_module, "tqdm", Bar)
    out = prepare(tmp_path / "out")
    replay_folder(unlabelled, MANAGER, out, progress=True)
    _same(out, whole)
    lines = sum(len((unlabelled / f).read_text().splitlines()) - 1 for f in ("plots.csv", "adsb.csv"))
    assert closed == [(lines, lines)]


def test_a_streamed_replay_makes_its_summary_once(unlabelled, whole, tmp_path, monkeypatch):
    made = []
    summary = run_module.RunResult.summary
    monkeypatch.setattr(run_module.RunResult, "summary", lambda self: made.append(1) or summary(self))
    replay_folder(unlabelled, MANAGER, prepare(tmp_path / "out"), progress=False)
    assert len(made) == 1
    _same(tmp_path / "out", whole)


def test_files_out_of_time_order_are_read_whole(unlabelled, whole, tmp_path):
    """plots.csv sorted by radar (each radar in time order, the file not): the same outputs, read whole."""
    folder = tmp_path / "scen"
    folder.mkdir()
    for f in unlabelled.iterdir():
        (folder / f.name).write_bytes(f.read_bytes())
    head, *rows = (unlabelled / "plots.csv").read_text().splitlines(keepends=True)
    rows.sort(key=lambda r: r.split(",")[1])
    (folder / "plots.csv").write_text(head + "".join(rows))
    for prefetch in (False, True):
        with pytest.raises(NotTimeOrdered):
            list(iter_files(open_scenario(folder, block_bytes=4096), prefetch=prefetch))
    out = prepare(tmp_path / "out")
    replay_folder(folder, MANAGER, out, progress=False)
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]
    _same(out, whole)


def test_with_truth_the_evaluation_is_that_of_the_whole_run(tmp_path):
    data = build_scenario("demo", seed=2, duration=120.0).run()
    write_scenario(tmp_path / "scen", data)
    ref = prepare(tmp_path / "ref")
    write_outputs(run(read_scenario(tmp_path / "scen"), MANAGER, progress=False), ref)
    out = prepare(tmp_path / "out")
    result = replay_folder(tmp_path / "scen", MANAGER, out, progress=False)
    assert result.streamed and len(result.events) > 0  # kept for the evaluation against truth
    _same(out, ref)
    assert _summary(out)["truth"]["estimates_compared"] > 0


def test_bad_rows_are_counted_in_file_order_when_streamed(unlabelled, tmp_path):
    folder = tmp_path / "scen"
    folder.mkdir()
    for f in unlabelled.iterdir():
        lines = f.read_text().splitlines(keepends=True)
        if f.name in ("plots.csv", "adsb.csv"):  # bad rows late in plots, early in ADS-B
            for k in ((len(lines) - 5, len(lines) - 3) if f.name == "plots.csv" else (2, 4)):
                fields = lines[k].split(",")
                fields[2] = "x" if f.name == "plots.csv" else "95"
                lines[k] = ",".join(fields)
            lines.insert(6, lines[5])  # an exact duplicate
        (folder / f.name).write_text("".join(lines))
    config = RunConfig(association="manager", estimator="coupled-sparse", skip_bad=True)
    ref = prepare(tmp_path / "ref")
    write_outputs(run(read_scenario(folder, skip_bad=True), config, progress=False), ref)
    out = prepare(tmp_path / "out")
    assert replay_folder(folder, config, out, progress=False).streamed
    _same(out, ref)
    skipped = _summary(out)["skipped_input_rows"]
    assert skipped == {"plots.csv:duplicate_row": 1, "plots.csv:malformed": 2, "adsb.csv:malformed": 2,
                       "adsb.csv:duplicate_row": 1}
    assert list(skipped) == ["plots.csv:duplicate_row", "plots.csv:malformed", "adsb.csv:malformed",
                             "adsb.csv:duplicate_row"]  # file order, as read whole


def test_a_failed_streamed_run_leaves_no_table(unlabelled, tmp_path):
    folder = tmp_path / "scen"
    folder.mkdir()
    for f in unlabelled.iterdir():
        (folder / f.name).write_bytes(f.read_bytes())
    lines = (folder / "plots.csv").read_text().splitlines(keepends=True)
    lines[len(lines) // 2] = lines[len(lines) // 2].replace(",", ",x", 1)  # unknown radar, half-way
    (folder / "plots.csv").write_text("".join(lines))
    out = prepare(tmp_path / "out")
    for prefetch in (False, True):  # an error in the reading thread is raised in the replay's
        with pytest.raises(FormatError, match=f"plots.csv.*line {len(lines) // 2 + 1}.*radar"):
            replay_folder(folder, MANAGER, out, progress=False, prefetch=prefetch)
        assert list(out.iterdir()) == []


def test_recorder_hands_on_and_drops_rows():
    got = []

    class Sink:
        def events(self, ev):
            got.append(len(ev))

        def biases(self, b):
            pass

    rec = recorder.Recorder(sink=Sink(), keep=False, flush_every=3)
    for k in range(7):
        rec.event(float(k), k % 2 + 1, "updated", "confirmed", np.zeros(4), None, None, None, None)
    rec.flush()
    assert got == [3, 3, 1] and len(rec.events()) == 0 and rec.track_ids == {1, 2}

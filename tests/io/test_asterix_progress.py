"""ASTERIX export and import move a progress bar over every record and byte; --quiet turns the bars off, also in
a process that imported tqdm before (tqdm reads its own TQDM_DISABLE once, at import)."""

import pytest
from tqdm import tqdm

import radartracker.progress
from radartracker.cli import main
from radartracker.io.scenario import write_scenario
from radartracker.simulation.scenarios import build_scenario


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    d = tmp_path_factory.mktemp("asterix_progress")
    data = build_scenario("demo", seed=3, duration=30.0).run()
    write_scenario(d / "scen", data)
    return d / "scen", len(data.plots) + len(data.adsb)


@pytest.fixture()
def bars(monkeypatch):
    """Every progress bar made, kept to be looked at."""
    made = []

    class Kept(tqdm):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.off, self.what = self.disable, kwargs.get("desc")  # close() sets disable; a disabled bar keeps no desc
            made.append(self)

    monkeypatch.setattr(radartracker.progress, "tqdm", Kept)
    return made


def test_export_then_import_count_every_record_and_byte(scenario, tmp_path, bars, capsys):
    folder, records = scenario
    assert main(["asterix-export", str(folder), "--out", str(tmp_path / "rec.ast")]) == 0
    assert main(["asterix-import", str(tmp_path / "rec.ast"), "--out", str(tmp_path / "back")]) == 0
    (write,) = [b for b in bars if b.what == "write rec.ast"]
    (read,) = [b for b in bars if b.what == "read rec.ast"]
    assert (write.n, write.total, write.unit, write.off) == (records, records, "record", False)
    size = (tmp_path / "rec.ast").stat().st_size
    assert (read.n, read.total, read.unit, read.off) == (size, size, "B", False)


@pytest.mark.parametrize("where", ["before", "after"])
def test_quiet_turns_the_bars_off(scenario, tmp_path, bars, capsys, where):
    folder, _ = scenario
    quiet = (["--quiet"], []) if where == "before" else ([], ["--quiet"])
    assert main([*quiet[0], "asterix-export", str(folder), "--out", str(tmp_path / "rec.ast"), *quiet[1]]) == 0
    assert main([*quiet[0], "asterix-import", str(tmp_path / "rec.ast"), "--out", str(tmp_path / "b"), *quiet[1]]) == 0
    assert {b.what for b in bars} >= {"write rec.ast", "read rec.ast"} and all(b.off for b in bars)

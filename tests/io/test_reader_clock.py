"""The scenario reader's stream clock with look ahead: a first row dated far ahead costs that row only,
and a pause of any length costs nothing (radartracker.io.rowchecks.PlotReader)."""

from __future__ import annotations

import shutil

import pytest

from radartracker.errors import FormatError
from radartracker.io.scenario import read_scenario, write_scenario
from radartracker.simulation.scenarios import build_scenario

@pytest.fixture(scope="module")
def lines(tmp_path_factory):
    folder = tmp_path_factory.mktemp("clock") / "s"
    write_scenario(folder, build_scenario("demo", seed=3, duration=120.0).run())
    return folder, (folder / "plots.csv").read_text().splitlines()

def _write(folder, lines):
    (folder / "plots.csv").write_text("\n".join(lines) + "\n")
    (folder / "adsb.csv").unlink(missing_ok=True)
    return folder

@pytest.mark.parametrize("fast", [True, False])
@pytest.mark.parametrize("far", ["1e12", "315576000"])  # 10⁹ s ahead, and ten years
def test_a_first_row_far_ahead_costs_itself(tmp_path, lines, far, fast):
    src, rows = lines

    folder = tmp_path / "s"
    shutil.copytree(src, folder)
    fields = rows[1].split(",")
    radar = fields[1]
    fields[0] = far
    _write(folder, [rows[0], ",".join(fields)] + rows[2:])
    n_radar = sum(1 for r in rows[2:] if r.split(",")[1] == radar)  # the radar's other plots: all kept
    data = read_scenario(folder, skip_bad=True, fast=fast)
    assert len(data.plots) == len(rows) - 2 and data.skipped == {"plots.csv:time_jump": 1}
    assert int((data.plots.radar == radar).sum()) == n_radar
    with pytest.raises(FormatError, match=r"plots.csv line 2, field 'time'"):  # that line, not the next good one
        read_scenario(folder, fast=fast)

@pytest.mark.parametrize("fast", [True, False])
@pytest.mark.parametrize("pause", [400.0, 7200.0])
def test_a_pause_costs_nothing(tmp_path, lines, pause, fast):

    src, rows = lines
    folder = tmp_path / "s"
    shutil.copytree(src, folder)
    out = [rows[0]]
    for r in rows[1:]:
        f = r.split(",")
        if float(f[0]) > 60.0:
            f[0] = f"{float(f[0]) + pause:.4f}"
        out.append(",".join(f))
    data = read_scenario(_write(folder, out), fast=fast)
    assert len(data.plots) == len(rows) - 1 and not data.skipped

def test_a_wild_row_between_good_ones_is_still_refused(tmp_path, lines):

    src, rows = lines
    folder = tmp_path / "s"
    shutil.copytree(src, folder)
    k = len(rows) // 2
    f = rows[k].split(",")
    f[0] = f"{float(f[0]) + 5000.0:.4f}"  # one row 5 000 s ahead: the rows after it are not a run with it
    data = read_scenario(_write(folder, rows[:k] + [",".join(f)] + rows[k + 1:]), skip_bad=True)
    assert len(data.plots) == len(rows) - 2 and data.skipped == {"plots.csv:time_jump": 1}
    with pytest.raises(FormatError, match=rf"plots.csv line {k + 1}, field 'time': .* ahead"):
        read_scenario(folder)

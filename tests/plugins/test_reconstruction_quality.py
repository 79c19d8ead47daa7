"""Quality flags, warnings, flight selection and exit status of ``reconstruct``.

Oracles: the ``manoeuvres`` scenario's own truth — its turns need u = v·ω (3°/s at 140–290 m/s,
7–15 m/s²), computed here from truth.csv by finite differences, far beyond the seed's bound of
4 m/s² — and its truth.csv positions for the error in summary.json (recomputed here from track.csv).
"""

import csv
import json

import numpy as np
import pytest

from radartracker.cli import main
from radartracker.geometry.plane import SystemPlane
from radartracker.io.scenario import write_scenario
from radartracker.simulation.scenarios import build_scenario


@pytest.fixture(scope="module")
def manoeuvres(tmp_path_factory):
    data = build_scenario("manoeuvres", seed=1, duration=400.0).run()
    folder = tmp_path_factory.mktemp("man") / "scenario"
    write_scenario(folder, data)
    return folder, data


def _true_lateral_acceleration(data, key):
    """max |u| = |v × a| / |v| of the truth, by finite differences of its plane positions."""
    plane = SystemPlane(*data.reference)
    sel = data.truth.target == key
    t = data.truth.time[sel]
    x, y = plane.to_plane(data.truth.lat[sel], data.truth.lon[sel])
    vx, vy = np.gradient(x, t), np.gradient(y, t)
    ax, ay = np.gradient(vx, t), np.gradient(vy, t)
    return float(np.max(np.abs(vx * ay - vy * ax) / np.hypot(vx, vy)))


FAST = ["--engine", "serial", "--quiet", "--no-figures", "--hypotheses", "4", "--no-shooting", "--truth-biases"]
SEED_BOUNDS = ["--max-u", "4", "--max-w", "2"]  # seed 000's bounds (no longer the defaults: docs/reconstruction.md)


def _run(folder, out, flights, *extra):
    return main(["reconstruct", str(folder), "--out", str(out), "--flights", ",".join(flights), *FAST, *extra])


def test_seed_bounds_on_manoeuvres_warn_name_the_flight_and_fail(manoeuvres, tmp_path, capsys):
    folder, data = manoeuvres
    key = sorted(set(data.truth.target))[0]
    assert _true_lateral_acceleration(data, key) > 6.0  # the truth needs more than the seed's 4 m/s²
    assert _run(folder, tmp_path / "o", [key], *SEED_BOUNDS) == 2  # every aircraft implausible: exit 2
    err = capsys.readouterr().err
    assert "no flight reconstructed plausibly" in err and "summary.json" in err and len(err.splitlines()) == 1
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    (row,) = s["reconstructed"]
    assert {"control": "u", "bound_mps2": 4.0} == {k: row["quality"]["pinned"][0][k] for k in ("control", "bound_mps2")}
    assert "--max-u" in row["quality"]["verdict"]
    assert s["implausible"] == [key] and row["quality"]["plausible"] is False
    assert row["quality"]["verdict"].startswith("implausible") and row["quality"]["chi2"] > 4
    assert any(p["control"] == "u" and p["bound_mps2"] == 4.0 for p in row["quality"]["pinned"])
    rows = list(csv.DictReader(open(tmp_path / "o" / key / "track.csv")))
    assert any("u" in r["pinned"] for r in rows)
    # the error in summary.json is the error against truth.csv (recomputed from the track at the plot times)
    assert row["truth_error"]["median_m"] > 150.0


def test_wide_bounds_fit_plausibly_and_report_the_truth_error(manoeuvres, tmp_path, capsys):
    folder, data = manoeuvres
    key = sorted(set(data.truth.target))[1]
    assert _run(folder, tmp_path / "o", [key], "--max-u", "16", "--max-w", "4") == 0
    assert "warning" not in capsys.readouterr().err
    (row,) = json.loads((tmp_path / "o" / "summary.json").read_text())["reconstructed"]
    q = row["quality"]
    assert q["plausible"] and q["pinned"] == [] and 0.5 < q["chi2"] < 2.0
    plane = SystemPlane(*data.reference)
    sel = data.truth.target == key
    tx, ty = plane.to_plane(data.truth.lat[sel], data.truth.lon[sel])
    rows = list(csv.DictReader(open(tmp_path / "o" / key / "track.csv")))
    t = np.array([float(r["time"]) for r in rows])
    e = np.hypot(np.interp(t, data.truth.time[sel], tx) - [float(r["x_m"]) for r in rows],
                 np.interp(t, data.truth.time[sel], ty) - [float(r["y_m"]) for r in rows])
    assert row["truth_error"]["median_m"] == pytest.approx(np.median(e), rel=0.3)  # plot times vs 1 s grid
    assert row["truth_error"]["median_m"] < 60.0


def test_unknown_flight_is_a_clear_error(manoeuvres, tmp_path, capsys):
    folder, _ = manoeuvres
    assert _run(folder, tmp_path / "o", ["nosuch"]) == 2
    assert "--flights: no aircraft nosuch" in capsys.readouterr().err


@pytest.mark.slow
def test_every_pinned_flight_of_manoeuvres_warns(manoeuvres, tmp_path, capsys):
    folder, data = manoeuvres
    keys = sorted(set(data.truth.target))
    assert main(["reconstruct", str(folder), "--out", str(tmp_path / "o"), "--engine", "serial", "--quiet",
                 "--no-figures", "--truth-biases", *SEED_BOUNDS]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no flight reconstructed plausibly" in err[0], err  # the warnings: in summary.json
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    warned = {r["key"]: " ".join(r["warnings"]) for r in s["reconstructed"]}
    for key in keys:
        assert _true_lateral_acceleration(data, key) > 4.0
        segs = list(csv.DictReader(open(tmp_path / "o" / key / "segments.csv")))
        if any(abs(float(r["u_mps2"])) >= 0.99 * 4.0 for r in segs):
            assert f"{key}: lateral control u pinned at its bound 4 m/s²" in warned[key]
    assert sorted(s["implausible"]) == keys

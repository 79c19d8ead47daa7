"""``radartracker triangulate`` end to end through the documented CSV formats.

Oracles: positions simulated with pyproj, judged against the covariances the command writes by
a χ² bound; malformed input named by file, line and field.
"""

import csv
import json
import math

import numpy as np
import pytest
from scipy import stats

from radartracker.cli import main
from radartracker_plugins.triangulation import DirectionFinder, TriangulationFrame
from radartracker_plugins.triangulation.simulate import noisy_bearings, sites_around, true_bearings

LAT, LON, SIG_DEG = 50.0, 7.0, 0.05
REF = (50.0, 7.0, 0.0)


def _write_stations(path):
    sites = sites_around(LAT, LON, 35e3, [30, 150, 270])
    rows = [(f"df{i}", la, lo, 120.0) for i, (la, lo) in enumerate(sites)]
    with open(path, "w") as fh:
        fh.write("# direction finders\nid,lat_deg,lon_deg,height_m,sigma_azimuth_deg,sigma_elevation_deg\n")
        for r in rows:
            fh.write(f"{r[0]},{r[1]:.9f},{r[2]:.9f},{r[3]},{SIG_DEG},{SIG_DEG}\n")
    s = math.radians(SIG_DEG)
    return TriangulationFrame([DirectionFinder(r[0], r[1], r[2], r[3], s, s) for r in rows], REF)


def _write_bearings(path, rows):
    with open(path, "w") as fh:
        fh.write("time_s,station,azimuth_deg,elevation_deg,target\n")
        for t, sid, az, el, target in rows:
            fh.write(f"{t:.3f},{sid},{math.degrees(az):.9f},{math.degrees(el):.9f},{target}\n")


def _rows(frame, ids, times, positions, target, rng):
    bs = noisy_bearings(frame, ids, times, true_bearings(frame, ids, positions), rng, target)
    return [(b.time, b.station, b.azimuth_rad, b.elevation_rad, b.target) for b in bs]


def _read_csv(path):
    with open(path) as fh:
        return list(csv.DictReader(fh))


def _nees(row, truth):
    e = np.array([float(row[k]) for k in ("east_m", "north_m", "up_m")]) - truth
    c = [float(row[k]) for k in ("cov_ee_m2", "cov_en_m2", "cov_eu_m2", "cov_nn_m2", "cov_nu_m2", "cov_uu_m2")]
    C = np.array([[c[0], c[1], c[2]], [c[1], c[3], c[4]], [c[2], c[4], c[5]]])
    return e @ np.linalg.solve(C, e)


def test_static_command_writes_fixes_and_refuses_single_station(tmp_path, capsys):
    frame = _write_stations(tmp_path / "stations.csv")
    rng = np.random.default_rng(9)
    target = frame.enu(LAT + 0.05, LON - 0.1, 7000.0)
    ids = list(frame.stations) * 2
    rows = _rows(frame, ids, np.arange(6.0), np.tile(target, (6, 1)), "A", rng)
    rows += _rows(frame, ["df0"] * 3, [0.0, 1.0, 2.0], np.tile(target, (3, 1)), "lonely", rng)
    _write_bearings(tmp_path / "bearings.csv", rows)
    out = tmp_path / "out"
    rc = main(["triangulate", str(tmp_path / "bearings.csv"), "--stations", str(tmp_path / "stations.csv"),
               "--out", str(out), "--reference", ",".join(map(str, REF))])
    assert rc == 0
    assert "target lonely: refused" in capsys.readouterr().err
    fixes = _read_csv(out / "fixes.csv")
    assert [f["target"] for f in fixes] == ["A"]
    assert _nees(fixes[0], target) < stats.chi2.ppf(0.9999, 3)
    assert fixes[0]["status"] == "ok" and int(fixes[0]["dof"]) == 9
    summary = json.loads((out / "summary.json").read_text())
    assert summary["solved"] == ["A"] and "GDOP" in summary["refused"]["lonely"]
    assert summary["reference"]["lat_deg"] == REF[0]


def test_dynamic_command_writes_tracks_at_bearing_times(tmp_path):
    frame = _write_stations(tmp_path / "stations.csv")
    rng = np.random.default_rng(4)
    ids = np.array(["df0", "df1", "df2"] * 20)
    times = np.arange(60) * 1.7 + 0.3  # each station every 5.1 s, staggered
    start = frame.enu(LAT, LON, 9000.0)
    pos = start + np.outer(times, [150.0, -90.0, 2.0])
    _write_bearings(tmp_path / "bearings.csv", _rows(frame, ids, times, pos, "M", rng))
    out = tmp_path / "out"
    rc = main(["triangulate", str(tmp_path / "bearings.csv"), "--stations", str(tmp_path / "stations.csv"),
               "--out", str(out), "--mode", "dynamic", "--order", "1",
               "--reference", ",".join(map(str, REF))])
    assert rc == 0
    rows = _read_csv(out / "tracks.csv")
    assert len(rows) == 60 and np.allclose([float(r["time_s"]) for r in rows], times)
    # positions at different times are correlated; check the first, middle and last
    for k in (0, 30, 59):
        assert _nees(rows[k], pos[k]) < stats.chi2.ppf(0.9999, 3)
    assert json.loads((out / "summary.json").read_text())["order"] == 1
    rc = main(["triangulate", str(tmp_path / "bearings.csv"), "--stations", str(tmp_path / "stations.csv"),
               "--out", str(tmp_path / "grid"), "--mode", "dynamic", "--step", "10",
               "--reference", ",".join(map(str, REF))])
    grid = _read_csv(tmp_path / "grid" / "tracks.csv")
    assert rc == 0 and np.allclose([float(r["time_s"]) for r in grid], np.arange(times[0], times[-1], 10.0))


@pytest.mark.parametrize("line,field", [
    ("1.0,df0,400.0,1.0,A", "azimuth_deg"), ("x,df0,40.0,1.0,A", "time_s"),
    ("1.0,df0,40.0,nan,A", "elevation_deg"), ("1.0,,40.0,1.0,A", "station"),
])
def test_bad_bearing_row_is_named_by_file_line_and_field(tmp_path, capsys, line, field):
    _write_stations(tmp_path / "stations.csv")
    (tmp_path / "bearings.csv").write_text(
        "time_s,station,azimuth_deg,elevation_deg,target\n0.0,df1,10.0,1.0,A\n" + line + "\n")
    rc = main(["triangulate", str(tmp_path / "bearings.csv"), "--stations", str(tmp_path / "stations.csv"),
               "--out", str(tmp_path / "out")])
    assert rc == 2
    assert f"bearings.csv line 3, field '{field}'" in capsys.readouterr().err


def test_skip_bad_counts_malformed_and_unknown_station_rows(tmp_path):
    frame = _write_stations(tmp_path / "stations.csv")
    target = frame.enu(LAT, LON, 5000.0)
    rows = _rows(frame, list(frame.stations), np.zeros(3), np.tile(target, (3, 1)), "A",
                 np.random.default_rng(1))
    _write_bearings(tmp_path / "bearings.csv", rows)
    with open(tmp_path / "bearings.csv", "a") as fh:
        fh.write("1.0,df0,400.0,1.0,A\n1.0,nowhere,40.0,1.0,A\n1.0,df0\n")
    args = ["triangulate", str(tmp_path / "bearings.csv"), "--stations", str(tmp_path / "stations.csv")]
    assert main(args + ["--out", str(tmp_path / "strict")]) == 2
    assert main(args + ["--out", str(tmp_path / "out"), "--skip-bad"]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["skipped_rows"] == {"malformed": 2, "duplicate": 0, "unknown_station": 1}
    assert summary["solved"] == ["A"]


def test_non_empty_output_folder_is_refused(tmp_path, capsys):
    _write_stations(tmp_path / "stations.csv")
    (tmp_path / "bearings.csv").write_text("time_s,station,azimuth_deg,elevation_deg\n")
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "keep.txt").write_text("x")
    rc = main(["triangulate", str(tmp_path / "bearings.csv"), "--stations", str(tmp_path / "stations.csv"),
               "--out", str(tmp_path / "out")])
    assert rc == 2 and "not empty" in capsys.readouterr().err

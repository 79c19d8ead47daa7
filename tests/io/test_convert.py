"""The ``tracks_plots_00`` converter: selection, filtering, sorting, accounting, failure safety.

Oracles: the expected selection, per-track contents and counts are recomputed in the test with
plain Python from the records it generated (never from the converter's own output).
"""

from __future__ import annotations

import json
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import pytest

import radartracker.io.convert as conv
from radartracker.cli import main
from radartracker.io.convert import ConvertOptions, convert
from radartracker.io.recording import (AdsRecord, PlotRecord, TrackRecord, read_converted, read_new4, read_plt, write_recording)

FILES = ("plots_ads.txt", "tracks.txt", "plots.txt")


def _records(seed=0):
    """A small shuffled recording: 8 aircraft with 2..40 ADS-B reports, 2 radars, mixed sensors."""
    rng = np.random.default_rng(seed)
    recs = []
    for g in range(1, 9):
        n_ads = [40, 35, 35, 30, 12, 25, 2, 0][g - 1]
        for k in range(n_ads):
            recs.append(AdsRecord(1000.0 + k, g, f"{g:06x}", 56 + g * 0.01 + k * 1e-4, 37.0 + k * 1e-4,
                                  9000.0 + k, 8))
        for k in range(int(rng.integers(4, 16))):
            recs.append(TrackRecord(1000.0 + 4 * k, None, "240", g, None, 56 + k * 1e-3, 37.1, 9000.0))
        for radar in ("5", "17"):
            for k in range(int(rng.integers(3, 14))):
                sensor = str(rng.choice(["1", "3", "3"]))
                recs.append(TrackRecord(1000.5 + 5 * k, sensor, radar, g, 10 * g, 56.2 + k * 1e-3, 37.3, None))
                recs.append(PlotRecord(1000.0 + 5 * k, sensor, radar, g, 10 * g, 56.3 + k * 1e-3,
                                       37.4 + rng.uniform(0, 1e-3), 8000.0, 1e5 + k, 90.0 + k))
    recs.append(PlotRecord(1003.0, "3", "5", None, None, 56.0, 37.0, None, 5e4, 10.0))  # unassociated
    rng.shuffle(recs)  # time order is not assumed
    return recs


def _expected(recs, opts: ConvertOptions):
    """Oracle: the seed's rules applied naively in memory."""
    ads = Counter(r.global_ for r in recs if isinstance(r, AdsRecord))
    eligible = sorted((g for g, c in ads.items() if c >= opts.AZN_TRACKS_MIN_MEASUR), key=lambda g: (-ads[g], g))
    chosen = set(eligible[: opts.AZN_TRACKS_MAX])
    tracks = defaultdict(list)
    for r in recs:
        if r.global_ not in chosen:
            continue
        if isinstance(r, AdsRecord):
            stem = "ads"
        elif isinstance(r, TrackRecord) and r.radar == "240":
            stem = "240_mr"
        else:
            if opts.RADAR_SENSOR_ONLY is not None and r.sensor != opts.RADAR_SENSOR_ONLY:
                continue
            stem = f"{r.radar}_{'r' if isinstance(r, PlotRecord) else 'mr'}"
        tracks[(r.global_, stem)].append(r)
    return {k: sorted(v, key=lambda r: r.time) for k, v in tracks.items() if len(v) >= opts.TRACKS_MIN_MEASUR}


def _count_lines(path: Path) -> int:
    return len(path.read_bytes().splitlines())


OPTS = ConvertOptions(AZN_TRACKS_MAX=3, AZN_TRACKS_MIN_MEASUR=10, TRACKS_MIN_MEASUR=5, RADAR_SENSOR_ONLY="3")


@pytest.mark.parametrize("bucket_bytes", [32 << 20, 1 << 10])  # one bucket; many buckets (external sort)
def test_convert_matches_naive_oracle(tmp_path, bucket_bytes):
    recs = _records()
    write_recording(tmp_path / "rec", recs)
    opts = ConvertOptions(3, 10, 5, "3", bucket_bytes)
    report = convert(tmp_path / "rec", tmp_path / "new", opts)
    expected = _expected(recs, opts)
    assert report["selected_aircraft"] == [1, 2, 3]  # 40, 35, 35 reports; tie broken by number
    if bucket_bytes < 4096:
        assert report["buckets"] == 3
    got = {}
    for d in (tmp_path / "new").iterdir():
        if d.is_dir():
            for stem, pts in read_converted(d).items():
                got[(int(d.name), stem)] = pts
                assert (d / f"{stem}.plt").exists()
    assert set(got) == set(expected)
    for key, rows in expected.items():
        pts = got[key]
        np.testing.assert_allclose(pts.time, [r.time for r in rows], atol=5e-4)
        np.testing.assert_allclose(pts.lat, [r.lat for r in rows], atol=5.1e-8)
        np.testing.assert_allclose(pts.lon, [r.lon for r in rows], atol=5.1e-8)
        alt = np.array([np.nan if r.altitude_m is None else r.altitude_m for r in rows])
        np.testing.assert_allclose(pts.altitude_m, alt, atol=0.05)
        plt = read_plt(tmp_path / "new" / str(key[0]) / f"{key[1]}.plt")
        np.testing.assert_allclose(plt.lat, pts.lat, atol=1e-12)
        np.testing.assert_allclose(plt.time, pts.time, atol=1e-4)
    # accounting: every line counted once; "written" equals the rows in the .new4 files
    on_disk = json.loads((tmp_path / "new" / "report.json").read_text())
    assert on_disk["files"] == report["files"]
    for name in FILES:
        f = report["files"][name]
        assert f["lines"] == _count_lines(tmp_path / "rec" / name)
        reasons = {k: v for k, v in f.items() if isinstance(v, int) and k not in ("lines", "output_files", "accounted")}
        assert sum(reasons.values()) == f["lines"]
    written = sum(len(v) for v in expected.values())
    assert sum(f.get("written", 0) for f in report["files"].values()) == written
    n_sensor = sum(1 for r in recs if not isinstance(r, AdsRecord) and r.global_ in (1, 2, 3)
                   and r.radar != "240" and r.sensor != "3")
    assert (report["files"]["tracks.txt"].get("sensor_filtered", 0)
            + report["files"]["plots.txt"].get("sensor_filtered", 0)) == n_sensor
    assert report["files"]["plots.txt"]["unassociated"] == 1
    ads = report["files"]["plots_ads.txt"]
    assert ads["aircraft_over_AZN_TRACKS_MAX"] == 30 + 12 + 25  # aircraft 4, 5, 6 are eligible
    assert ads["aircraft_ads_track_too_short"] == 2  # aircraft 7
    assert not list(tmp_path.glob(".new.partial-*"))


def test_crlf_and_lf_give_identical_output(tmp_path):
    write_recording(tmp_path / "rec", _records(1))
    crlf = tmp_path / "crlf"
    crlf.mkdir()
    for name in FILES:
        (crlf / name).write_bytes((tmp_path / "rec" / name).read_bytes().replace(b"\n", b"\r\n"))
    a = convert(tmp_path / "rec", tmp_path / "new_lf", OPTS)
    b = convert(crlf, tmp_path / "new_crlf", OPTS)
    assert a["files"] == b["files"]
    for p in (tmp_path / "new_lf").rglob("*.new4"):
        assert p.read_bytes() == (tmp_path / "new_crlf" / p.relative_to(tmp_path / "new_lf")).read_bytes()


def test_malformed_and_truncated_lines_are_counted_with_line_numbers(tmp_path):
    write_recording(tmp_path / "rec", _records(2))
    path = tmp_path / "rec" / "plots.txt"
    lines = path.read_text().splitlines(keepends=True)
    cols = lines[5].split("\t")
    bad = [
        "\t".join(cols[:5]) + "\n",                                  # too few fields
        "\t".join(cols[:5] + ["north"] + cols[6:]),                  # lat not a number
        "\t".join(cols[:5] + ["91.0"] + cols[6:]),                   # lat out of range
        "\t".join(cols[:3] + ["-4"] + cols[4:]),                     # global negative
        "\n",                                                        # blank
    ]
    lines[3:3] = bad  # lines 4..8
    truncated = lines[-1][: len(lines[-1]) // 2]                    # a cut-off last line, no newline
    path.write_text("".join(lines[:-1]) + truncated)
    report = convert(tmp_path / "rec", tmp_path / "new", OPTS)
    f = report["files"]["plots.txt"]
    assert f["malformed"] == 4 and f["line_numbers"]["malformed"] == [4, 5, 6, 7]
    assert f["blank"] == 1 and f["line_numbers"]["blank"] == [8]
    n = len(lines)
    assert f["truncated_last_line"] == 1 and f["line_numbers"]["truncated_last_line"] == [n]
    assert f["lines"] == n and f["accounted"] == n
    msgs = [e["error"] for e in f["first_errors"]]
    assert "plots.txt: line 5: field lat: not a number: 'north'" in msgs
    assert any("line 6: field lat" in m and "outside" in m for m in msgs)
    assert any("line 7: field global" in m for m in msgs)


def test_empty_or_headerless_file_is_a_clear_error_and_writes_nothing(tmp_path):
    write_recording(tmp_path / "rec", _records(3))
    (tmp_path / "rec" / "tracks.txt").write_bytes(b"")
    with pytest.raises(ValueError, match=r"tracks\.txt line 1: empty file"):
        convert(tmp_path / "rec", tmp_path / "new", OPTS)
    (tmp_path / "rec" / "tracks.txt").write_text("time\tradar\n1\t2\n")
    with pytest.raises(ValueError, match=r"tracks\.txt line 1: header lacks column\(s\) sensor, global"):
        convert(tmp_path / "rec", tmp_path / "new", OPTS)
    (tmp_path / "rec" / "tracks.txt").unlink()
    with pytest.raises(FileNotFoundError, match="tracks.txt"):
        convert(tmp_path / "rec", tmp_path / "new", OPTS)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec"]


def test_header_only_files_convert_to_an_empty_result(tmp_path):
    write_recording(tmp_path / "rec", [])
    report = convert(tmp_path / "rec", tmp_path / "new", OPTS)
    assert report["selected_aircraft"] == []
    assert all(f["lines"] == 1 and f["header"] == 1 for f in report["files"].values())
    assert sorted(p.name for p in (tmp_path / "new").iterdir()) == ["report.json"]


def test_existing_output_folder_is_refused_untouched(tmp_path):
    write_recording(tmp_path / "rec", _records(4))
    (tmp_path / "new").mkdir()
    (tmp_path / "new" / "mine.txt").write_text("keep")
    with pytest.raises(FileExistsError, match="must not exist"):
        convert(tmp_path / "rec", tmp_path / "new", OPTS)
    assert [p.name for p in (tmp_path / "new").iterdir()] == ["mine.txt"]


def test_crash_midway_leaves_nothing_behind(tmp_path, monkeypatch):
    write_recording(tmp_path / "rec", _records(5))
    real = conv._write_bucket
    calls = []

    def crash(*a, **k):
        real(*a, **k)  # some output files exist in the temporary folder by now
        calls.append(1)
        raise OSError("disk full")

    monkeypatch.setattr(conv, "_write_bucket", crash)
    with pytest.raises(OSError, match="disk full"):
        convert(tmp_path / "rec", tmp_path / "new", OPTS)
    assert calls and sorted(p.name for p in tmp_path.iterdir()) == ["rec"]


def test_cli_convert(tmp_path, capsys):
    write_recording(tmp_path / "rec", _records(6))
    args = ["convert", str(tmp_path / "rec"), "--out", str(tmp_path / "new"), "--AZN_TRACKS_MAX", "2",
            "--AZN_TRACKS_MIN_MEASUR", "10", "--TRACKS_MIN_MEASUR", "3", "--RADAR_SENSOR_ONLY", "1"]
    assert main(args) == 0
    report = json.loads((tmp_path / "new" / "report.json").read_text())
    assert report["selected_aircraft"] == [1, 2]
    assert report["parameters"]["RADAR_SENSOR_ONLY"] == "1"
    assert main(args) == 2
    assert "already exists" in capsys.readouterr().err
    assert main(["convert", str(tmp_path / "nowhere"), "--out", str(tmp_path / "n2")]) == 2


def test_simulated_scenario_round_trip(tmp_path):
    from radartracker.geometry.plane import RadarFrame, SystemPlane
    from radartracker.io.recording import write_scenario_recording
    from radartracker.simulation.scenarios import build_scenario

    data = build_scenario("manoeuvres", seed=2, duration=200).run()
    write_scenario_recording(tmp_path / "rec", data)
    opts = ConvertOptions(AZN_TRACKS_MAX=10, AZN_TRACKS_MIN_MEASUR=10, TRACKS_MIN_MEASUR=3)
    report = convert(tmp_path / "rec", tmp_path / "new", opts)
    number = {a.icao24: i + 1 for i, a in enumerate(data.aircraft)}
    with_ads = {number[i] for i in set(data.adsb.icao24.tolist())}
    assert set(report["selected_aircraft"]) == with_ads and with_ads
    plane = SystemPlane(*data.reference)
    n_plots = 0
    for g in with_ads:
        icao = data.aircraft[g - 1].icao24
        sel = data.adsb.icao24 == icao
        order = np.argsort(data.adsb.time[sel], kind="stable")
        ads = read_new4(tmp_path / "new" / str(g) / "ads.new4")
        np.testing.assert_allclose(ads.time, data.adsb.time[sel][order], atol=5e-4)
        np.testing.assert_allclose(ads.lat, data.adsb.lat[sel][order], atol=5.1e-8)
        np.testing.assert_allclose(ads.lon, data.adsb.lon[sel][order], atol=5.1e-8)
        for radar in data.radars:
            mask = (data.plots.target == icao) & (data.plots.radar == radar.id)
            path = tmp_path / "new" / str(g) / f"{radar.id}_r.new4"
            if mask.sum() < opts.TRACKS_MIN_MEASUR:
                assert not path.exists()
                continue
            pts = read_new4(path)
            o = np.argsort(data.plots.time[mask], kind="stable")
            np.testing.assert_allclose(pts.time, data.plots.time[mask][o], atol=5e-4)
            # the plot position re-measured with the exact polar model gives back the measurement
            rho, theta, _ = RadarFrame(radar.lat, radar.lon, radar.height_m, plane).polar(
                pts.lat, pts.lon, np.nan_to_num(pts.altitude_m))
            np.testing.assert_allclose(rho, data.plots.range_m[mask][o], atol=0.05)
            dth = np.angle(np.exp(1j * (theta - data.plots.azimuth_rad[mask][o])))
            np.testing.assert_allclose(dth * rho, 0.0, atol=0.05)
            n_plots += len(pts.time)
    assert n_plots > 0


def test_cli_simulate_write_recording_convert(tmp_path):
    from radartracker.io.scenario import write_scenario
    from radartracker.simulation.scenarios import build_scenario

    data = build_scenario("demo", seed=1, duration=150).run()
    write_scenario(tmp_path / "scen", data)
    assert main(["write-recording", "--scenario", str(tmp_path / "scen"), "--out", str(tmp_path / "rec")]) == 0
    n_lines = {n: _count_lines(tmp_path / "rec" / n) for n in FILES}
    assert n_lines == {"plots_ads.txt": len(data.adsb) + 1, "tracks.txt": 1, "plots.txt": len(data.plots) + 1}
    assert main(["convert", str(tmp_path / "rec"), "--out", str(tmp_path / "new"),
                 "--AZN_TRACKS_MIN_MEASUR", "5", "--TRACKS_MIN_MEASUR", "2"]) == 0
    report = json.loads((tmp_path / "new" / "report.json").read_text())
    equipped = sorted(i + 1 for i, a in enumerate(data.aircraft) if a.icao24 in set(data.adsb.icao24.tolist()))
    assert sorted(report["selected_aircraft"]) == equipped
    assert report["files"]["plots_ads.txt"]["written"] == len(data.adsb)
    assert main(["write-recording", "--synthetic-mb", "0.2", "--out", str(tmp_path / "syn")]) == 0
    assert sum(p.stat().st_size for p in (tmp_path / "syn").iterdir()) >= 0.2e6


def test_cli_bad_recordings_give_one_line_naming_the_file(tmp_path, capsys):
    """Exit 2 and one line (no traceback) for a binary file, a folder where a file belongs, a missing one."""
    write_recording(tmp_path / "rec", _records(8))
    cases = {"plots.txt": ("bytes", bytes(range(128, 256))), "tracks.txt": ("folder", None),
             "plots_ads.txt": ("missing", None)}
    for name, (kind, content) in cases.items():
        path = tmp_path / "rec" / name
        saved = path.read_bytes()
        path.unlink()
        if kind == "bytes":
            path.write_bytes(content)
        elif kind == "folder":
            path.mkdir()
        assert main(["convert", str(tmp_path / "rec"), "--out", str(tmp_path / "new")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        expected = {"bytes": "plots.txt line 1: not UTF-8", "folder": "tracks.txt: not a file",
                    "missing": "plots_ads.txt: missing"}[kind]
        assert len(err) == 1 and expected in err[0], err
        path.rmdir() if kind == "folder" else path.unlink(missing_ok=True)
        path.write_bytes(saved)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec"]


def test_cli_names_the_first_malformed_line_and_exits_2_when_nothing_is_selected(tmp_path, capsys):
    recs = [r for r in _records(9) if not isinstance(r, AdsRecord)]  # no ADS-B: no aircraft can be selected
    write_recording(tmp_path / "rec", recs)
    lines = (tmp_path / "rec" / "plots.txt").read_text().splitlines(keepends=True)
    cols = lines[2].split("\t")
    lines[2] = "\t".join(cols[:5] + ["north"] + cols[6:])  # line 3: lat
    (tmp_path / "rec" / "plots.txt").write_text("".join(lines))
    assert main(["convert", str(tmp_path / "rec"), "--out", str(tmp_path / "new")]) == 2
    out, err = capsys.readouterr()
    assert "1 malformed (first: plots.txt: line 3: field lat: not a number: 'north')" in out
    assert len(err.splitlines()) == 1 and "no aircraft has 20 or more ADS-B reports" in err
    assert json.loads((tmp_path / "new" / "report.json").read_text())["files"]["plots.txt"]["malformed"] == 1


@pytest.mark.parametrize("argv,words", [
    (["write-recording", "--synthetic-mb", "nan"], "--synthetic-mb: nan is not finite"),
    (["write-recording", "--synthetic-mb", "inf"], "--synthetic-mb: inf is not finite"),
    (["write-recording", "--synthetic-mb", "0"], "--synthetic-mb: 0.0 must be > 0"),
    (["write-recording", "--synthetic-mb", "1e300"], "--synthetic-mb: 1e+300 must be <="),  # never ended
    (["write-recording", "--synthetic-mb", "0.1", "--seed", "-1"], "--seed: -1 must be >= 0"),
    (["convert", "REC", "--bucket-mb", "inf"], "--bucket-mb: inf is not finite"),
    (["convert", "REC", "--bucket-mb", "nan"], "--bucket-mb: nan is not finite"),
])
def test_cli_numeric_options_are_refused_in_one_line(tmp_path, capsys, argv, words):
    write_recording(tmp_path / "rec", _records(1))
    argv = [str(tmp_path / "rec") if a == "REC" else a for a in argv]
    assert main([*argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec"]

"""Recording formats: writers, .new4 and OziExplorer .plt readers/writers (seed 000 §2.6)."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from radartracker.io.recording import (ADS_COLUMNS, PLOT_COLUMNS, TRACK_COLUMNS, AdsRecord, PlotRecord, TrackPoints, TrackRecord, format_plt, ozi_days, read_new4, read_plt, write_new4, write_plt, write_recording)


def _points(n=25, seed=3):
    rng = np.random.default_rng(seed)
    t = 1.7e9 + np.sort(rng.uniform(0, 3600, n))
    alt = rng.uniform(0, 12000, n)
    alt[3] = np.nan
    return TrackPoints(t, rng.uniform(-89, 89, n), rng.uniform(-179, 179, n), alt)


def test_ozi_days_against_datetime():
    # Oracle: calendar arithmetic of the standard library, independent of ozi_days' constant.
    when = dt.datetime(2024, 2, 29, 13, 45, 30, tzinfo=dt.timezone.utc)
    expected = (when - dt.datetime(1899, 12, 30, tzinfo=dt.timezone.utc)).total_seconds() / 86400
    assert ozi_days(when.timestamp()) == pytest.approx(expected, abs=1e-10)
    assert ozi_days(0.0) == 25569.0  # 1970-01-01 in the Delphi/OLE calendar


def test_plt_layout_and_round_trip(tmp_path):
    pts = _points()
    path = tmp_path / "a.plt"
    write_plt(path, pts, name="42 ads")
    lines = path.read_text().splitlines()
    assert lines[0].startswith("OziExplorer Track Point File Version")
    assert lines[1] == "WGS 84" and lines[2] == "Altitude is in Feet"
    assert int(lines[5]) == len(pts.time) and len(lines) == 6 + len(pts.time)
    first = lines[6].split(",")
    assert first[2] == "1" and lines[7].split(",")[2] == "0"  # a new track starts with a break
    assert float(first[3]) == pytest.approx(pts.altitude_m[0] / 0.3048, abs=0.05)
    assert lines[9].split(",")[3] == "-777"  # missing altitude
    when = dt.datetime.fromtimestamp(pts.time[0], dt.timezone.utc)
    assert first[5] == when.strftime("%d-%b-%y") and first[6] == when.strftime("%H:%M:%S")
    back = read_plt(path)
    np.testing.assert_allclose(back.time, pts.time, atol=1e-4)  # 1e-10 day
    np.testing.assert_allclose(back.lat, pts.lat, atol=5.1e-8)
    np.testing.assert_allclose(back.lon, pts.lon, atol=5.1e-8)
    np.testing.assert_allclose(back.altitude_m, pts.altitude_m, atol=0.05 * 0.3048 + 1e-9)
    assert np.isnan(back.altitude_m[3])


def test_new4_round_trip_and_crlf(tmp_path):
    pts = _points()
    path = tmp_path / "a.new4"
    write_new4(path, pts)
    back = read_new4(path)
    np.testing.assert_allclose(back.time, pts.time, atol=5e-4)
    np.testing.assert_allclose(back.lat, pts.lat, atol=5.1e-8)
    np.testing.assert_allclose(back.altitude_m, pts.altitude_m, atol=0.05)
    assert np.isnan(back.altitude_m[3])
    crlf = tmp_path / "crlf.new4"
    crlf.write_bytes(path.read_bytes().replace(b"\n", b"\r\n"))
    again = read_new4(crlf)
    for a, b in zip(again, back):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("bad, field", [("1.0\t56.0\t37.0", "line"), ("1.0\tx\t37.0\t10", "lat"),
                                        ("1.0\t56.0\tnan\t10", "lon")])
def test_new4_bad_line_names_file_line_field(tmp_path, bad, field):
    path = tmp_path / "b.new4"
    path.write_text("0.0\t56.0\t37.0\t100.0\n" + bad + "\n")
    with pytest.raises(ValueError, match=rf"b\.new4 line 2, field .{field}."):
        read_new4(path)


def test_plt_rejects_other_files(tmp_path):
    path = tmp_path / "x.plt"
    path.write_text("not ozi\n")
    with pytest.raises(ValueError, match="line 1.*OziExplorer"):
        read_plt(path)
    path.write_text("OziExplorer Track Point File Version 2.1\nWGS 84\n")
    with pytest.raises(ValueError, match="truncated"):
        read_plt(path)


def test_plt_name_with_comma_does_not_break_fields():
    text = format_plt([0.0], [1.0], [2.0], [3.0], name="a,b")
    assert text.splitlines()[4].split(",")[3] == "a b"


def test_recording_writer_columns_and_refuses_existing(tmp_path):
    rec = tmp_path / "rec"
    write_recording(rec, [
        AdsRecord(10.0, 7, "4b0001", 56.1, 37.2, 9000.0, 8),
        TrackRecord(11.0, "3", "240", 7, None, 56.1, 37.2, None),
        PlotRecord(12.0, "3", "5", None, 12, 56.1, 37.2, 9000.0, 12345.67, 359.99, "4b0001", "7777"),
    ])
    for name, cols in (("plots_ads.txt", ADS_COLUMNS), ("tracks.txt", TRACK_COLUMNS),
                       ("plots.txt", PLOT_COLUMNS)):
        lines = (rec / name).read_text().splitlines()
        assert lines[0].split("\t") == list(cols) and len(lines) == 2
        assert len(lines[1].split("\t")) == len(cols)
    assert (rec / "tracks.txt").read_text().splitlines()[1].split("\t")[7] == ""  # missing altitude
    assert (rec / "plots.txt").read_text().splitlines()[1].split("\t")[3] == ""  # unassociated
    with pytest.raises(FileExistsError):
        write_recording(rec, [])
    with pytest.raises(ValueError, match="radar"):
        write_recording(tmp_path / "r2", [TrackRecord(1.0, "3", "a b", 1, 1, 0.0, 0.0, 0.0)])


def test_synthetic_recording_is_geometrically_consistent(tmp_path):
    from radartracker.geometry.plane import RadarFrame, SystemPlane
    from radartracker.io.recording import synthetic_records, write_synthetic_recording

    size = write_synthetic_recording(tmp_path / "syn", batches=1, aircraft_per_batch=3, flight_s=120.0, seed=5)
    assert size == sum((tmp_path / "syn" / n).stat().st_size for n in ("plots.txt", "tracks.txt", "plots_ads.txt"))
    rows = [line.split("\t") for line in (tmp_path / "syn" / "plots.txt").read_text().splitlines()[1:]]
    times = [float(r[0]) for r in rows]
    assert times == sorted(times) and len(rows) > 50
    # the radar sites of the generator, rebuilt here: plot lat/lon must re-measure to its range/azimuth
    plane = SystemPlane(56.8, 60.6)
    sites = {"1": (60e3, 0.0), "2": (-60e3, 20e3), "3": (0.0, 70e3), "4": (10e3, -80e3)}
    for name, (x, y) in sites.items():
        sel = [r for r in rows if r[2] == name and r[3]]
        la, lo = plane.to_geodetic(x, y)
        frame = RadarFrame(float(la), float(lo), 300.0, plane)
        rho, theta, _ = frame.polar([float(r[5]) for r in sel], [float(r[6]) for r in sel], [float(r[7]) for r in sel])
        np.testing.assert_allclose(rho, [float(r[8]) for r in sel], atol=0.1)
        dth = np.angle(np.exp(1j * (theta - np.radians([float(r[9]) for r in sel]))))
        assert np.all(np.abs(dth * rho) < 0.3)
    batch = next(synthetic_records(seed=5, batches=1, aircraft_per_batch=3, flight_s=120.0))
    assert sum(isinstance(r, PlotRecord) for r in batch) == len(rows)

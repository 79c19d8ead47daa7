"""``.new4`` radar plots with their radar's polar noise, several radars fused for one aircraft.

Oracles: the plot covariance recomputed here from a finite-difference Jacobian of the project's
exact polar-to-plane conversion (RadarFrame.to_plane) at each point; the aircraft's ADS-B file
(``ads.new4``: its exact positions every second) as the truth, against which the fused
reconstruction must beat the one from a single radar's plots.
"""

import csv
import math

import numpy as np
import pytest

from radartracker.api import RadarFrame, SystemPlane, read_new4, read_radars
from radartracker.cli import main
from radartracker.io.convert import ConvertOptions, convert
from radartracker.io.recording import write_synthetic_recording
from radartracker_plugins.reconstruction.tracks import new4_set_tracks

# the synthetic recording's radars (radartracker.io.recording.synthetic_records): name, x, y (m), period;
# plots have σ 50 m in range and 0.05° in azimuth, sites 300 m high around (56.8, 60.6)
SITES = [("1", 60e3, 0.0, 4.0), ("2", -60e3, 20e3, 5.0), ("3", 0.0, 70e3, 6.0), ("4", 10e3, -80e3, 10.0)]


@pytest.fixture(scope="module")
def new4_set(tmp_path_factory):
    base = tmp_path_factory.mktemp("fuse")
    write_synthetic_recording(base / "rec", batches=1, aircraft_per_batch=2, flight_s=600.0, seed=4)
    convert(base / "rec", base / "new", ConvertOptions())
    plane = SystemPlane(56.8, 60.6)
    with open(base / "radars.csv", "w") as f:
        f.write("radar,lat,lon,height_m,sigma_range_m,sigma_azimuth_deg,period_s,max_range_m\n")
        for name, x, y, period in SITES:
            lat, lon = plane.to_geodetic(x, y)
            f.write(f"{name},{float(lat):.9f},{float(lon):.9f},300,50,0.05,{period},250000\n")
    folder = sorted(p.parent for p in (base / "new").glob("*/ads.new4"))[0]
    return folder, base / "radars.csv"


def test_plot_covariance_is_the_polar_one(new4_set):
    folder, radars_csv = new4_set
    radars = read_radars(radars_csv)
    files = sorted(folder.glob("*_r.new4"))
    (pt,), planes, _ = new4_set_tracks(files, radars, 100.0)
    assert pt.key == folder.name and set(pt.radar) == {f.stem[:-2] for f in files}
    plane = planes[pt.key]
    for r in radars:
        sel = np.flatnonzero(pt.radar == r.id)[:5]
        if not len(sel):
            continue
        frame = RadarFrame(r.lat, r.lon, r.height_m, plane)
        lat, lon = plane.to_geodetic(pt.z[sel, 0], pt.z[sel, 1])
        alt = pt.h[sel]
        rho, theta, _ = frame.polar(lat, lon, alt)
        h = np.array([1.0, 1e-5])
        D = np.stack([(frame.to_plane(rho + h[0], theta, alt)[0] - frame.to_plane(rho - h[0], theta, alt)[0]) / (2 * h[0]),
                      (frame.to_plane(rho, theta + h[1], alt)[0] - frame.to_plane(rho, theta - h[1], alt)[0]) / (2 * h[1])],
                     axis=-1)
        W = np.diag([50.0**2, math.radians(0.05) ** 2])
        np.testing.assert_allclose(pt.R[sel], D @ W @ D.transpose(0, 2, 1), rtol=2e-3)


def _error(track_csv, ads):
    rows = list(csv.DictReader(open(track_csv)))
    t = np.array([float(r["time"]) for r in rows])
    plane = SystemPlane(float(np.mean(ads.lat)), float(np.mean(ads.lon)))
    x, y = plane.to_plane(np.array([float(r["lat"]) for r in rows]), np.array([float(r["lon"]) for r in rows]))
    ax, ay = plane.to_plane(ads.lat, ads.lon)
    return float(np.median(np.hypot(x - np.interp(t, ads.time, ax), y - np.interp(t, ads.time, ay))))


def test_fused_radars_beat_one_radar(new4_set, tmp_path):
    folder, radars_csv = new4_set
    files = sorted(folder.glob("*_r.new4"))
    common = ["--engine", "serial", "--quiet", "--no-figures"]
    assert main(["reconstruct", *map(str, files), "--radars", str(radars_csv), "--out", str(tmp_path / "fused"),
                 *common]) == 0
    one = max(files, key=lambda f: len(read_new4(f).time))
    assert main(["reconstruct", str(one), "--radars", str(radars_csv), "--out", str(tmp_path / "one"), *common]) == 0
    ads = read_new4(folder / "ads.new4")
    fused = _error(tmp_path / "fused" / folder.name / "track.csv", ads)
    single = _error(tmp_path / "one" / folder.name / "track.csv", ads)
    assert fused < single
    segs = list(csv.DictReader(open(tmp_path / "fused" / folder.name / "segments.csv")))
    assert len(segs) == 1  # a straight flight

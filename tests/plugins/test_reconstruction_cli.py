"""The ``reconstruct`` command and the engines: scenario folders and .new4 files in, per-aircraft files out.

Oracles: the scenario's truth (reconstruction error far below the plot noise), the files re-read
with the project's own independent readers (.plt, .new4), and the serial engine's result for the
process and Dask engines (the same flights must give the same tracks).
"""

import csv
import json

import numpy as np
import pytest

from radartracker.cli import main
from radartracker.domain import Aircraft
from radartracker.io.scenario import write_scenario
from radartracker.geometry.plane import SystemPlane
from radartracker.io.recording import TrackPoints, read_plt, write_new4
from radartracker.simulation.simulator import KinematicTrajectory, Leg, SimAircraft, SimRadar, Simulator
from radartracker_plugins.reconstruction import MultiHypothesisReconstructor, ReconstructionConfig
from radartracker_plugins.reconstruction.engine import batches, executor
from radartracker_plugins.reconstruction.sim import REFERENCE, radars_around
from radartracker_plugins.reconstruction.tracks import scenario_tracks


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    plane = SystemPlane(*REFERENCE)
    radars = [SimRadar(r) for r in radars_around(plane, [(-50, -30), (40, 50)], [5.0, 8.0])]
    aircraft = [
        SimAircraft(Aircraft("aa0001"), KinematicTrajectory(0, -10e3, 0, 5000, 0.5, 160, [Leg(120), Leg(60, u=3.0), Leg(120)])),
        SimAircraft(Aircraft("aa0002"), KinematicTrajectory(0, 10e3, 5e3, 7000, 3.5, 200, [Leg(150, w=0.5), Leg(150)])),
        SimAircraft(Aircraft("aa0003"), KinematicTrajectory(0, 0, -20e3, 3000, 2.0, 140, [Leg(5.0)])),  # too few plots
    ]
    data = Simulator(REFERENCE, radars, aircraft, 0.0, 300.0, seed=3).run()
    folder = tmp_path_factory.mktemp("rec") / "scenario"
    write_scenario(folder, data)
    return folder, data


def test_reconstruct_scenario_folder(scenario, tmp_path):
    folder, data = scenario
    out = tmp_path / "out"
    assert main(["reconstruct", str(folder), "--out", str(out), "--engine", "serial", "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert [r["key"] for r in summary["reconstructed"]] == ["aa0001", "aa0002"]
    assert sum(summary["skipped_plots"].values()) > 0  # aa0003's few plots, counted
    plane = SystemPlane(*REFERENCE)
    for key, n_seg in (("aa0001", 3), ("aa0002", 2)):
        d = out / key
        assert {p.name for p in d.iterdir()} == {"track.csv", "track.plt", "segments.csv", "hypotheses.csv", "figure.png"}
        rows = list(csv.DictReader(open(d / "track.csv")))
        t = np.array([float(r["time"]) for r in rows])
        xy = np.array([[float(r["x_m"]), float(r["y_m"])] for r in rows])
        sel = data.truth.target == key
        tx, ty = plane.to_plane(data.truth.lat[sel], data.truth.lon[sel])
        err = np.hypot(np.interp(t, data.truth.time[sel], tx) - xy[:, 0], np.interp(t, data.truth.time[sel], ty) - xy[:, 1])
        assert np.sqrt(np.mean(err**2)) < 40.0  # plots have σ 70 m and 0.08° (≈ 70 m at 50 km)
        plt = read_plt(d / "track.plt")
        np.testing.assert_allclose(plt.time, t, atol=1e-3)
        lat, lon = plane.to_geodetic(xy[:, 0], xy[:, 1])
        np.testing.assert_allclose(plt.lat, lat, atol=1e-6)
        segs = list(csv.DictReader(open(d / "segments.csv")))
        assert len(segs) == n_seg
        assert all(float(a["t_end"]) == pytest.approx(float(b["t_start"])) for a, b in zip(segs, segs[1:]))
    # the output folder must be new
    assert main(["reconstruct", str(folder), "--out", str(out), "--engine", "serial", "--quiet"]) == 2


def test_reconstruct_new4_files(scenario, tmp_path):
    _, data = scenario
    sel = data.truth.target == "aa0002"
    rng = np.random.default_rng(0)
    t = data.truth.time[sel][::4]
    lat = data.truth.lat[sel][::4] + rng.normal(0, 3e-4, len(t))
    lon = data.truth.lon[sel][::4] + rng.normal(0, 4e-4, len(t))
    d = tmp_path / "new" / "17"
    d.mkdir(parents=True)
    write_new4(d / "ads.new4", TrackPoints(t, lat, lon, data.truth.altitude_m[sel][::4]))
    out = tmp_path / "out"
    assert main(["reconstruct", str(d / "ads.new4"), "--out", str(out), "--sigma", "40", "--engine", "serial",
                 "--quiet", "--no-figures"]) == 0
    assert (out / "17_ads" / "track.plt").exists()
    assert main(["reconstruct", str(tmp_path / "missing.new4"), "--out", str(tmp_path / "o2")]) == 2
    (tmp_path / "bad.new4").write_text("1\t2\tx\t3\n")
    assert main(["reconstruct", str(tmp_path / "bad.new4"), "--out", str(tmp_path / "o3"), "--quiet"]) == 2


def test_batches_cover_every_flight_once():
    class T:
        def __init__(self, n):
            self.n = n

        def __len__(self):
            return self.n

    tracks = [T(n) for n in (500, 300, 1200, 50, 700, 900)]
    bs = batches(tracks, 1000)
    assert sorted(id(t) for b in bs for t in b) == sorted(id(t) for t in tracks)
    assert all(sum(map(len, b)) <= 1000 or len(b) == 1 for b in bs)


def test_process_and_dask_engines_match_serial(scenario):
    _, data = scenario
    tracks, _, _ = scenario_tracks(data)
    rec = MultiHypothesisReconstructor(ReconstructionConfig(hypotheses=2))
    serial = {r.key: r.control.u for r in rec.reconstruct_many(tracks)}
    for engine in ("process", "dask"):
        with executor(engine, workers=2) as ex:
            got = {r.key: r.control.u for r in rec.reconstruct_many(tracks, ex, batch_plots=50)}
        assert got.keys() == serial.keys()
        for k in got:
            np.testing.assert_allclose(got[k], serial[k], rtol=1e-9, atol=1e-12)


def test_outputs_are_written_atomically(scenario, tmp_path, monkeypatch):
    """Each output reaches its name only by a rename of a complete temporary file; a write that fails
    (here: the rename of hypotheses.csv) leaves neither that file nor a temporary one behind."""
    import os

    import radartracker.io.atomic as atomic

    folder, _ = scenario
    args = ["reconstruct", str(folder), "--flights", "aa0002", "--engine", "serial", "--quiet", "--no-figures",
            "--hypotheses", "2", "--no-shooting"]
    renamed, real_replace = {}, os.replace

    def replace(src, dst):
        assert not os.path.exists(dst)  # nothing was written under the final name before
        renamed[os.path.basename(dst)] = open(src, "rb").read()
        real_replace(src, dst)

    monkeypatch.setattr(atomic.os, "replace", replace)
    out = tmp_path / "out"
    assert main([*args, "--out", str(out)]) == 0
    assert {"track.csv", "track.plt", "segments.csv", "hypotheses.csv", "summary.json"} <= renamed.keys()
    for name, data in renamed.items():  # the renamed file is the complete final file
        final = out / name if name == "summary.json" else out / "aa0002" / name
        assert final.read_bytes() == data

    def failing(src, dst):
        if os.path.basename(dst) == "hypotheses.csv":
            raise OSError(28, "No space left on device")
        real_replace(src, dst)

    monkeypatch.setattr(atomic.os, "replace", failing)
    out2 = tmp_path / "out2"
    assert main([*args, "--out", str(out2)]) == 2  # an OSError is one line and exit 2
    names = {p.name for p in (out2 / "aa0002").iterdir()}
    assert "hypotheses.csv" not in names and not [n for n in names if n.endswith(atomic.TMP_SUFFIX)]
    assert not (out2 / "summary.json").exists()

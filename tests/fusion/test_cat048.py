"""Local tracks over ASTERIX CAT048 (I161, I200, I170): written from the per-radar trackers, read back
to within the items' resolution, and fused by the distributed architecture without local trackers."""

from __future__ import annotations

import json
import math

import attrs
import numpy as np
import pytest

from radartracker.cli import main
from radartracker.fusion import local_tracks_from_asterix
from radartracker.fusion.cat048 import write_local_tracks
from radartracker.pipeline.distributed import collect_local_tracks
from radartracker.fusion.center import LocalTrackEnd, LocalTracks
from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.io.asterix import NM
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.run import run
from radartracker.simulation.scenarios import build_scenario


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    data = build_scenario("demo", seed=3, duration=120.0).run()
    tracks = collect_local_tracks(data)
    last = tracks.reports[-1]  # one track ends: its last report carries TRE
    tracks = LocalTracks(tracks.reports, tracks.ends + [LocalTrackEnd(last.time, last.radar, last.track)])
    path = tmp_path_factory.mktemp("cat048") / "local.ast"
    write_local_tracks(path, data, tracks, default_altitude_m=6000.0)
    return data, tracks, path, local_tracks_from_asterix(path, reference=data.reference)


def test_reports_read_back_within_the_resolution_of_the_items(exported):
    data, tracks, _, (imported_data, imported) = exported
    assert len(imported.reports) == len(tracks.reports) and len(data.adsb) == len(imported_data.adsb)
    plane = SystemPlane(*data.reference)
    frames = {r.id: RadarFrame(r.lat, r.lon, r.height_m, plane) for r in data.radars}
    key = lambda r: (r.radar, round(r.time * 128), r.mode_s)  # noqa: E731
    back: dict = {}
    for r in imported.reports:
        back.setdefault(key(r), []).append(r)
    for r in tracks.reports:  # a track may report twice at one time (confirmed, then updated): the nearer
        b = min(back[key(r)], key=lambda c: float(np.hypot(*(c.state[:2] - r.state[:2]))))
        rho = float(np.hypot(*(r.state[:2] - frames[r.radar].plane.to_plane(data.radar_by_id[r.radar].lat,
                                                                             data.radar_by_id[r.radar].lon))))
        # I040: ρ in 1/256 NM, θ in 360°/2¹⁶ (half an LSB each), I090 in 1/4 FL (moves the ground range)
        tol = 0.5 * NM / 256 + rho * math.pi / 2 ** 16 + 8.0
        assert np.hypot(*(b.state[:2] - r.state[:2])) <= tol
        # I200: ground speed in 2⁻¹⁴ NM/s, heading in 360°/2¹⁶
        assert np.hypot(*(b.state[2:] - r.state[2:])) <= 0.5 * NM * 2 ** -14 + 250 * math.pi / 2 ** 16 + 1e-6
        assert (b.altitude_m is None) == (r.altitude_m is None) and b.mode_s == r.mode_s and b.mode_3a == r.mode_3a
    assert [(e.radar, e.time) for e in imported.ends] == [(last.radar, pytest.approx(last.time, abs=1 / 128))
                                                         for last in [tracks.reports[-1]]]


def test_distributed_run_on_imported_local_tracks(exported):
    data, _, _, (imported_data, imported) = exported
    with_truth = attrs.evolve(imported_data, truth=data.truth, truth_biases=data.truth_biases)
    s = run(with_truth, RunConfig(architecture="distributed"), local_tracks=imported, progress=False).summary()
    for rid, b in s["biases"].items():
        assert abs(b["z_range"]) < 3 and abs(b["z_azimuth"]) < 3, (rid, b)
    assert s["tracking"]["false_tracks"] == 0
    assert s["tracking"]["confirmed_tracks"] == len(set(data.truth.target))
    assert s["counts"]["local_track_reports_used"] > 0 and s["counts"]["adsb_used"] > 0


def test_replay_of_a_track_recording_with_the_distributed_architecture(exported, tmp_path, capsys):
    _, tracks, path, _ = exported
    out = tmp_path / "out"
    assert main(["--quiet", "replay", str(path), "--architecture", "distributed", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["counts"]["local_track_reports_used"] > 0 and s["tracks"] == len({r.mode_s for r in tracks.reports})
    assert "track reports" not in capsys.readouterr().err
    # the central architecture reads the track positions as plots, and says so
    assert main(["--quiet", "replay", str(path), "--out", str(tmp_path / "central")]) == 0
    assert "CAT048 track reports (I161)" in capsys.readouterr().err

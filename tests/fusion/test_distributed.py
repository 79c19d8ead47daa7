"""The distributed architecture: biases and tracks on a simulated scenario, the central outputs and
schema, config.json reproducing the run byte for byte, and the fusion centre's association rules."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from radartracker.cli import main
from radartracker.estimation.base import EstimatorConfig
from radartracker.estimation.motion import MotionModel
from radartracker.fusion.center import FusionCentre, FusionConfig, LocalReport
from radartracker.geometry.plane import SystemPlane
from radartracker.io.scenario import write_scenario
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.run import run
from radartracker.registry import make_estimator
from radartracker.simulation.scenarios import build_scenario


@pytest.fixture(scope="module")
def demo():
    return build_scenario("demo", seed=3, duration=150.0).run()


@pytest.fixture(scope="module")
def distributed(demo):
    return run(demo, RunConfig(architecture="distributed"), progress=False)


def test_biases_within_three_sigma_and_no_false_tracks(distributed, demo):
    s = distributed.summary()
    assert set(s["biases"]) == {r.id for r in demo.radars}
    for rid, b in s["biases"].items():
        assert abs(b["z_range"]) < 3 and abs(b["z_azimuth"]) < 3, (rid, b)
    assert s["tracking"]["false_tracks"] == 0
    assert s["tracking"]["confirmed_tracks"] == len(set(demo.truth.target))  # one system track per aircraft
    assert s["tracking"]["breaks"] == 0 and s["tracking"]["swaps"] == 0


def _header(path):
    with path.open() as f:
        return next(csv.reader(f))


def _keys(d, prefix=""):
    """The key paths of a JSON summary, per-radar and per-aircraft names replaced by '*'."""
    out = set()
    for k, v in d.items():
        name = "*" if prefix.endswith(("biases", "per_target", "radars", "counts", "skipped_input_rows")) else k
        out.add(prefix + "/" + name)
        if isinstance(v, dict):
            out |= _keys(v, prefix + "/" + name)
    return out


def test_same_outputs_as_central_and_config_reproduces_the_run(tmp_path, demo):
    scen = tmp_path / "scen"
    write_scenario(scen, build_scenario("demo", seed=4, duration=90.0).run())
    out = {a: tmp_path / a for a in ("central", "distributed", "again")}
    assert main(["--quiet", "replay", str(scen), "--out", str(out["central"])]) == 0
    assert main(["--quiet", "replay", str(scen), "--out", str(out["distributed"]), "--architecture", "distributed",
                 "--motion-model", "cv"]) == 0
    files = {a: sorted(p.name for p in out[a].iterdir()) for a in ("central", "distributed")}
    assert files["central"] == files["distributed"]
    for name in ("tracks.csv", "events.csv", "biases.csv"):
        assert _header(out["central"] / name) == _header(out["distributed"] / name), name
    summaries = [json.loads((out[a] / "summary.json").read_text()) for a in ("central", "distributed")]
    assert _keys(summaries[0]) - {"/counts/*"} <= _keys(summaries[1]) | {"/counts/*"}
    assert _keys(summaries[1]) <= _keys(summaries[0]) | {"/counts/*"}
    cfg = json.loads((out["distributed"] / "config.json").read_text())["settings"]
    assert cfg["architecture"] == "distributed" and cfg["fusion"]["period_s"] == FusionConfig().period_s
    assert main(["--quiet", "replay", str(scen), "--config", str(out["distributed"] / "config.json"),
                 "--out", str(out["again"])]) == 0
    for name in ("tracks.csv", "biases.csv", "events.csv", "config.json"):
        assert (out["again"] / name).read_bytes() == (out["distributed"] / name).read_bytes(), name


# --- association, on the fusion centre alone ---------------------------------------------------------

@pytest.fixture()
def centre(demo):
    plane = SystemPlane(*demo.reference)
    est = make_estimator("coupled", EstimatorConfig(motion=MotionModel(5.0)), [r.id for r in demo.radars])
    events = []
    c = FusionCentre(demo.radars, plane, est, 5.0, FusionConfig(), lambda t, tr, kind, ident: events.append(kind),
                     9000.0)
    return c


def _report(radar, track, x, y, *, t=10.0, mode_s=None, sd=50.0):
    return LocalReport(t, radar, track, np.array([x, y, 230.0, 0.0]), np.diag([sd * sd, sd * sd, 25.0, 25.0]),
                       9000.0, mode_s)


def test_two_radars_tracks_of_one_aircraft_end_in_one_system_track(centre):
    centre.report(_report("R1", 7, 1000.0, 2000.0))
    centre.report(_report("R2", 3, 1060.0, 1950.0))
    centre.epoch(10.0)
    assert len(centre.tracks) == 1
    assert next(iter(centre.tracks.values())).members == {("R1", 7), ("R2", 3)}
    # a third radar, many epochs later, joins the same track; a far one starts its own
    centre.report(_report("R1", 7, 1000.0 + 230 * 4, 2000.0, t=14.0))
    centre.report(_report("R3", 5, 1000.0 + 230 * 6, 2030.0, t=16.0))
    centre.report(_report("R3", 6, 60_000.0, -20_000.0, t=16.0))
    centre.epoch(16.0)
    members = sorted(sorted(tr.members) for tr in centre.tracks.values())
    assert members == [[("R1", 7), ("R2", 3), ("R3", 5)], [("R3", 6)]]


@pytest.mark.parametrize("mode_s", [None, "4b0000"])
def test_a_radar_never_gives_one_system_track_two_local_tracks(centre, mode_s):
    # one radar, two local tracks 100 m apart (a split track): within the gate, same Mode S, yet never joined
    centre.report(_report("R1", 1, 1000.0, 2000.0, mode_s=mode_s))
    centre.report(_report("R1", 2, 1100.0, 2000.0, mode_s=mode_s))
    centre.report(_report("R2", 9, 1050.0, 2000.0, mode_s=mode_s))
    centre.epoch(10.0)
    assert len(centre.tracks) == 2
    for tr in centre.tracks.values():
        radars = [r for r, _ in tr.members]
        assert len(radars) == len(set(radars))
    assert sum(len(tr.members) for tr in centre.tracks.values()) == 3

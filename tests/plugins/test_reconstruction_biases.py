"""Radar biases in reconstruction: a replay's biases.csv read and applied, and the joint estimate.

Oracles: the exact polar conversion of bias-corrected plots (ρ − Δr, θ − Δθ) by the project's
RadarFrame against the linear correction z − Cς; the scenario's truth_biases.csv (a biases.csv
holding the true values with zero sd must give the --truth-biases result); for the joint mode,
the true biases and the reconstruction error without bias removal.
"""

import json
import math

import numpy as np
import pytest

from radartracker.api import FormatError, RadarFrame, SystemPlane
from radartracker.cli import main
from radartracker.io.scenario import write_scenario
from radartracker.simulation.scenarios import build_scenario
from radartracker_plugins.reconstruction.biases import BiasEstimate, debias, read_biases
from radartracker_plugins.reconstruction.tracks import scenario_tracks

HEADER = "time,radar,range_bias_m,azimuth_bias_deg,sd_range_m,sd_azimuth_deg\n"


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    data = build_scenario("manoeuvres", seed=2, duration=400.0).run()
    folder = tmp_path_factory.mktemp("bias") / "scenario"
    write_scenario(folder, data)
    return folder, data


def test_read_biases_takes_the_last_row_per_radar_and_names_bad_fields(tmp_path):
    p = tmp_path / "biases.csv"
    p.write_text(HEADER + "1.0,A,10.0,0.05,20.0,0.02\n2.0,B,-5.0,-0.1,8.0,0.01\n3.0,A,80.5,0.1,3.0,0.005\n")
    b = read_biases(p, {"A", "B"})
    np.testing.assert_allclose(b["A"].value, [80.5, math.radians(0.1)])
    np.testing.assert_allclose(np.diag(b["A"].cov), [9.0, math.radians(0.005) ** 2])
    p.write_text(HEADER + "1.0,A,10.0,0.05,20.0,0.02\n2.0,B,-5.0,abc,8.0,0.01\n")
    with pytest.raises(FormatError) as e:
        read_biases(p, {"A", "B"})
    assert e.value.line == 3 and e.value.field == "azimuth_bias_deg"
    p.write_text(HEADER + "1.0,C,10.0,0.05,20.0,0.02\n")
    with pytest.raises(FormatError, match="unknown radar 'C'"):
        read_biases(p, {"A", "B"})
    p.write_text(HEADER + "1.0,A,10.0,0.05,-2.0,0.02\n")
    with pytest.raises(FormatError) as e:
        read_biases(p, {"A"})
    assert e.value.field == "sd_range_m"


def test_linear_correction_matches_the_exact_polar_one(scenario):
    _, data = scenario
    tracks, plane, _ = scenario_tracks(data)
    pt = tracks[0]
    cov = np.diag([10.0**2, math.radians(0.02) ** 2])
    est = {r: BiasEstimate(np.array(b), cov) for r, b in data.truth_biases.items()}
    fixed = debias(pt, est)
    radars = data.radar_by_id
    p = data.plots
    for radar in set(pt.radar):
        r = radars[radar]
        frame = RadarFrame(r.lat, r.lon, r.height_m, plane)
        sel = (p.target == pt.key) & (p.radar == radar)
        db = data.truth_biases[radar]
        exact, _ = frame.to_plane(p.range_m[sel] - db[0], p.azimuth_rad[sel] - db[1], p.altitude_m[sel])
        exact = exact[np.argsort(p.time[sel], kind="stable")]
        got = fixed.z[pt.radar == radar]
        assert np.max(np.hypot(*(got - exact).T)) < 2.0  # metres; the bias moves plots by ~100 m
        C = pt.C[pt.radar == radar]
        np.testing.assert_allclose(fixed.R[pt.radar == radar], pt.R[pt.radar == radar] + C @ cov @ C.transpose(0, 2, 1))


FAST = ["--engine", "serial", "--quiet", "--no-figures", "--hypotheses", "4", "--no-shooting", "--max-u", "16",
        "--max-w", "4"]


def test_biases_csv_with_the_true_values_equals_truth_biases(scenario, tmp_path):
    folder, data = scenario
    key = sorted(set(data.truth.target))[0]
    bcsv = tmp_path / "biases.csv"
    bcsv.write_text(HEADER + "".join(f"100.0,{r},{b[0]:.6f},{math.degrees(b[1]):.9f},0,0\n"
                                     for r, b in data.truth_biases.items()))
    runs = {}
    for name, extra in (("file", ["--biases", str(bcsv)]), ("truth", ["--truth-biases"]), ("none", ["--keep-biases"])):
        out = tmp_path / name
        assert main(["reconstruct", str(folder), "--out", str(out), "--flights", key, *FAST, *extra]) in (0, 1)
        runs[name] = json.loads((out / "summary.json").read_text())["reconstructed"][0]
    assert runs["file"]["weight"] == pytest.approx(runs["truth"]["weight"], rel=1e-6)
    assert runs["file"]["truth_error"]["median_m"] == pytest.approx(runs["truth"]["truth_error"]["median_m"], abs=0.2)
    assert runs["file"]["truth_error"]["median_m"] < runs["none"]["truth_error"]["median_m"]


@pytest.mark.slow
def test_joint_estimate_recovers_the_biases(scenario, tmp_path):
    folder, data = scenario
    out = tmp_path / "joint"
    assert main(["reconstruct", str(folder), "--out", str(out), "--estimate-biases", *FAST]) == 0
    s = json.loads((out / "summary.json").read_text())
    for radar, (dr, da) in data.truth_biases.items():
        got = s["joint_biases"]["biases"][radar]
        assert abs(got["range_bias_m"] - dr) < 25.0
        assert abs(got["azimuth_bias_deg"] - math.degrees(da)) < 0.03


def test_components_on_the_command_line(tmp_path, capsys):
    """``--components range_gain,time_offset``: every estimated radar's summary carries the four components with
    their sd; refused (exit 2, one line) with an unknown name, without the joint estimate, or for .new4 input."""
    from radartracker_plugins.reconstruction.sim import biased_scenario

    data, _ = biased_scenario(3, 200.0, {"R0": {"range_gain": 3e-4, "time_offset_s": 0.1}})
    folder = tmp_path / "scenario"
    write_scenario(folder, data)
    out = tmp_path / "out"
    assert main(["reconstruct", str(folder), "--out", str(out), "--components", "range_gain,time_offset", *FAST]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["biases_removed"] == "estimated jointly"
    for radar in ("R0", "R1"):
        got = s["joint_biases"]["biases"][radar]
        assert set(got) == {"range_bias_m", "azimuth_bias_deg", "range_gain_ppm", "time_offset_ms", "sd_range_m",
                            "sd_azimuth_deg", "sd_range_gain_ppm", "sd_time_offset_ms"}
        assert all(math.isfinite(v) for v in got.values())
    r0 = s["joint_biases"]["biases"]["R0"]
    assert abs(r0["range_gain_ppm"] - 300.0) < 3 * r0["sd_range_gain_ppm"]
    seen = s["joint_biases"]["observability"]
    for radar, got in s["joint_biases"]["biases"].items():  # the status from each σ against its prior's
        prior = {"range_gain_ppm": 1e3, "time_offset_ms": 500.0}
        for key, name in (("range_gain_ppm", "range_gain"), ("time_offset_ms", "time_offset")):
            ratio = (got[f"sd_{key}"] / prior[key]) ** 2
            assert seen[radar][name] == ("unobservable" if ratio >= 0.9 else "weak" if ratio >= 0.1 else "observable")
        assert seen[radar]["azimuth_offset"] == "observable"
    new4 = tmp_path / "a.new4"
    new4.write_text("")
    capsys.readouterr()
    for inputs, extra, why in (([folder], ["--components", "range_drift"], "unknown 'range_drift'"),
                               ([folder], ["--components", "time_offset", "--keep-biases"], "only with the joint"),
                               ([new4], ["--components", "range_gain"], "scenario input only")):
        assert main(["reconstruct", *map(str, inputs), "--out", str(tmp_path / "x"), *extra, *FAST]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and why in err[0] and "--components" in err[0]

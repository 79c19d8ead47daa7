"""The simulator's range gain and time-stamp offset (issue 30): what they do to the plots, their truth files,
and that scenarios without them are unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from radartracker.cli import main
from radartracker.errors import ConfigurationError
from radartracker.io.scenario import read_scenario, write_scenario
from radartracker.simulation.scenarios import build_scenario, with_sensor_errors
from radartracker.simulation.traffic import traffic_scenario


def _radar_rows(data, rid: str) -> tuple[np.ndarray, np.ndarray]:
    idx = np.flatnonzero(data.plots.radar == rid)
    idx = idx[np.argsort(data.plots.time[idx], kind="stable")]
    return data.plots.time[idx], data.plots.range_m[idx]


def test_no_sensor_errors_leaves_the_scenario_unchanged():
    plain = build_scenario("demo", duration=200.0).run()
    same = with_sensor_errors(build_scenario("demo", duration=200.0), {}).run()
    for name in ("time", "radar", "range_m", "azimuth_rad"):
        np.testing.assert_array_equal(getattr(plain.plots, name), getattr(same.plots, name))
    assert plain.truth_sensor is None and same.truth_sensor is None


def test_gain_and_time_offset_change_exactly_the_radars_plots_they_are_given_to():
    g, tau = 3e-4, 0.1
    plain = build_scenario("demo", duration=200.0).run()
    errs = with_sensor_errors(build_scenario("demo", duration=200.0), {"R1": {"range_gain": g, "time_offset_s": tau}}).run()
    t0, r0 = _radar_rows(plain, "R1")
    t1, r1 = _radar_rows(errs, "R1")
    np.testing.assert_allclose(t1 - t0, tau, atol=1e-9)
    bias = plain.truth_biases["R1"][0]
    np.testing.assert_allclose(r1 - r0, g * (r0 - bias), rtol=1e-9, atol=1e-6)  # ρ_meas = ρ (1 + g) + Δr
    for rid in ("R2", "R3"):
        np.testing.assert_array_equal(_radar_rows(plain, rid)[1], _radar_rows(errs, rid)[1])
    assert errs.truth_sensor["R1"] == {"range_gain": g, "time_offset": tau}
    assert errs.truth_sensor["R2"] == {"range_gain": 0.0, "time_offset": 0.0}


def test_drifting_errors_reach_the_truth_file_and_read_back(tmp_path):
    sim = with_sensor_errors(build_scenario("demo", duration=300.0),
                             {"R2": {"time_offset_s": 0.05, "drift_time": 1e-5, "drift_gain": 1e-12}})
    data = sim.run()
    end = data.truth_sensor["R2"]
    assert end["time_offset"] != 0.05 and end["range_gain"] != 0.0  # they walked
    t0, _ = _radar_rows(build_scenario("demo", duration=300.0).run(), "R2")
    t1, _ = _radar_rows(data, "R2")
    shift = t1 - t0
    assert np.ptp(shift) > 0.0 and abs(shift[0] - 0.05) < 0.01
    write_scenario(tmp_path / "s", data)
    header = (tmp_path / "s" / "truth_biases.csv").read_text().splitlines()[0]
    assert header == "radar,range_bias_m,azimuth_bias_deg,range_gain,time_offset_s"
    back = read_scenario(tmp_path / "s")
    for rid, values in data.truth_sensor.items():
        for k, v in values.items():
            assert back.truth_sensor[rid][k] == pytest.approx(v, rel=1e-12, abs=1e-15)


def test_a_scenario_without_them_writes_the_old_truth_file(tmp_path):
    write_scenario(tmp_path / "s", build_scenario("demo", duration=60.0).run())
    assert (tmp_path / "s" / "truth_biases.csv").read_text().splitlines()[0] == "radar,range_bias_m,azimuth_bias_deg"
    assert read_scenario(tmp_path / "s").truth_sensor is None


def test_traffic_scenarios_take_them_too():
    sim = traffic_scenario(seed=2, duration=60.0, aircraft=5, radars=2)
    data = with_sensor_errors(sim, {"R01": {"range_gain": 1e-4, "time_offset_s": -0.02}}).run()
    assert data.truth_sensor["R01"] == {"range_gain": 1e-4, "time_offset": -0.02}
    assert data.truth_sensor["R00"] == {"range_gain": 0.0, "time_offset": 0.0}


@pytest.mark.parametrize("errors, message", [({"R9": {"range_gain": 1.0}}, "unknown radar 'R9'"),
                                             ({"R1": {"gain": 1.0}}, "unknown 'gain'"),
                                             ({"R1": {"drift_time": -1.0}}, "'drift_time' must be >= 0")])
def test_bad_sensor_errors_are_configuration_errors(errors, message):
    with pytest.raises(ConfigurationError, match=message):
        with_sensor_errors(build_scenario("demo", duration=60.0), errors)


@pytest.mark.parametrize("spec, message", [("R1", "expected RADAR:KEY=VALUE"), ("R1:range_gain", "expected"),
                                           ("R1:range_gain=x", "'x' is not a number"),
                                           ("R1:time_offset_s=nan", "is not finite")])
def test_simulate_refuses_a_malformed_sensor_error(tmp_path, capsys, spec, message):
    assert main(["simulate", str(tmp_path / "s"), "--scenario", "demo", "--sensor-error", spec]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and not (tmp_path / "s").exists()


def test_the_parquet_truth_file_carries_the_new_columns_with_their_units(tmp_path):
    import pyarrow.parquet as pq

    data = with_sensor_errors(build_scenario("demo", duration=60.0), {"R3": {"range_gain": 1e-4}}).run()
    write_scenario(tmp_path / "pq", data, format="parquet")
    schema = pq.read_schema(tmp_path / "pq" / "truth_biases.parquet")
    assert {f.name: f.metadata[b"unit"].decode() for f in schema} == {
        "radar": "", "range_bias_m": "m", "azimuth_bias_deg": "deg", "range_gain": "1", "time_offset_s": "s"}
    assert read_scenario(tmp_path / "pq").truth_sensor["R3"] == {"range_gain": 1e-4, "time_offset": 0.0}

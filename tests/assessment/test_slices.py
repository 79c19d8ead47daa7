"""A recording assessed in time slices, in this process and on a Dask LocalCluster of 2 workers, gives the
one-pass figures: counts exactly, the rest within radartracker.assessment.slices.TOLERANCE (round-off); and
no plot, sweep or expected crossing is lost or counted twice at a slice boundary."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from radartracker.assessment.assess import AssessmentConfig, assess
from radartracker.assessment.matching import MatchConfig
from radartracker.assessment.profile import load_profile
from radartracker.assessment.reference import build_reference
from radartracker.assessment.slices import TOLERANCE, SliceConfig, tally_radars
from radartracker.cli import main
from radartracker.simulation.faults import Faults, plant
from radartracker.simulation.scenarios import build_scenario

FAULTS = Faults(wrong_mode_3a=0.03, wrong_mode_c=0.02, wrong_mode_s=0.03, split=0.02, out_of_order=0.01,
                reflection=0.02)


def _flat(d, path: str = "") -> dict:
    if isinstance(d, dict):
        return {k: v for key, sub in d.items() for k, v in _flat(sub, f"{path}/{key}").items()}
    return {path: d}


def assert_same_figures(one: dict, other: dict) -> None:
    """Every field of two ``assessment.json`` equal: floats within TOLERANCE (relative), the rest exactly."""
    a, b = _flat(one), _flat(other)
    assert a.keys() == b.keys()
    for k, x in a.items():
        if isinstance(x, float) and isinstance(b[k], float):
            assert math.isclose(x, b[k], rel_tol=TOLERANCE, abs_tol=1e-300), (k, x, b[k])
        else:
            assert x == b[k], (k, x, b[k])


@pytest.fixture(scope="module")
def planted():
    return plant(build_scenario("tracking", seed=4, duration=300.0).run(), FAULTS, seed=4)


def test_slices_in_process_give_the_one_pass_figures(planted):
    one = assess(planted, load_profile(), progress=False).summary()
    for slice_s in (37.0, 100.0):
        sliced = assess(planted, load_profile(), AssessmentConfig(slices=SliceConfig(slice_s)), progress=False).summary()
        assert_same_figures(one, sliced)


def test_slice_boundaries_lose_or_double_nothing(planted):
    """Per radar, the slices' plots add up to the radar's plots, and their sweeps, crossings and unmatched
    plots to one pass's."""
    reference = build_reference(planted)
    biases = {r.id: (0.0, 0.0) for r in planted.radars}
    whole = tally_radars(planted, reference, biases, MatchConfig(), 300.0, SliceConfig(), progress=False)
    cut = tally_radars(planted, reference, biases, MatchConfig(), 300.0, SliceConfig(23.0), progress=False)
    for r in planted.radars:
        n = int((planted.plots.radar == r.id).sum())
        assert whole[r.id].plots == cut[r.id].plots == n
        assert (whole[r.id].sweeps, whole[r.id].split_sweeps, whole[r.id].unmatched) == \
            (cut[r.id].sweeps, cut[r.id].split_sweeps, cut[r.id].unmatched)
        assert sum(cut[r.id].scans.values()) == n and cut[r.id].scans == whole[r.id].scans
        a, b = whole[r.id].expected_table(), cut[r.id].expected_table()
        assert len(a["time"]) == len(b["time"]) and np.array_equal(np.sort(a["time"]), np.sort(b["time"]))
        assert a["detected"].sum() == b["detected"].sum() and a["above_cone"].sum() == b["above_cone"].sum()
        assert np.array_equal(np.sort(a["elevation_deg"]), np.sort(b["elevation_deg"]))
        assert np.array_equal(whole[r.id].sample.key, cut[r.id].sample.key)  # the error scatter's plots
        assert np.array_equal(whole[r.id].sample.values, cut[r.id].sample.values)


def test_dask_command_gives_the_one_process_figures(tmp_path: Path):
    """``assess --slice-s 60 --workers 2`` (a LocalCluster) against ``assess``: assessment.json field by field. The
    truth is taken away, so the reference's flights are reconstructed too, on the same cluster as the slices."""
    assert main(["--quiet", "simulate", str(tmp_path / "s"), "--scenario", "tracking", "--duration", "240"]) == 0
    (tmp_path / "s" / "truth.csv").unlink()
    assert main(["--quiet", "assess", str(tmp_path / "s"), "--out", str(tmp_path / "one")]) == 0
    assert main(["--quiet", "assess", str(tmp_path / "s"), "--out", str(tmp_path / "dask"), "--slice-s", "60",
                 "--workers", "2"]) == 0
    one, dask = (json.loads((tmp_path / d / "assessment.json").read_text()) for d in ("one", "dask"))
    assert one["reference"] == dask["reference"] and one["reference"].endswith("reconstruction")
    assert_same_figures(one, dask)


def test_bad_slicing_options_are_refused(tmp_path: Path, capsys):
    assert main(["--quiet", "assess", str(tmp_path), "--out", str(tmp_path / "o"), "--slice-s", "0"]) == 2
    assert "--slice-s" in capsys.readouterr().err

"""The defaults of ``reconstruct``: radar biases estimated jointly unless given or kept, and the control bounds.

Oracles: the scenario's truth_biases.csv and truth.csv (the default's truth error must be close to that of
``--truth-biases``, which removes the true biases, and far below that of ``--keep-biases``, which leaves
them in); for the bounds, the known controls of a simulated flight turning at 6 m/s² (beyond the seed's
bound of 4, within the default's).
"""

import json
import math

import attrs
import numpy as np
import pytest

from radartracker.api import KinematicTrajectory, Leg, SystemPlane
from radartracker.cli import main
from radartracker.io.scenario import write_scenario
from radartracker_plugins.reconstruction import ReconstructionConfig
from radartracker_plugins.reconstruction.hypotheses import reconstruct
from radartracker_plugins.reconstruction.integrate import sample
from radartracker_plugins.reconstruction.joint import shared_radars
from radartracker_plugins.reconstruction.quality import assess, pinned_segments
from radartracker_plugins.reconstruction.sim import REFERENCE, biased_scenario, radars_around, simulate_flight
from radartracker_plugins.reconstruction.tracks import scenario_tracks

FAST = ["--engine", "serial", "--quiet", "--no-figures", "--hypotheses", "2", "--no-shooting"]


@pytest.fixture(scope="module")
def biased(tmp_path_factory):
    """Two biased radars (60 m, 0.08°; −40 m, −0.1°: shifts of 60–100 m), four flights of 200 s."""
    data, _ = biased_scenario(seed=3, duration=200.0)
    folder = tmp_path_factory.mktemp("defaults") / "scenario"
    write_scenario(folder, data)
    return folder


def _errors(folder, out, *extra) -> tuple[list[float], dict]:
    assert main(["reconstruct", str(folder), "--out", str(out), *FAST, *extra]) == 0
    s = json.loads((out / "summary.json").read_text())
    return [r["truth_error"]["median_m"] for r in s["reconstructed"]], s


def test_default_removes_the_biases_and_keep_biases_leaves_them(biased, tmp_path):
    default, s = _errors(biased, tmp_path / "default")
    truth, _ = _errors(biased, tmp_path / "truth", "--truth-biases")
    kept, k = _errors(biased, tmp_path / "keep", "--keep-biases")
    assert s["biases_removed"] == "estimated jointly" and set(s["joint_biases"]["biases"]) == {"R0", "R1"}
    assert "biases_removed" not in k and "joint_biases" not in k
    assert np.mean(default) < np.mean(truth) + 10.0  # metres: as good as knowing the biases, within 10 m
    assert np.mean(kept) > np.mean(truth) + 30.0  # the biases left in shift every flight
    assert main(["reconstruct", str(biased), "--out", str(tmp_path / "x"), "--keep-biases", "--truth-biases"]) == 2


def test_single_radar_scenario_keeps_its_plots_and_says_why(tmp_path, capsys):
    """One radar: its azimuth bias (a rotation of every track about it) is unobservable, so the default
    does not estimate it (the prior-held estimate wandered and doubled the error, docs/reconstruction.md)."""
    data, _ = biased_scenario(seed=4, duration=200.0)
    data = attrs.evolve(data, plots=data.plots.take(np.flatnonzero(data.plots.radar == "R0")),
                        radars=[r for r in data.radars if r.id == "R0"], truth_biases={"R0": data.truth_biases["R0"]})
    folder = tmp_path / "one"
    write_scenario(folder, data)
    default, s = _errors(folder, tmp_path / "default")
    assert "no aircraft was seen by two radars" in capsys.readouterr().err
    kept, _ = _errors(folder, tmp_path / "keep", "--keep-biases")
    assert s["biases_removed"].startswith("none") and default == kept


def test_default_bounds_fit_a_6_mps2_turn_without_pinning():
    """A 60-s turn at u = 6 m/s² (3.4°/s at 100 m/s, a tight approach turn) between straight legs."""
    plane = SystemPlane(*REFERENCE)
    traj = KinematicTrajectory(0.0, -8e3, 0.0, 3000.0, math.radians(80.0), 100.0,
                               [Leg(120.0), Leg(60.0, u=6.0), Leg(120.0)])
    pt, true = simulate_flight(traj, radars_around(plane, [(-40.0, -20.0), (30.0, 35.0)], [4.0, 5.0]), seed=5)
    cfg = ReconstructionConfig(shooting=False, hypotheses=3)
    rec = reconstruct(pt, cfg)
    assert not any(mask.any() for mask in pinned_segments(rec, cfg).values())
    assert assess(rec, cfg)["plausible"]
    assert np.median(np.hypot(*(sample(rec.control, pt.t)[:, :2] - true).T)) < 40.0  # plots: σ ≈ 70 m


def test_only_radars_seen_with_another_are_estimated():
    """A radar whose aircraft no other radar saw is left out of the joint estimate (its bias unobservable)."""
    data, _ = biased_scenario(seed=5, duration=200.0)
    tracks, _, _ = scenario_tracks(data)
    assert shared_radars(tracks) == {"R0", "R1"}
    alone = attrs.evolve(tracks[0], radar=np.full(len(tracks[0]), "R9"))  # one aircraft seen by R9 only
    assert shared_radars([*tracks[1:], alone]) == {"R0", "R1"}
    assert shared_radars([alone]) == set()

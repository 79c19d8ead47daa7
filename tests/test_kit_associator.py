"""A third party's associator — nearest neighbour, in its own package with an entry point, importing only
radartracker.api — passes check_associator and runs from ``radartracker replay --associator NAME`` with
nothing in the core touched."""

import json

import numpy as np
import pytest

from radartracker.cli import main
from tests.plugin_install import install, uninstall
from radartracker.io.scenario import write_scenario
from radartracker.registry import available_associators, load_associator
from radartracker.simulation.scenarios import build_scenario
from radartracker.testing import ASSOCIATOR_CHECKS, CheckFailed, check_associator

PLUGIN = '''
"""Nearest neighbour: each plot to the closest free track within the search radius whose d² passes the gate."""
import numpy as np
from radartracker.api import NEW_TRACK, REFUSED, Association, Associator, gate_costs

CALLS = []


class Nearest(Associator):
    name = "nearest"

    def associate(self, plots, tracks):
        CALLS.append(len(plots.plots))
        out = np.full(len(plots.plots), NEW_TRACK, np.int64)
        reasons, taken = {}, set()
        for k in range(len(plots.plots)):
            if not plots.valid[k]:
                out[k], reasons[k] = REFUSED, "plots_impossible_geometry"
                continue
            if not len(tracks):
                continue
            d = np.hypot(*(tracks.position - plots.z[k]).T)
            for i in np.argsort(d).tolist():
                if d[i] > self.settings.search_radius_m:
                    break
                if i in taken:
                    continue
                pos, vel, cov = tracks.exact(np.array([i]))
                d2, _ = gate_costs(plots.z[k:k + 1], plots.C[k:k + 1], plots.R[k:k + 1], plots.bias, plots.bias_cov,
                                   pos + vel * (plots.plots[k].time - tracks.time), cov)
                if d2[0] <= self.settings.gate:
                    out[k] = i
                    taken.add(i)
                break
        return Association(out, reasons)


class Greedy(Nearest):
    """A broken associator: every plot to track 0."""
    name = "greedy"

    def associate(self, plots, tracks):
        return Association(np.zeros(len(plots.plots), np.int64), {})
'''


@pytest.fixture()
def nearest(tmp_path, monkeypatch):
    """The plugin installed the way pip would: a package and a dist-info with entry_points.txt on sys.path."""
    yield install(tmp_path, monkeypatch, "rt_nearest", PLUGIN,
                  "[radartracker.associators]\nnearest = rt_nearest:Nearest\ngreedy = rt_nearest:Greedy\n")
    uninstall("rt_nearest")


def test_thirdparty_associator_passes_its_checks(nearest):
    assert {"gnn", "labels", "nearest"} <= set(available_associators())
    assert check_associator(load_associator("nearest")) == ASSOCIATOR_CHECKS


def test_a_broken_associator_fails_its_checks(nearest):
    with pytest.raises(CheckFailed, match="greedy.*contract"):
        check_associator(load_associator("greedy"))


@pytest.mark.parametrize("name", ["gnn", "labels"])
def test_builtin_associators_pass_their_checks(name):
    assert check_associator(load_associator(name)) == ASSOCIATOR_CHECKS


def test_replay_with_the_thirdparty_associator(nearest, tmp_path, capsys):
    import rt_nearest

    write_scenario(tmp_path / "scen", build_scenario("demo", seed=2, duration=150.0).run())
    assert main(["replay", str(tmp_path / "scen"), "--out", str(tmp_path / "out"), "--manager", "--associator",
                 "nearest", "--quiet"]) == 0
    assert len(rt_nearest.CALLS) > 100
    config = json.loads((tmp_path / "out" / "config.json").read_text())["settings"]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert config["associator"] == "nearest" and summary["tracking"]["confirmed_tracks"] >= 4
    assert main(["replay", str(tmp_path / "scen"), "--out", str(tmp_path / "o2"), "--manager", "--associator",
                 "missing", "--quiet"]) == 2
    assert "unknown associator 'missing'" in capsys.readouterr().err
    assert main(["replay", str(tmp_path / "scen"), "--out", str(tmp_path / "o3"), "--association", "labels",
                 "--associator", "nearest", "--quiet"]) == 2
    assert np.isfinite(summary["truth"]["position_rmse_m"])

"""Plugins are found through entry points: a throw-away package is listed and usable by name."""

import sys
import textwrap

import numpy as np
import pytest

from radartracker.cli import main
from radartracker.estimation.base import Estimator
from radartracker.registry import available_estimators, load_estimator
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.run import run

PLUGIN = '''
import numpy as np
from radartracker.domain import BiasState
from radartracker.estimation.base import AircraftEstimate, Estimator, Innovation


class Frozen(Estimator):
    """Keeps each aircraft at its first measurement: enough to show the plugin is really used."""

    name = "frozen"

    def __init__(self, config=None):
        super().__init__(config)
        self._a, self._r, self.calls = {}, [], 0

    def add_radar(self, radar):
        self._r.append(radar)

    def add_aircraft(self, key, time, state, cov):
        self._a[key] = AircraftEstimate(time, np.array(state), np.array(cov))

    def remove_aircraft(self, key):
        del self._a[key]

    def update(self, m):
        self.calls += 1
        return Innovation(np.zeros(2), np.eye(2), 0.0)

    def aircraft(self, key):
        return self._a[key]

    def bias(self, radar):
        return BiasState(radar, 0.0, np.array([42.0, 0.0]), np.eye(2))

    @property
    def aircraft_keys(self):
        return list(self._a)

    @property
    def radars(self):
        return list(self._r)
'''


@pytest.fixture()
def throwaway_plugin(tmp_path, monkeypatch):
    pkg = tmp_path / "rt_frozen_plugin"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(textwrap.dedent(PLUGIN))
    dist = tmp_path / "rt_frozen_plugin-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: rt-frozen-plugin\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[radartracker.estimators]\nfrozen = rt_frozen_plugin:Frozen\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield "frozen"
    sys.modules.pop("rt_frozen_plugin", None)


def test_throwaway_plugin_is_listed_and_used_by_name(throwaway_plugin, demo_data, capsys):
    assert "frozen" in available_estimators() and "decoupled" in available_estimators()
    assert main(["estimators"]) == 0
    assert "frozen" in capsys.readouterr().out
    cls = load_estimator("frozen")
    assert issubclass(cls, Estimator)
    result = run(demo_data, RunConfig(estimator="frozen"), progress=False)
    assert result.estimator_name == "frozen"
    assert all(b.bias[0] == 42.0 for b in result.final_biases.values())
    assert result.counts["plots_used"] == len(demo_data.plots)


def test_unknown_estimator_lists_installed():
    with pytest.raises(ValueError, match="unknown estimator 'nope'; installed: .*decoupled"):
        load_estimator("nope")


def test_interface_is_abstract():
    with pytest.raises(TypeError):
        Estimator()  # type: ignore[abstract]
    est = load_estimator("decoupled")()
    est.add_radar("R1")
    est.add_aircraft("a", 0.0, np.zeros(4), np.eye(4))
    with pytest.raises(ValueError, match="already"):
        est.add_aircraft("a", 0.0, np.zeros(4), np.eye(4))
    pred = est.predict("a", 10.0)
    assert pred.time == 10.0 and pred.cov[0, 0] == pytest.approx(1 + 100)

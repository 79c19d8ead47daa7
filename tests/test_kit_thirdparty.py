"""A throw-away third-party estimator with an option and a motion model with typed settings, installed from
this test as a distribution with entry points (nothing in the core touched): they pass check_estimator and
check_motion_model, and their options set on the command line reach them (labelled replay and TrackManager)."""

import json

import numpy as np
import pytest

from radartracker.registry import make_manager, restore_manager
from radartracker.cli import main
from tests.plugin_install import install, uninstall
from radartracker.errors import ConfigurationError
from radartracker.io.scenario import write_scenario
from radartracker.pipeline.stream import scenario_stream
from radartracker.registry import load_estimator, load_motion_model, make_estimator
from radartracker.simulation.scenarios import build_scenario
from radartracker.testing import ESTIMATOR_CHECKS, MOTION_CHECKS, check_estimator, check_motion_model
from radartracker.tracking.config import ManagerConfig

PLUGIN = '''
"""Decoupled aircraft and bias filters with a bias forgetting factor (a third party's estimator)."""
import attrs
import numpy as np
from radartracker.api import (AircraftEstimate, BiasState, Estimator, Innovation, MotionConfig, MotionModel,
                              TrackFilter, correct, nis, require_new_radar, validated_prior)

BUILT = []  # the options of every estimator built: the test reads what reached the plugin
FILTERS = []  # the config of every track filter built


@attrs.frozen
class ForgettingConfig:
    """``bias_forgetting`` λ ≥ 1: the bias covariance is inflated, P_s ← λ P_s, before each radar update."""

    bias_forgetting: float = attrs.field(default=1.0, converter=float, validator=attrs.validators.ge(1.0))


class Forgetting(Estimator):
    """Per-aircraft and per-radar Kalman filters sharing the innovation ν = z − C_x χ̄ − C_s ς̄."""

    name = "thirdparty"
    options_class = ForgettingConfig

    def __init__(self, config=None, options=None):
        super().__init__(config, options)
        BUILT.append(self.options)
        self._x, self._s = {}, {}

    def add_radar(self, radar):
        require_new_radar(radar, self._s)
        self._s[radar] = [float("nan"), np.zeros(2), self.config.bias_prior()]

    def add_aircraft(self, key, time, state, cov):
        self._x[key] = [float(time), *validated_prior(key, state, cov, self._x)]

    def remove_aircraft(self, key):
        del self._x[key]

    def update(self, m):
        t, x, P = self._x[m.aircraft]
        A, Q = self.config.motion.transition(m.time - t)
        x, P = A @ x, A @ P @ A.T + Q
        nu, S = m.z - x[:2], P[:2, :2] + m.R
        if m.radar is not None:
            _, s, Ps = self._s[m.radar]
            Ps = self.options.bias_forgetting * Ps
            nu = nu - m.C @ s
            Ks = Ps @ m.C.T
            self._s[m.radar] = [float(m.time), *correct(s, Ps, Ks, m.C @ Ks + m.R, nu)]
        self._x[m.aircraft] = [float(m.time), *correct(x, P, P[:, :2], S, nu)]
        return Innovation(nu, S, float(nu @ np.linalg.solve(S, nu)))

    def aircraft(self, key):
        t, x, P = self._x[key]
        return AircraftEstimate(t, x.copy(), P.copy())

    def bias(self, radar):
        t, s, P = self._s[radar]
        return BiasState(radar, t, s.copy(), P.copy())

    @property
    def aircraft_keys(self):
        return list(self._x)

    @property
    def radars(self):
        return list(self._s)


@attrs.frozen
class ThirdCVConfig(MotionConfig):
    """``q``: white-acceleration density (m²/s³)."""

    q: float = attrs.field(default=1.0, converter=float, validator=attrs.validators.ge(0.0))


def _checked(time, z, R):
    time, z, R = float(time), np.asarray(z, float), np.asarray(R, float)
    if not np.isfinite(time):
        raise ValueError(f"time: not finite ({time})")
    if z.shape != (2,) or not np.isfinite(z).all():
        raise ValueError(f"z: expected 2 finite numbers, got {z.tolist()}")
    if R.shape != (2, 2) or not np.isfinite(R).all() or not np.allclose(R, R.T) or np.linalg.eigvalsh(R).min() <= 0:
        raise ValueError(f"R: expected a symmetric positive definite 2×2 matrix, got {R.tolist()}")
    return time, z, R


class ThirdCV(TrackFilter):
    """Constant-velocity Kalman filter: χ̄ = A χ̂, P̄ = A P̂ Aᵀ + Q(Δt), then the position correction."""

    name = "thirdcv"
    config_class = ThirdCVConfig

    def __init__(self, config=None):
        super().__init__(config)
        FILTERS.append(self.config)
        self.time, self.x, self.P = None, np.zeros(4), np.eye(4)

    def start(self, time, z, R):
        self.time, z, R = _checked(time, z, R)
        self.x = np.array([z[0], z[1], 0.0, 0.0])
        self.P = np.zeros((4, 4))
        self.P[:2, :2], self.P[2:, 2:] = R, self.config.prior_sd_velocity_mps ** 2 * np.eye(2)

    def predict(self, time):
        if self.time is None:
            raise ValueError("filter not started")
        time = float(time)
        if not np.isfinite(time) or abs(time - self.time) > self.config.max_gap_s:
            raise ValueError(f"time: {time} too far from the track's epoch {self.time}")
        A, Q = MotionModel(self.config.q).transition(time - self.time)
        return A @ self.x, A @ self.P @ A.T + Q

    def update(self, time, z, R):
        time, z, R = _checked(time, z, R)
        x, P = self.predict(time)
        nu, S = z - x[:2], P[:2, :2] + R
        self.x, self.P = correct(x, P, P[:, :2], S, nu)
        self.time = time
        return nis(nu, S)

    def estimate(self):
        if self.time is None:
            raise ValueError("filter not started")
        return self.time, self.x.copy(), self.P.copy()
'''


@pytest.fixture()
def thirdparty(tmp_path, monkeypatch):
    """Install the plugin the way pip would: a package and a dist-info with entry_points.txt on sys.path."""
    yield install(tmp_path, monkeypatch, "rt_kit_thirdparty", PLUGIN,
                  "[radartracker.estimators]\nthirdparty = rt_kit_thirdparty:Forgetting\n"
                  "[radartracker.motion_models]\nthirdcv = rt_kit_thirdparty:ThirdCV\n")
    uninstall("rt_kit_thirdparty")


@pytest.fixture(scope="module")
def short_demo():
    return build_scenario("demo", seed=3, duration=150.0).run()


@pytest.fixture(scope="module")
def scenario(tmp_path_factory, short_demo):
    folder = tmp_path_factory.mktemp("kit") / "demo"
    write_scenario(folder, short_demo)
    return folder


def test_thirdparty_passes_check_estimator(thirdparty):
    cls = load_estimator("thirdparty")
    assert cls is thirdparty.Forgetting
    assert check_estimator(cls, bias_forgetting="1.02") == list(ESTIMATOR_CHECKS)
    assert thirdparty.BUILT[-1].bias_forgetting == 1.02


def test_thirdparty_motion_model_passes_and_takes_cli_settings(thirdparty, scenario, tmp_path, capsys):
    cls = load_motion_model("thirdcv")
    assert cls is thirdparty.ThirdCV
    assert check_motion_model(cls, cls.config_class(q=2.0)) == list(MOTION_CHECKS)
    thirdparty.FILTERS.clear()
    out = tmp_path / "out"
    argv = ["replay", str(scenario), "--out", str(out), "--association", "manager", "--estimator", "coupled",
            "--motion-model", "thirdcv", "--motion-option", "q=3", "--motion-option", "prior_sd_velocity_mps=250",
            "--quiet"]
    assert main(argv) == 0, capsys.readouterr().err
    assert thirdparty.FILTERS and all(c == cls.config_class(q=3.0, prior_sd_velocity_mps=250.0) for c in thirdparty.FILTERS)
    config = json.loads((out / "config.json").read_text())
    assert config["settings"]["motion_model"] == "thirdcv"
    assert config["plugins"]["motion_model"] == {"prior_sd_velocity_mps": 250.0, "max_gap_s": 3600.0, "q": 3.0}
    assert main(["replay", str(scenario), "--out", str(tmp_path / "bad"), "--association", "manager",
                 "--motion-model", "thirdcv", "--motion-option", "q_turn=1", "--quiet"]) == 2
    assert "'q_turn'; valid options: max_gap_s, prior_sd_velocity_mps, q" in capsys.readouterr().err


def test_option_reaches_the_plugin_from_the_cli_on_both_paths(thirdparty, scenario, tmp_path, capsys):
    biases = {}
    for association, value in (("labels", "1.0"), ("labels", "1.05"), ("manager", "1.05")):
        out = tmp_path / f"{association}-{value}"
        thirdparty.BUILT.clear()
        argv = ["replay", str(scenario), "--out", str(out), "--association", association,
                "--estimator", "thirdparty", "--estimator-option", f"bias_forgetting={value}", "--quiet"]
        assert main(argv) == 0, capsys.readouterr().err
        assert [o.bias_forgetting for o in thirdparty.BUILT] == [float(value)]
        config = json.loads((out / "config.json").read_text())
        settings = config["settings"]
        assert settings["estimator"] == "thirdparty" and settings["estimator_options"] == {"bias_forgetting": value}
        assert config["plugins"]["estimator"] == {"bias_forgetting": float(value)}
        biases[association, value] = (out / "biases.csv").read_text()
    assert biases["labels", "1.0"] != biases["labels", "1.05"]  # the option changes what the plugin computes


def test_bad_option_from_the_cli_names_plugin_key_and_valid_keys(thirdparty, scenario, tmp_path, capsys):
    argv = ["replay", str(scenario), "--out", str(tmp_path / "o"), "--estimator", "thirdparty",
            "--estimator-option", "forgetting=2"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "'thirdparty'" in err and "'forgetting'" in err and "bias_forgetting" in err
    assert main(argv[:-1] + ["bias_forgetting=0.5"]) == 2  # the plugin's own validator: λ ≥ 1
    assert "bias_forgetting" in capsys.readouterr().err


def test_thirdparty_in_the_track_manager(thirdparty, short_demo):
    """By name with its options (as the CLI sets them), and as an instance."""
    mgr = make_manager(short_demo.radars, short_demo.reference,
                       ManagerConfig(estimator="thirdparty", estimator_options={"bias_forgetting": "1.05"}))
    assert mgr.estimator.options.bias_forgetting == 1.05
    items = scenario_stream(short_demo)
    mgr.process_many(items)
    assert mgr.accounting().get("plots_used", 0) > 0
    assert set(mgr.biases()) == {r.id for r in short_demo.radars}
    inst = make_estimator("thirdparty", mgr.config.estimator_config, [], {"bias_forgetting": "1.05"})
    mgr2 = make_manager(short_demo.radars, short_demo.reference, ManagerConfig(), estimator=inst)
    assert mgr2.estimator is inst and sorted(inst.radars) == sorted(r.id for r in short_demo.radars)
    mgr2.process_many(items)
    for rid, b in mgr2.biases().items():
        np.testing.assert_array_equal(b.bias, mgr.biases()[rid].bias)  # same plugin, same options, same data
    with pytest.raises(ConfigurationError, match="options apply to a plugin name"):
        make_estimator(inst, None, [], {"bias_forgetting": "2"})


def test_thirdparty_manager_snapshot_continues_bit_for_bit(thirdparty, short_demo, tmp_path):
    """The safe snapshot format carries a third party's estimator (its state_dict) and its options."""
    items = scenario_stream(short_demo)
    half = len(items) // 2
    config = ManagerConfig(estimator="thirdparty", estimator_options={"bias_forgetting": "1.05"})
    whole, first = (make_manager(short_demo.radars, short_demo.reference, config) for _ in range(2))
    for i in items[:half]:
        whole.process(i)
        first.process(i)
    first.snapshot(tmp_path / "snap.rts")
    restored = restore_manager(tmp_path / "snap.rts")
    assert restored.estimator.options.bias_forgetting == 1.05
    events = [whole.process(i) for i in items[half:]] + [whole.flush()]
    again = [restored.process(i) for i in items[half:]] + [restored.flush()]
    assert again == events and sum(map(len, events)) > 0
    for rid, b in whole.biases().items():
        np.testing.assert_array_equal(restored.biases()[rid].bias, b.bias)
        np.testing.assert_array_equal(restored.biases()[rid].cov, b.cov)

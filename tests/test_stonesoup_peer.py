"""The Stone Soup peer of ``scripts/tracking_report.py`` keeps Stone Soup's model: its transition model with
F and Q made once per time step gives what Stone Soup's own combined constant-velocity model gives."""

from __future__ import annotations

import datetime as dt
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stonesoup")
from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity  # noqa: E402
from stonesoup.predictor.kalman import KalmanPredictor  # noqa: E402
from stonesoup.types.state import GaussianState  # noqa: E402

SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"


@pytest.fixture()
def peer(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.syspath_prepend(str(SCRIPTS))
    spec = importlib.util.spec_from_file_location("_peer_tracking_stonesoup", SCRIPTS / "tracking_stonesoup.py")
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)
    spec.loader.exec_module(module)
    return module


def test_cached_model_is_stone_soups(peer) -> None:
    q = 5.0
    ours = peer.CachedConstantVelocity([ConstantVelocity(q), ConstantVelocity(q)])
    theirs = CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])
    prior = GaussianState(np.array([[1000.0], [200.0], [-3000.0], [-50.0]]), np.diag([4e4, 900.0, 4e4, 900.0]),
                          timestamp=dt.datetime(2026, 1, 1))
    for seconds in (0.5, 4.0, 12.3, 4.0, 0.5):  # repeated steps come from the cache
        step = dt.timedelta(seconds=seconds)
        np.testing.assert_array_equal(ours.matrix(time_interval=step), theirs.matrix(time_interval=step))
        np.testing.assert_array_equal(ours.covar(time_interval=step), theirs.covar(time_interval=step))
        a = KalmanPredictor(ours).predict(prior, timestamp=prior.timestamp + step)
        b = KalmanPredictor(theirs).predict(prior, timestamp=prior.timestamp + step)
        np.testing.assert_array_equal(a.state_vector, b.state_vector)
        np.testing.assert_array_equal(a.covar, b.covar)

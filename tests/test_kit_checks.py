"""radartracker.testing: every built-in plugin passes its conformance checks, and each check catches the
fault it is meant for in a deliberately broken plugin."""

import numpy as np
import pytest

from radartracker.api import AircraftEstimate, ConfigurationError
from radartracker.registry import available_estimators, available_motion_models, load_estimator, load_motion_model
from radartracker.testing import (ESTIMATOR_CHECKS, EXACT_CHECKS, MOTION_CHECKS, CheckFailed, check_estimator,
                                  check_motion_model)
from radartracker_plugins.decoupled import DecoupledEstimator
from radartracker_plugins.motion import CVFilter, IMMFilter

BUILT_IN_ESTIMATORS = ["decoupled", "coupled", "blom", "coupled-sparse"]
BUILT_IN_MOTION = ["cv", "imm", "adaptive", "fading"]


@pytest.mark.parametrize("name", BUILT_IN_ESTIMATORS)
def test_built_in_estimators_pass(name):
    """The exact joint filters also pass the χ² checks on biased measurements (joint_consistency)."""
    assert name in available_estimators()
    checks = EXACT_CHECKS if name in ("coupled", "coupled-sparse") else ESTIMATOR_CHECKS
    assert check_estimator(load_estimator(name), checks=checks) == list(checks)


@pytest.mark.parametrize("name", ["decoupled", "blom"])
def test_filters_ignoring_cross_covariances_fail_joint_consistency(name):
    """Their optimistic covariances (docs/estimators.md) are what the joint χ² check is for."""
    with pytest.raises(CheckFailed, match="'joint_consistency' failed: summed NIS"):
        check_estimator(load_estimator(name), checks=["joint_consistency"])


def test_estimator_options_are_checked_too():
    assert check_estimator(load_estimator("coupled-sparse"), refresh_every="7", rebuild_factor=2) == list(ESTIMATOR_CHECKS)
    with pytest.raises(ConfigurationError, match="unknown option 'refresh'.*rebuild_factor, refresh_every"):
        check_estimator(load_estimator("coupled-sparse"), refresh="7")
    with pytest.raises(ConfigurationError, match="takes no options"):
        check_estimator(load_estimator("coupled"), refresh_every=7)


@pytest.mark.parametrize("name", BUILT_IN_MOTION)
def test_built_in_motion_models_pass(name):
    assert name in available_motion_models()
    single = name != "imm"  # the IMM's estimate is a mixture, not one Kalman correction (its own FilterPy test)
    expected = [c for c in MOTION_CHECKS if single or c != "filterpy"]
    assert check_motion_model(load_motion_model(name), kalman_update=single) == expected


def test_imm_is_not_a_single_kalman_update():
    """The FilterPy check tells a mixture from one Gaussian: it fails on the IMM."""
    with pytest.raises(CheckFailed, match="'filterpy'.*multiple-model"):
        check_motion_model(IMMFilter, checks=["filterpy"])


# --- broken estimators: each check catches its fault -------------------------------------------

class NoProcessNoise(DecoupledEstimator):
    """Predicts without Q: not the Kalman filter of its configuration."""

    def __init__(self, config=None):
        super().__init__(config)
        self.config = type(self.config)(motion=type(self.config.motion)(0.0))


class Overconfident(DecoupledEstimator):
    """Reports a third of its covariance."""

    def aircraft(self, key):
        a = super().aircraft(key)
        return AircraftEstimate(a.time, a.state, a.cov / 3.0)


class ReturnsViews(DecoupledEstimator):
    """Hands out its own arrays: a caller who writes to them corrupts the filter."""

    def aircraft(self, key):
        t, x, P = self._x[key]
        return AircraftEstimate(t, x, P)


class KeepsRemoved(DecoupledEstimator):
    def remove_aircraft(self, key):
        pass


class AcceptsDuplicates(DecoupledEstimator):
    def add_aircraft(self, key, time, state, cov):
        self._x.pop(key, None)
        super().add_aircraft(key, time, state, cov)


class ForgetsBiasesInSnapshots(DecoupledEstimator):
    def state_dict(self):
        state = super().state_dict()
        return {**state, "radars": {r: [None, np.zeros(2), self.config.bias_prior()] for r in state["radars"]}}


class BatchDropsLast(DecoupledEstimator):
    def update_many(self, time, aircraft, radar, z, C, R):
        inn = super().update_many(time[:-1], aircraft[:-1], radar[:-1], z[:-1], C[:-1], R[:-1])
        return type(inn)(np.vstack([inn.nu, inn.nu[-1:]]), np.concatenate([inn.S, inn.S[-1:]]),
                         np.append(inn.nis, inn.nis[-1]))


@pytest.mark.parametrize("cls, check", [(AcceptsDuplicates, "contract"), (NoProcessNoise, "filterpy"),
                                        (Overconfident, "consistency"), (ReturnsViews, "reads"),
                                        (KeepsRemoved, "lifecycle"), (BatchDropsLast, "update_many"),
                                        (ForgetsBiasesInSnapshots, "snapshot")])
def test_broken_estimator_fails_its_check(cls, check):
    with pytest.raises(CheckFailed, match=f"check '{check}' failed"):
        check_estimator(cls, checks=[check])
    with pytest.raises(CheckFailed):  # and the full run stops at a failure
        check_estimator(cls)


def test_a_plugin_that_raises_is_reported_not_crashed():
    class Raises(DecoupledEstimator):
        def update(self, m):
            raise RuntimeError("bug inside the plugin")

    with pytest.raises(CheckFailed, match="'contract' failed: raised RuntimeError: bug inside the plugin"):
        check_estimator(Raises)


# --- broken motion models ----------------------------------------------------------------------

class PredictMoves(CVFilter):
    def predict(self, time):
        x, P = super().predict(time)
        self.x = x  # a read that writes
        return x, P


class OverconfidentCV(CVFilter):
    def update(self, time, z, R):
        nis = super().update(time, z, R)
        self.P = self.P / 5.0
        return nis


class AcceptsNaN(CVFilter):
    def update(self, time, z, R):
        return 0.0 if not np.isfinite(np.asarray(z, float)).all() else super().update(time, z, R)


class RestoresWithoutCovariance(CVFilter):
    def load_state_dict(self, state):
        super().load_state_dict({k: v for k, v in state.items() if k != "P"})


class ScreenWithoutBiasCovariance(CVFilter):
    """A faster screen that forgets the bias covariance in R_c."""

    def screen(self, time, z, C, R, bias, bias_cov, gate=None):
        return super().screen(time, z, C, R, bias, np.zeros((2, 2)), gate)


class WrongCovariance(CVFilter):
    def start(self, time, z, R):
        super().start(time, z, R)
        self.P[2:, 2:] *= 4.0


@pytest.mark.parametrize("cls, check", [(WrongCovariance, "contract"), (AcceptsNaN, "errors"), (PredictMoves, "reads"),
                                        (ScreenWithoutBiasCovariance, "screen"),
                                        (OverconfidentCV, "filterpy"), (OverconfidentCV, "consistency"),
                                        (RestoresWithoutCovariance, "snapshot")])
def test_broken_motion_model_fails_its_check(cls, check):
    with pytest.raises(CheckFailed, match=f"check '{check}' failed"):
        check_motion_model(cls, checks=[check])


def test_not_a_plugin_class():
    with pytest.raises(CheckFailed, match="not an Estimator"):
        check_estimator(CVFilter)
    with pytest.raises(CheckFailed, match="not a TrackFilter"):
        check_motion_model(DecoupledEstimator)

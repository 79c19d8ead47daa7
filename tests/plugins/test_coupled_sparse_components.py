"""``coupled-sparse`` with the sensor error model's components (issue 30): radars of 2 to 4 bias entries.

The oracle is the dense ``coupled`` filter (one covariance over everything, its own linearisation of the
range gain and the time offset): the sparse filter must give its estimates and covariances to round-off.
"""

from __future__ import annotations

import copy

import attrs
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from radartracker.api import ConfigurationError, InputError
from radartracker.estimation.base import Estimator, EstimatorConfig, PlaneMeasurement
from radartracker.estimation.motion import MotionModel
from radartracker.estimation.sensor import BiasComponent
from radartracker.registry import make_estimator
from radartracker.simulation.linsim import make_linear_scenario
from radartracker_plugins.coupled_sparse import CoupledSparseEstimator

from tests.plugins.lifetimes import P0, drive

EXTRA = {"gain": (BiasComponent("range_gain", 1e-3),), "time": (BiasComponent("time_offset", 0.5),),
         "both": (BiasComponent("range_gain", 1e-3), BiasComponent("time_offset", 0.5))}


def _config(ids: list[str], extras: list[str | None], q: float) -> EstimatorConfig:
    """Radar ids[r] with the components EXTRA[extras[r]] beside its two offsets (None: the two offsets only)."""
    base = EstimatorConfig(motion=MotionModel(q))
    return attrs.evolve(base, sensors={r: base.sensor(r).with_components(*EXTRA[e])
                                       for r, e in zip(ids, extras) if e is not None})


def _plots(sc) -> list[PlaneMeasurement]:
    """The scenario's plots with their slant range: the distance from the radar to the aircraft's true
    position (any finite ρ would do for the comparison; this one is of the right size)."""
    out = []
    for m in sc.measurements:
        rho = np.nan
        if m.radar is not None:
            j = sc.radar_ids.index(m.radar)
            truth = sc.truth[m.aircraft]
            rho = float(np.hypot(*(truth[min(truth, key=lambda t: abs(t - m.time))][:2] - sc.radar_xy[j])))
        out.append(PlaneMeasurement(m.time, m.aircraft, m.radar, m.z, m.C, m.R, rho))
    return out


def _drive(ests: list[Estimator], sc, lifetime: float, batch: int) -> list[list[tuple]]:
    """The same plots to every estimator (``update_many`` batches of ``batch``); an aircraft's track is
    removed and restarted under a new key every ``lifetime`` s. The joints after each removal and at the end."""

    def update(ests: list[Estimator], pending: list[PlaneMeasurement]) -> None:
        cols = ([m.time for m in pending], [m.aircraft for m in pending], [m.radar for m in pending],
                *(np.array([getattr(m, f) for m in pending]) for f in ("z", "C", "R")))
        nis = [e.update_many(*cols, [m.rho for m in pending]).nis if isinstance(e, CoupledSparseEstimator)
               else np.array([e.update(m).nis for m in pending]) for e in ests]
        np.testing.assert_allclose(nis[1], nis[0], rtol=1e-7, atol=1e-10)

    return drive(ests, _plots(sc), lifetime, batch, update, lambda m: m.z)


def _largest_difference(a: tuple, b: tuple) -> tuple[float, float]:
    """max |Δξ| / σ and max |ΔP| / (σ_i σ_j) of ``b`` against the reference ``a``."""
    (xa, Pa), (xb, Pb) = a, b
    sd = np.sqrt(np.diag(Pa))
    assert np.all(np.isfinite(xb)) and np.all(np.isfinite(Pb))
    return float(np.max(np.abs(xa - xb) / sd)), float(np.max(np.abs(Pa - Pb) / np.outer(sd, sd)))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), n=st.integers(1, 5), extras=st.lists(
    st.sampled_from([None, "gain", "time", "both"]), min_size=1, max_size=4), adsb=st.integers(0, 2),
    q=st.sampled_from([0.0, 0.5]), lifetime=st.sampled_from([40.0, 1e9]), batch=st.sampled_from([1, 7]),
    refresh=st.sampled_from([1, 256]), rebuild=st.sampled_from([1, 64]))
def test_sparse_equals_dense_coupled_with_every_component(seed, n, extras, adsb, q, lifetime, batch, refresh,
                                                           rebuild):
    """Estimates, biases and all covariances of the dense filter to 1e-8 of the σ's, with radars of 2, 3
    and 4 components side by side, ADS-B, process noise, aircraft added and removed, any refresh schedule."""
    sc = make_linear_scenario(n_aircraft=n, n_radars=len(extras), duration=150.0, period=5.0, rng=seed,
                              adsb_aircraft=adsb, q=q)
    cfg = _config(sc.radar_ids, extras, q)
    dense = make_estimator("coupled", cfg, sc.radar_ids)
    sparse = CoupledSparseEstimator(cfg, refresh_every=refresh, rebuild_factor=rebuild)
    for r in sc.radar_ids:
        sparse.add_radar(r)
    for a, b in _drive([dense, sparse], sc, lifetime, batch):
        dx, dP = _largest_difference(a, b)
        assert dx < 1e-8 and dP < 1e-8
    for r in sc.radar_ids:
        bd, bs = dense.bias(r), sparse.bias(r)
        assert bs.components == bd.components == cfg.sensor(r).names
        sd = np.sqrt(np.diag(bd.cov))
        assert np.max(np.abs(bs.bias - bd.bias) / sd) < 1e-8
        assert np.max(np.abs(bs.cov - bd.cov) / np.outer(sd, sd)) < 1e-8


def test_two_offsets_beside_four_components_keep_their_own_blocks():
    """A radar with the two offsets beside one with four: bias reads of 2 and 4 entries, Y_ib blocks 4×2 and
    4×4 for an aircraft both saw, and every number the dense filter's."""
    sc = make_linear_scenario(n_aircraft=3, n_radars=2, duration=120.0, period=4.0, rng=7, adsb_aircraft=1, q=0.5)
    cfg = _config(sc.radar_ids, [None, "both"], 0.5)
    dense, sparse = (make_estimator(name, cfg, sc.radar_ids) for name in ("coupled", "coupled-sparse"))
    [(a, b)] = _drive([dense, sparse], sc, 1e9, 5)
    dx, dP = _largest_difference(a, b)
    assert dx < 1e-9 and dP < 1e-9
    two, four = sc.radar_ids
    assert sparse.bias(two).bias.shape == (2,) and sparse.bias(four).cov.shape == (4, 4)
    _, blocks, _, _ = sparse.information()["aircraft"][sparse.aircraft_keys[0]]
    assert blocks[two].shape == (4, 2) and blocks[four].shape == (4, 4)
    # the unbiased ADS-B plots and the two-offset radar leave the four-component radar's prior where no plot is
    assert np.all(np.linalg.eigvalsh(sparse.bias(four).cov) > 0)


def test_snapshot_round_trip_with_components_continues_as_the_original():
    """state_dict → a new estimator → the same plots: the same numbers as the estimator never stopped (to the
    last bit), also through copy.deepcopy; a state of radars with other sensor models is refused."""
    sc = make_linear_scenario(n_aircraft=3, n_radars=3, duration=160.0, period=5.0, rng=3, adsb_aircraft=1, q=0.5)
    cfg = _config(sc.radar_ids, ["both", None, "time"], 0.5)
    plots = _plots(sc)
    first, rest = plots[:len(plots) // 2], plots[len(plots) // 2:]
    est = make_estimator("coupled-sparse", cfg, sc.radar_ids)
    for k, x in sc.initial.items():
        est.add_aircraft(k, 0.0, x, P0)
    for m in first:
        est.update(m)
    restored = make_estimator("coupled-sparse", cfg, sc.radar_ids)
    restored.load_state_dict(est.state_dict())
    copied = copy.deepcopy(est)
    for m in rest:
        for e in (est, restored, copied):
            e.update(m)
    for e in (restored, copied):
        assert all(np.array_equal(u, v) for u, v in zip(est.joint(), e.joint()))
    other = make_estimator("coupled-sparse", _config(sc.radar_ids, ["gain", None, "time"], 0.5), sc.radar_ids)
    with pytest.raises(InputError, match="coupled-sparse state"):
        other.load_state_dict(est.state_dict())


def test_drift_of_any_component_is_refused_with_the_reason():
    base = EstimatorConfig()
    drifting = attrs.evolve(base, sensors={"A": base.sensor("A").with_components(
        BiasComponent("time_offset", 0.5, drift=1e-6))})
    with pytest.raises(ValueError, match="drifting biases make the information matrix dense"):
        make_estimator("coupled-sparse", drifting, ["A"])


def test_a_range_gain_without_the_slant_range_and_a_zero_prior_are_refused():
    """A plot of a radar with a range gain and no ρ: ValueError naming it, the rows before it applied."""
    sc = make_linear_scenario(n_aircraft=1, n_radars=1, duration=30.0, period=5.0, rng=1)
    cfg = _config(sc.radar_ids, ["gain"], 0.0)
    est, ref = (make_estimator("coupled-sparse", cfg, sc.radar_ids) for _ in range(2))
    for e in (est, ref):
        for k, x in sc.initial.items():
            e.add_aircraft(k, 0.0, x, P0)
    m0, m1 = _plots(sc)[:2]
    ref.update(m0)
    cols = ([m0.time, m1.time], [m0.aircraft, m1.aircraft], [m0.radar, m1.radar],
            *(np.array([getattr(m0, f), getattr(m1, f)]) for f in ("z", "C", "R")))
    with pytest.raises(ValueError, match="has a range gain, which needs the plot's slant range") as info:
        est.update_many(*cols, [m0.rho, np.nan])
    assert info.value.index == 1
    assert all(np.array_equal(u, v) for u, v in zip(ref.joint(), est.joint()))
    zero = attrs.evolve(EstimatorConfig(), sensors={"A": EstimatorConfig().sensor("A").with_components(
        BiasComponent("range_gain", 0.0))})
    with pytest.raises(ConfigurationError, match="prior σ 0"):
        make_estimator("coupled-sparse", zero, ["A"])

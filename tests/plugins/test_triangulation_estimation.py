"""Static and dynamic triangulation against exact answers, the Cramér–Rao bound and χ² bounds.

Oracles: noiseless bearings from pyproj (exact recovery), the independently assembled CRLB (its
Fisher information is checked against finite differences in test_triangulation_model), scipy's
χ² quantiles for Monte Carlo statistics, and finite differences of the pyproj-based ML cost.
"""

import math

import attrs
import numpy as np
import pytest
from scipy import stats

from radartracker_plugins.triangulation import (DirectionFinder, GeometryError, PolynomialBasis,
                                                TriangulationFrame, locate, track)
from radartracker_plugins.triangulation import crlb
from radartracker_plugins.triangulation.simulate import (noisy_bearings, schedule, sites_around,
                                                         true_bearings)

SIG = 1e-3
LAT, LON = 47.0, 8.0


def _stations(azimuths, dist=40e3, sigma=SIG, grids=None):
    sites = sites_around(LAT, LON, dist, azimuths)
    return [DirectionFinder(f"s{i}", la, lo, 100.0 + 50 * i, sigma, sigma,
                            None if grids is None else grids[i]) for i, (la, lo) in enumerate(sites)]


def _good_static():
    frame = TriangulationFrame(_stations([10, 130, 250]))
    return frame, frame.enu(LAT, LON, 8000.0), list(frame.stations)


def _good_dynamic(order=1):
    grids = [np.arange(0.0, 120.0, 4.0), np.arange(1.3, 120.0, 5.0), np.arange(2.1, 120.0, 6.0)]
    frame = TriangulationFrame(_stations([10, 130, 250], grids=grids))
    ids, times = schedule(frame)
    basis = PolynomialBasis(order, 60.0, 60.0)
    theta = np.zeros((3, order + 1))
    theta[:, 0] = frame.enu(LAT, LON, 8000.0)
    theta[:, 1] = [12e3, 6e3, 300.0]  # 200 m/s east, 100 m/s north, 5 m/s up (τ = t/60)
    if order >= 2:
        theta[:, 2] = [-3e3, 2e3, 0.0]
    return frame, ids, times, basis, theta


class _NoNoise:
    """Stands in for a numpy Generator: noiseless bearings."""

    def standard_normal(self, shape):
        return np.zeros(shape)


def _rmse_interval(bound_eigs, runs, p=0.999):
    """Two-sided interval for RMSE/√Σλ over ``runs`` when each error is N(0, diag(λ)).

    Σλ_i χ²_1 is approximated by c·χ²_ν (Satterthwaite: ν = (Σλ)²/Σλ²), so the mean over runs is
    (Σλ)·χ²_{runs·ν}/(runs·ν).
    """
    lam = np.asarray(bound_eigs)
    nu = runs * lam.sum() ** 2 / np.sum(lam**2)
    lo, hi = stats.chi2.ppf([(1 - p) / 2, (1 + p) / 2], nu) / nu
    return math.sqrt(lo), math.sqrt(hi)


def test_static_noiseless_recovers_target_exactly():
    frame, r, ids = _good_static()
    truth = true_bearings(frame, ids, np.tile(r, (3, 1)))
    fix = locate(frame, noisy_bearings(frame, ids, [0, 0, 0], truth, _NoNoise()))
    assert np.allclose(fix.position, r, atol=1e-4)
    assert fix.chi2 < 1e-12 and fix.dof == 3 and not fix.poor_geometry


def test_static_estimate_is_a_minimum_of_the_pyproj_ml_cost():
    frame, r, ids = _good_static()
    rng = np.random.default_rng(11)
    truth = true_bearings(frame, ids, np.tile(r, (3, 1)))
    bs = noisy_bearings(frame, ids, [0, 0, 0], truth, rng)
    meas = np.array([[b.azimuth_rad, b.elevation_rad] for b in bs])

    def cost(p):
        d = meas - true_bearings(frame, ids, np.tile(p, (3, 1)))
        d[:, 0] = np.angle(np.exp(1j * d[:, 0]))
        return float(np.sum((d / SIG) ** 2))

    fix = locate(frame, bs)
    grad = [(cost(fix.position + e) - cost(fix.position - e)) / 2.0 for e in np.eye(3)]
    assert np.max(np.abs(grad)) < 1e-5  # per metre; the cost changes by ~1e-3 per metre here
    assert abs(cost(fix.position) - fix.chi2) < 1e-8
    # the start is a different, worse point: the refinement does something
    assert cost(fix.start) > cost(fix.position)


def _static_monte_carlo(runs, seed):
    """RMSE/CRLB, its efficient-estimator 99.9 % interval, and the total NEES over ``runs``."""
    frame, r, ids = _good_static()
    ids = ids * 2  # two bearings per station
    truth = true_bearings(frame, ids, np.tile(r, (len(ids), 1)))
    bound = crlb.static_crlb(frame, ids, r)
    rng = np.random.default_rng(seed)
    err = np.array([locate(frame, noisy_bearings(frame, ids, np.zeros(len(ids)), truth, rng)).position - r
                    for _ in range(runs)])
    ratio = math.sqrt(np.mean(np.sum(err**2, axis=1)) / np.trace(bound))
    nees = np.einsum("ni,ij,nj->", err, np.linalg.inv(bound), err)
    return ratio, _rmse_interval(np.linalg.eigvalsh(bound), runs), nees


def test_static_monte_carlo_rmse_and_nees_match_crlb():
    runs = 60
    ratio, (lo, hi), nees = _static_monte_carlo(runs, seed=2024)
    assert lo < ratio < hi and hi < 1.35
    assert stats.chi2.ppf(0.0005, 3 * runs) < nees < stats.chi2.ppf(0.9995, 3 * runs)


@pytest.mark.slow
def test_static_monte_carlo_500_runs_rmse_within_10_percent_of_crlb():
    ratio, (lo, hi), _ = _static_monte_carlo(500, seed=77)
    assert abs(ratio - 1.0) < 0.10 and lo < ratio < hi


@pytest.mark.parametrize("order", [1, 2])
def test_dynamic_noiseless_recovers_motion(order):
    frame, ids, times, basis, theta = _good_dynamic(order)
    pos = basis(times) @ theta.T
    tr = track(frame, noisy_bearings(frame, ids, times, true_bearings(frame, ids, pos), _NoNoise()),
               order=order)
    assert np.allclose(tr.position(times), pos, atol=1e-3)
    assert tr.dof == 2 * len(times) - 3 * (order + 1)


def _dynamic_monte_carlo(runs, seed, order=1):
    frame, ids, times, basis, theta = _good_dynamic(order)
    Q = basis(times)
    pos = Q @ theta.T
    truth = true_bearings(frame, ids, pos)
    bound = crlb.dynamic_crlb(frame, ids, times, basis, theta)
    rng = np.random.default_rng(seed)
    err, nees = [], 0.0
    for _ in range(runs):
        tr = track(frame, noisy_bearings(frame, ids, times, truth, rng), basis=basis)
        err.append(tr.position(times) - pos)
        d = (tr.theta - theta).ravel()
        nees += d @ np.linalg.solve(bound, d)
    mse = np.mean(np.sum(np.array(err) ** 2, axis=2))
    # the per-run MSE is δθᵀ G δθ with G = mean_n (I₃⊗q_n)ᵀ(I₃⊗q_n): eigenvalues of G·bound
    G = np.mean([np.kron(np.eye(3), q[None]).T @ np.kron(np.eye(3), q[None]) for q in Q], axis=0)
    lam = np.linalg.eigvals(G @ bound).real
    return math.sqrt(mse / lam.sum()), _rmse_interval(lam, runs), nees, 3 * (order + 1)


def test_dynamic_monte_carlo_rmse_and_nees_match_crlb():
    runs = 60
    ratio, (lo, hi), nees, p = _dynamic_monte_carlo(runs, seed=7)
    assert lo < ratio < hi and hi < 1.35
    assert stats.chi2.ppf(0.0005, p * runs) < nees < stats.chi2.ppf(0.9995, p * runs)


@pytest.mark.slow
@pytest.mark.parametrize("order", [1, 2])
def test_dynamic_monte_carlo_500_runs_rmse_within_10_percent_of_crlb(order):
    ratio, (lo, hi), _, _ = _dynamic_monte_carlo(500, seed=78 + order, order=order)
    assert abs(ratio - 1.0) < 0.10 and lo < ratio < hi


@pytest.mark.slow
def test_poor_geometry_monte_carlo_is_flagged_and_stays_near_the_bound():
    """Two stations 20 km apart, target 80 km away 8° off their axis (GDOP ≈ 40)."""
    sites = sites_around(LAT, LON, 10e3, [90.0, 270.0])
    frame = TriangulationFrame([DirectionFinder(f"p{i}", la, lo, 200.0, SIG, SIG)
                                for i, (la, lo) in enumerate(sites)])
    r = frame.enu(*sites_around(LAT, LON, 80e3, [82.0])[0], 3000.0)
    ids = list(frame.stations)
    truth = true_bearings(frame, ids, np.tile(r, (2, 1)))
    bound = crlb.static_crlb(frame, ids, r)
    rng = np.random.default_rng(5)
    fixes = [locate(frame, noisy_bearings(frame, ids, [0, 0], truth, rng)) for _ in range(300)]
    assert all(f.poor_geometry and f.gdop > 10 for f in fixes)
    ratio = math.sqrt(np.mean([np.sum((f.position - r) ** 2) for f in fixes]) / np.trace(bound))
    lo, hi = _rmse_interval(np.linalg.eigvalsh(bound), len(fixes))
    assert lo < ratio < hi


def test_dynamic_basis_hook_gives_the_same_trajectory():
    frame, ids, times, basis, theta = _good_dynamic(order=2)
    pos = basis(times) @ theta.T
    bs = noisy_bearings(frame, ids, times, true_bearings(frame, ids, pos), np.random.default_rng(1))
    poly = track(frame, bs, order=2)

    def legendre(t):  # P0, P1, P2 on [0, 120]: spans the same space as 1, t, t²
        x = (np.asarray(t, float) - 60.0) / 60.0
        return np.column_stack([np.ones_like(x), x, 1.5 * x**2 - 0.5])

    hooked = track(frame, bs, basis=legendre)
    assert hooked.theta.shape == (3, 3)
    assert np.allclose(hooked.position(times), poly.position(times), atol=1e-6)
    assert np.allclose(hooked.covariance(times), poly.covariance(times), rtol=1e-6)


def test_basis_with_wrong_shape_is_refused():
    frame, ids, times, basis, theta = _good_dynamic()
    bs = noisy_bearings(frame, ids, times, true_bearings(frame, ids, basis(times) @ theta.T), _NoNoise())
    with pytest.raises(ValueError, match="basis"):
        track(frame, bs, basis=lambda t: np.ones(len(t)))


def test_single_station_is_refused_with_gdop():
    frame, r, _ = _good_static()
    ids = ["s0"] * 5
    bs = noisy_bearings(frame, ids, np.zeros(5), true_bearings(frame, ids, np.tile(r, (5, 1))),
                        np.random.default_rng(0))
    with pytest.raises(GeometryError, match="GDOP = inf") as exc:
        locate(frame, bs)
    assert exc.value.gdop == math.inf and "minor" in str(exc.value)


def test_collinear_stations_and_target_are_refused_with_gdop():
    near, far = sites_around(LAT, LON, 20e3, [90])[0], sites_around(LAT, LON, 50e3, [90])[0]
    frame = TriangulationFrame([DirectionFinder("near", *near, 100.0, SIG, SIG),
                                DirectionFinder("far", *far, 300.0, SIG, SIG)])
    a, b = frame.position["near"], frame.position["far"]
    target = b + 1.5 * (b - a)  # on the 3-D straight line through both sites
    ids = list(frame.stations)
    truth = true_bearings(frame, ids, np.tile(target, (2, 1)))
    with pytest.raises(GeometryError, match="GDOP") as exc:
        locate(frame, noisy_bearings(frame, ids, [0, 0], truth, _NoNoise()))
    assert exc.value.gdop == math.inf and "collinear" in str(exc.value)


def test_nearly_collinear_geometry_is_flagged_or_refused_never_silent():
    frame = TriangulationFrame(_stations([0, 180], dist=20e3))
    a, b = frame.position["s0"], frame.position["s1"]
    ids = ["s0", "s1"]
    rng = np.random.default_rng(3)
    outcomes = set()
    for angle_deg in (1.0, 3.0, 60.0):  # target 60 km off the baseline's mid-point, near its axis
        u = (a - b) / np.linalg.norm(a - b)
        side = np.cross(u, [0.0, 0.0, 1.0])
        side /= np.linalg.norm(side)
        r = 0.5 * (a + b) + 60e3 * (math.cos(math.radians(angle_deg)) * u + math.sin(math.radians(angle_deg)) * side)
        r[2] = 3000.0
        truth = true_bearings(frame, ids, np.tile(r, (2, 1)))
        try:
            fix = locate(frame, noisy_bearings(frame, ids, [0, 0], truth, rng))
        except GeometryError as exc:
            assert "GDOP" in str(exc) and exc.gdop > 10
            outcomes.add("refused")
            continue
        bound = crlb.static_crlb(frame, ids, r)
        gdop_true = math.sqrt(np.trace(bound)) / (SIG * np.linalg.norm(r - 0.5 * (a + b)))
        outcomes.add("poor" if fix.poor_geometry else "ok")
        assert fix.poor_geometry == (fix.gdop > 10.0)
        if angle_deg == 60.0:
            assert not fix.poor_geometry and gdop_true < 10
    assert "ok" in outcomes and outcomes & {"poor", "refused"}


def test_unknown_station_in_bearings_is_refused():
    frame, r, ids = _good_static()
    truth = true_bearings(frame, ids, np.tile(r, (3, 1)))
    bs = noisy_bearings(frame, ids, [0, 0, 0], truth, _NoNoise())
    bs[0] = attrs.evolve(bs[0], station="nope")
    with pytest.raises(ValueError, match="unknown station"):
        locate(frame, bs)

"""The seed's least-squares triangulation with a free weight matrix W (seed 001 eq. 3.1).

Oracles: an independent weighted least squares — scipy's ``least_squares`` (trust-region, finite
difference Jacobian) on the full 2N×2N W, its square root from ``scipy.linalg.sqrtm``, and the
bearing model evaluated station by station — for static and dynamic cases; W = K⁻¹ reproduces ML;
the sandwich covariance against Monte Carlo scatter.
"""

import numpy as np
import pytest
from scipy.linalg import block_diag, sqrtm
from scipy.optimize import least_squares

from radartracker.api import FormatError
from radartracker_plugins.triangulation import StationWeights, locate, read_weights, track
from radartracker_plugins.triangulation.frame import wrap_angle
from radartracker_plugins.triangulation.simulate import noisy_bearings, true_bearings

from tests.plugins.test_triangulation_estimation import SIG, _good_dynamic, _good_static

BLOCKS = {"s0": np.array([[2.0, 0.3], [0.3, 0.5]]), "s1": np.eye(2), "s2": np.array([[0.7, -0.2], [-0.2, 3.0]])}


def _independent(frame, bearings, positions_of, x0, blocks):
    """argmin (γ̃ − h)ᵀ W (γ̃ − h) with W the full block-diagonal matrix, by scipy alone."""
    g = np.array([[b.azimuth_rad, b.elevation_rad] for b in bearings])
    st = [b.station for b in bearings]
    t = np.array([b.time for b in bearings])
    S = np.real(sqrtm(block_diag(*[blocks[s] for s in st])))

    def fun(x):
        r = positions_of(x, t)
        h = np.array([frame.bearings(s, r[n:n + 1])[0] for n, s in enumerate(st)])
        d = g - h
        d[:, 0] = wrap_angle(d[:, 0])
        return S @ d.ravel() / SIG  # in units of the noise, so the tolerances mean something

    fit = least_squares(fun, x0, method="trf", jac="3-point", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return fit.x, lambda x: 0.5 * float(np.sum(fun(x) ** 2))


def test_static_lsq_equals_an_independent_weighted_least_squares():
    frame, pos, ids = _good_static()
    rng = np.random.default_rng(3)
    ids3 = ids * 3
    bearings = noisy_bearings(frame, ids3, np.zeros(len(ids3)), true_bearings(frame, ids3, [pos] * len(ids3)), rng)
    for blocks in (BLOCKS, {s: np.eye(2) for s in ids}):
        weights = StationWeights(blocks) if len(blocks) == 3 and blocks is BLOCKS else StationWeights.identity()
        fix = locate(frame, bearings, weights=weights)
        ref, cost = _independent(frame, bearings, lambda x, t: np.tile(x, (len(t), 1)), pos + 50.0, blocks)
        # the same minimiser (to the finite-difference optimiser's precision), ours at least as low
        np.testing.assert_allclose(fix.position, ref, rtol=0, atol=1e-5)
        assert cost(fix.position) <= cost(ref) * (1 + 1e-9)
        assert fix.estimator == "lsq"


def test_w_equal_k_inverse_is_the_ml_estimate_and_identity_differs():
    frame, pos, ids = _good_static()
    sig = frame.sigmas(ids[0])
    bearings = noisy_bearings(frame, ids, np.zeros(3), true_bearings(frame, ids, [pos] * 3), np.random.default_rng(5))
    ml = locate(frame, bearings)
    kinv = locate(frame, bearings, weights=StationWeights({s: np.diag(frame.sigmas(s) ** -2) for s in ids}))
    np.testing.assert_allclose(kinv.position, ml.position, atol=1e-7)
    np.testing.assert_allclose(kinv.cov, ml.cov, rtol=1e-8)
    assert ml.estimator == "ml" and sig[0] > 0


def test_dynamic_lsq_equals_an_independent_weighted_least_squares():
    frame, ids, times, basis, theta = _good_dynamic(order=1)
    pos = basis(times) @ theta.T
    bearings = noisy_bearings(frame, ids, times, true_bearings(frame, ids, pos), np.random.default_rng(7))
    fit = track(frame, bearings, basis=basis, weights=StationWeights(BLOCKS))
    K = theta.shape[1]
    ref, cost = _independent(frame, bearings, lambda x, t: basis(t) @ x.reshape(3, K).T, (theta + 30.0).ravel(),
                             BLOCKS)
    np.testing.assert_allclose(fit.theta.ravel(), ref, rtol=0, atol=1e-4)
    assert cost(fit.theta.ravel()) <= cost(ref) * (1 + 1e-9)
    ml = track(frame, bearings, basis=basis)
    assert np.max(np.abs(ml.theta - fit.theta)) > 1e-2  # unequal weights: LSQ is not ML here
    assert fit.estimator == "lsq"


def test_sandwich_covariance_matches_monte_carlo_scatter():
    """cov of the W = I estimate under the stated noise: 400 runs, trace within a χ²-sized band."""
    frame, pos, ids = _good_static()
    frame = type(frame)([s.__class__(s.id, s.lat, s.lon, s.height_m, s.sigma_azimuth_rad * (1 + 2 * i),
                                     s.sigma_elevation_rad, s.times) for i, s in enumerate(frame.stations.values())],
                        frame.reference)
    truth = true_bearings(frame, ids, [pos] * 3)
    rng = np.random.default_rng(11)
    errs, cov = [], None
    for _ in range(400):
        fix = locate(frame, noisy_bearings(frame, ids, np.zeros(3), truth, rng), weights=StationWeights.identity())
        errs.append(fix.position - pos)
        cov = fix.cov
    scatter = np.cov(np.array(errs).T)
    ratio = np.trace(scatter) / np.trace(cov)
    assert 0.8 < ratio < 1.25, ratio
    ml = locate(frame, noisy_bearings(frame, ids, np.zeros(3), truth, rng))
    assert np.trace(cov) >= np.trace(ml.cov) * (1 - 1e-9)  # Gauss–Markov: ML is never worse


def test_weights_file_rows_are_checked(tmp_path):
    p = tmp_path / "w.csv"
    p.write_text("station,w_azimuth,w_elevation,w_cross\ns0,1,2,0.5\ns1,1,1,\n")
    w = read_weights(p)
    np.testing.assert_array_equal(w.blocks["s0"], [[1, 0.5], [0.5, 2]])
    p.write_text("station,w_azimuth,w_elevation,w_cross\ns0,1,1,5\n")
    with pytest.raises(FormatError, match="line 2"):
        read_weights(p)
    p.write_text("station,w_azimuth,w_elevation\ns0,1,x\n")
    with pytest.raises(FormatError, match="w_elevation"):
        read_weights(p)


def test_command_line_lsq_matches_the_library_and_refuses_weights_with_ml(tmp_path, capsys):
    from radartracker.cli import main
    from radartracker_plugins.triangulation import io
    from tests.plugins.test_triangulation_cli import LAT, LON, REF, _read_csv, _rows, _write_bearings, _write_stations

    frame = _write_stations(tmp_path / "stations.csv")
    target = frame.enu(LAT + 0.05, LON - 0.1, 7000.0)
    ids = list(frame.stations) * 2
    _write_bearings(tmp_path / "b.csv", _rows(frame, ids, np.arange(6.0), np.tile(target, (6, 1)), "A",
                                              np.random.default_rng(2)))
    (tmp_path / "w.csv").write_text("station,w_azimuth,w_elevation\ndf0,4,1\ndf1,1,1\ndf2,1,9\n")
    common = [str(tmp_path / "b.csv"), "--stations", str(tmp_path / "stations.csv"), "--reference",
              ",".join(map(str, REF))]
    assert main(["triangulate", *common, "--out", str(tmp_path / "o"), "--estimator", "lsq",
                 "--weights", str(tmp_path / "w.csv")]) == 0
    row = _read_csv(tmp_path / "o" / "fixes.csv")[0]
    bearings, _ = io.read_bearings(tmp_path / "b.csv")
    lib = locate(frame, bearings, weights=read_weights(tmp_path / "w.csv"))
    np.testing.assert_allclose([float(row[k]) for k in ("east_m", "north_m", "up_m")], lib.position, atol=0.01)
    assert main(["triangulate", *common, "--out", str(tmp_path / "o2"), "--weights", "identity"]) == 2
    assert "--weights: only with --estimator lsq" in capsys.readouterr().err

"""Triangulation model: sensors, the exact bearing model, its Jacobian and the Fisher information.

Oracles: pyproj's geodetic → station-ENU path (RadarFrame.polar), finite differences of it.
"""

import math

import numpy as np
import pytest

from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker_plugins.triangulation import Bearing, DirectionFinder, TriangulationFrame
from radartracker_plugins.triangulation import crlb
from radartracker_plugins.triangulation.dynamic import PolynomialBasis
from radartracker_plugins.triangulation.simulate import sites_around, true_bearings

SIG = 1e-3


def _frame(lat=52.0, lon=4.5, n=3, dist=40e3, reference=None):
    sites = sites_around(lat, lon, dist, np.linspace(0, 360, n, endpoint=False) + 20)
    return TriangulationFrame([DirectionFinder(f"s{i}", la, lo, 30.0 * i, SIG, 2 * SIG)
                               for i, (la, lo) in enumerate(sites)], reference)


@pytest.mark.parametrize("field,value", [
    ("lat", 91.0), ("lon", float("nan")), ("height_m", "x"), ("sigma_azimuth_rad", 0.0),
    ("sigma_elevation_rad", -1e-3), ("id", " "), ("times", [3.0, 2.0]),
])
def test_direction_finder_validation_names_field(field, value):
    kw = dict(id="a", lat=50.0, lon=5.0, height_m=10.0, sigma_azimuth_rad=1e-3, sigma_elevation_rad=1e-3)
    kw[field] = value
    with pytest.raises(ValueError, match=field):
        DirectionFinder(**kw)


@pytest.mark.parametrize("field,value", [
    ("time", float("inf")), ("station", ""), ("azimuth_rad", 2 * math.pi), ("azimuth_rad", -0.1),
    ("elevation_rad", 1.6),
])
def test_bearing_validation_names_field(field, value):
    kw = dict(time=0.0, station="a", azimuth_rad=1.0, elevation_rad=0.1)
    kw[field] = value
    with pytest.raises(ValueError, match=field):
        Bearing(**kw)


def test_duplicate_station_ids_refused():
    s = DirectionFinder("a", 50.0, 5.0, 0.0, SIG, SIG)
    with pytest.raises(ValueError, match="twice"):
        TriangulationFrame([s, s])


@pytest.mark.parametrize("lat,lon", [(52.0, 4.5), (-33.9, 151.2), (69.7, 18.9), (0.1, 179.9)])
def test_bearing_model_matches_pyproj_polar(lat, lon):
    frame = _frame(lat, lon, n=4, dist=150e3)
    plane = SystemPlane(lat, lon)
    rng = np.random.default_rng(3)
    r = np.column_stack([rng.uniform(-2e5, 2e5, 20), rng.uniform(-2e5, 2e5, 20), rng.uniform(1e3, 12e3, 20)])
    glat, glon, gh = frame.geodetic(r)
    for sid, s in frame.stations.items():
        _, az, el = RadarFrame(s.lat, s.lon, s.height_m, plane).polar(glat, glon, gh)
        got = frame.bearings(sid, r)
        assert np.allclose(np.angle(np.exp(1j * (got[:, 0] - az))), 0.0, atol=1e-10)
        assert np.allclose(got[:, 1], el, atol=1e-10)


def test_line_of_sight_points_along_bearing():
    frame = _frame()
    for sid in frame.stations:
        d = frame.line_of_sight(sid, 1.234, 0.2)
        assert np.isclose(np.linalg.norm(d), 1.0)
        assert np.allclose(frame.bearings(sid, frame.position[sid] + 5e4 * d), [1.234, 0.2], atol=1e-12)


def _fd_jacobian(f, x, step=1.0):
    cols = []
    for k in range(len(x)):
        dx = np.zeros(len(x))
        dx[k] = step
        d = f(x + dx) - f(x - dx)
        d[..., 0] = np.angle(np.exp(1j * d[..., 0]))  # azimuth differences across north
        cols.append(d.ravel() / (2 * step))
    return np.array(cols).T


def test_jacobian_matches_finite_differences_of_pyproj_model():
    frame = _frame()
    rng = np.random.default_rng(5)
    r = np.column_stack([rng.uniform(-6e4, 6e4, 8), rng.uniform(-6e4, 6e4, 8), rng.uniform(500, 1e4, 8)])
    steps = np.vstack([np.eye(3), -np.eye(3)])  # ±1 m along each axis
    pts = (r[:, None, :] + steps[None]).reshape(-1, 3)
    for sid in frame.stations:
        g = true_bearings(frame, [sid] * len(pts), pts).reshape(len(r), 6, 2)
        d = g[:, :3] - g[:, 3:]
        d[..., 0] = np.angle(np.exp(1j * d[..., 0]))  # azimuth differences across north
        fd = np.transpose(d, (0, 2, 1)) / 2.0  # (point, angle, axis)
        assert np.allclose(frame.jacobian(sid, r), fd, rtol=1e-6, atol=1e-12)


def _numerical_fisher(frame, stations, params, position_of):
    """Σ JᵀK⁻¹J with J from central differences of the pyproj model w.r.t. the parameters."""
    def h(p):
        return true_bearings(frame, stations, position_of(p))
    J = _fd_jacobian(h, params).reshape(len(stations), 2, len(params))
    w = np.array([1.0 / frame.sigmas(s) ** 2 for s in stations])
    return np.einsum("nip,ni,niq->pq", J, w, J)


def test_static_fisher_matches_numerical_fisher():
    frame = _frame(n=3)
    r = np.array([5e3, -8e3, 9e3])
    stations = list(frame.stations) * 2
    numeric = _numerical_fisher(frame, stations, r, lambda p: np.tile(p, (len(stations), 1)))
    assert np.allclose(np.linalg.inv(crlb.static_crlb(frame, stations, r)), numeric, rtol=1e-6)


def test_dynamic_fisher_matches_numerical_fisher():
    frame = _frame(n=3)
    times = np.arange(0.0, 60.0, 3.0)
    stations = [list(frame.stations)[i % 3] for i in range(len(times))]
    basis = PolynomialBasis(2, 30.0, 30.0)
    theta = np.array([[1e3, 6e3, -500.0], [-2e3, 3e3, 800.0], [9e3, 0.0, -300.0]])
    Q = basis(times)
    numeric = _numerical_fisher(frame, stations, theta.ravel(), lambda p: Q @ p.reshape(3, 3).T)
    analytic = np.linalg.inv(crlb.dynamic_crlb(frame, stations, times, basis, theta))
    assert np.allclose(analytic, numeric, rtol=1e-6, atol=1e-9 * np.abs(numeric).max())


def test_position_bound_of_static_basis_is_the_parameter_bound():
    B = np.diag([1.0, 2.0, 3.0])
    assert np.allclose(crlb.position_bound(np.ones((2, 1)), B), B)

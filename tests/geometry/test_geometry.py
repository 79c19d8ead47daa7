"""Geodesy against pyproj's geodesic, round trips, and the Jacobian against finite differences."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import Geod, Proj

from radartracker.geometry.plane import RadarFrame, SystemPlane

PLANE = SystemPlane(48.85, 2.35)
RADAR = RadarFrame(49.4, 3.6, 150.0, PLANE)


def test_round_trip_to_millimetres():
    rng = np.random.default_rng(0)
    lat = 48.85 + rng.uniform(-2.5, 2.5, 1000)
    lon = 2.35 + rng.uniform(-3.5, 3.5, 1000)
    x, y = PLANE.to_plane(lat, lon)
    lat2, lon2 = PLANE.to_geodetic(x, y)
    x2, y2 = PLANE.to_plane(lat2, lon2)
    assert np.max(np.hypot(x2 - x, y2 - y)) < 1e-3
    # 1 mm is about 9e-9 degrees of latitude
    assert np.max(np.abs(lat2 - lat)) < 1e-8 and np.max(np.abs(lon2 - lon)) < 1.5e-8


def test_plane_axes_point_east_and_north():
    x, y = PLANE.to_plane(48.85, 2.45)
    assert x > 7000 and abs(y) < 100
    x, y = PLANE.to_plane(48.95, 2.35)
    assert y > 11000 and abs(x) < 1e-6


def test_distances_agree_with_geodesic_within_scale_error():
    """A plane distance lies within the projection's scale factors along the geodesic (pyproj)."""
    geod = Geod(ellps="WGS84")
    proj = Proj(PLANE.crs)
    rng = np.random.default_rng(1)
    for _ in range(100):
        lat1, lon1 = 48.85 + rng.uniform(-2, 2), 2.35 + rng.uniform(-3, 3)
        lat2, lon2 = lat1 + rng.uniform(-0.5, 0.5), lon1 + rng.uniform(-0.7, 0.7)
        _, _, s = geod.inv(lon1, lat1, lon2, lat2)
        pts = np.array([(lon1, lat1)] + geod.npts(lon1, lat1, lon2, lat2, 50) + [(lon2, lat2)])
        k = proj.get_factors(pts[:, 0], pts[:, 1]).meridional_scale
        (x1, x2), (y1, y2) = PLANE.to_plane([lat1, lat2], [lon1, lon2])
        ratio = math.hypot(x2 - x1, y2 - y1) / s
        # the chord is at most the projected geodesic (≤ k_max·s), and at least k_min·s less its sagitta
        assert k.min() - 1e-6 <= ratio <= k.max() + 1e-9


def test_polar_against_geodesic_and_locate_inverts():
    geod = Geod(ellps="WGS84")
    lat, lon, alt = np.array([48.9, 50.1, 49.0]), np.array([2.2, 4.9, 5.5]), np.array([10000.0, 3000.0, 150.0])
    rho, theta, elev = RADAR.polar(lat, lon, alt)
    az, _, s = geod.inv(np.full(3, RADAR.lon), np.full(3, RADAR.lat), lon, lat)
    # the geodesic azimuth matches the radar's azimuth (differences well under 1e-3 deg)
    assert np.max(np.abs((np.degrees(theta) - np.mod(az, 360) + 180) % 360 - 180)) < 2e-3
    # a target at the radar's height: the slant range is the chord 2(R+h)·sin(s/2R) of the geodesic
    R, h = 6.381e6, 150.0
    assert rho[2] == pytest.approx(2 * (R + h) * math.sin(s[2] / (2 * R)), abs=0.5)
    lat2, lon2, ok = RADAR.locate(rho, theta, alt)
    assert ok.all()
    np.testing.assert_allclose(lat2, lat, atol=1e-9)
    np.testing.assert_allclose(lon2, lon, atol=1e-9)


def test_locate_flags_impossible_geometry():
    _, _, ok = RADAR.locate(np.array([1000.0]), np.array([1.0]), np.array([10000.0]))
    assert not ok[0]


@settings(max_examples=60, deadline=None)
@given(rng_km=st.floats(5, 250), az=st.floats(0, 2 * math.pi - 1e-9), alt=st.floats(300, 12500))
def test_bias_jacobian_matches_finite_differences(rng_km, az, alt):
    """C_s = ∂p/∂(ρ, θ) of the exact model, by central differences, to 1e-3 relative."""
    rho = np.array([rng_km * 1e3])
    if rho[0] < alt * 1.2:
        return
    theta, h = np.array([az]), np.array([alt])
    p, ok = RADAR.to_plane(rho, theta, h)
    if not ok[0]:
        return
    J = RADAR.bias_jacobian(p, rho, h)[0]
    dr, da = 1.0, 1e-6
    fd_r = (RADAR.to_plane(rho + dr, theta, h)[0] - RADAR.to_plane(rho - dr, theta, h)[0])[0] / (2 * dr)
    fd_a = (RADAR.to_plane(rho, theta + da, h)[0] - RADAR.to_plane(rho, theta - da, h)[0])[0] / (2 * da)
    assert np.linalg.norm(J[:, 0] - fd_r) <= 1e-3 * np.linalg.norm(fd_r)
    assert np.linalg.norm(J[:, 1] - fd_a) <= 1e-3 * np.linalg.norm(fd_a)


def test_azimuth_column_sign_convention():
    """θ clockwise from north, x east, y north: a target due north moves east as θ grows."""
    rho, theta, h = np.array([100e3]), np.array([0.0]), np.array([9000.0])
    p, _ = RADAR.to_plane(rho, theta, h)
    J = RADAR.bias_jacobian(p, rho, h)[0]
    assert J[0, 1] > 0.9e5 and abs(J[1, 1]) < 0.05e5
    assert J[1, 0] > 0.99


def test_flat_earth_would_fake_a_range_bias():
    """DESIGN §3: at 150 km the flat-earth slant-to-ground conversion is off by ~100 m."""
    rho, theta, h = np.array([150e3]), np.array([1.0]), np.array([10000.0])
    p, _ = RADAR.to_plane(rho, theta, h)
    d_exact = np.linalg.norm(p[0] - RADAR.xy)
    d_flat = math.sqrt(rho[0] ** 2 - (h[0] - 150.0) ** 2)
    assert 50.0 < abs(d_exact - d_flat) < 500.0


def test_planes_sharing_a_centre_and_threads_give_pyproj_numbers():
    """SystemPlane's projection is made once per centre and shared (also between threads): the same numbers
    as a projection built here from the same definition, for two centres in turn."""
    from concurrent.futures import ThreadPoolExecutor

    from pyproj import CRS, Transformer

    rng = np.random.default_rng(3)
    for lat0, lon0 in ((48.85, 2.35), (44.0, -1.5), (48.85, 2.35)):
        crs = CRS.from_proj4(f"+proj=stere +lat_0={lat0} +lon_0={lon0} +k_0=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m")
        own = Transformer.from_crs("EPSG:4326", crs, always_xy=True)
        lat, lon = lat0 + rng.uniform(-2, 2, 50), lon0 + rng.uniform(-3, 3, 50)
        want = own.transform(lon, lat)
        plane = SystemPlane(lat0, lon0)
        with ThreadPoolExecutor(4) as pool:
            got = list(pool.map(lambda _: SystemPlane(lat0, lon0).to_plane(lat, lon), range(8)))
        for x, y in [plane.to_plane(lat, lon), *got]:
            assert np.array_equal(x, want[0]) and np.array_equal(y, want[1])


def test_radar_frame_makes_its_local_frame_on_first_use():
    from pyproj import Transformer

    frame = RadarFrame(45.2, 5.1, 320.0, PLANE)
    own = Transformer.from_pipeline("+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad +step +proj=cart "
                                    "+ellps=WGS84 +step +proj=topocentric +ellps=WGS84 +lat_0=45.2 +lon_0=5.1 "
                                    "+h_0=320.0")
    assert "_enu" not in vars(frame)
    lat, lon, alt = np.array([45.6, 44.9]), np.array([5.3, 4.8]), np.array([9000.0, 300.0])
    e, n, u = own.transform(lon, lat, alt)
    assert np.array_equal(frame.enu(lat, lon, alt), np.stack([e, n, u], axis=-1))

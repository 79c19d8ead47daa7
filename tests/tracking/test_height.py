"""The height of tracks without altitude (radartracker.tracking.height), held to independent oracles: ∂z/∂h
against finite differences of the exact conversion, the filter's height against a batch nonlinear least-squares
fit of the slant ranges and azimuths through pyproj's exact 3-D geometry, and its NEES against the χ²₁ band over
Monte Carlo runs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.stats import chi2

from radartracker.domain import Radar
from radartracker.geometry.plane import RadarFrame, SystemPlane, height_gradient
from radartracker.pipeline.stream import scenario_stream
from radartracker.registry import make_manager, restore_manager
from radartracker.simulation.scenarios import build_scenario
from radartracker.simulation.traffic import traffic_scenario
from radartracker.tracking.config import ManagerConfig
from radartracker.tracking.height import HeightConfig, HeightFilter, PlotRow, joint_heights
from radartracker.tracking.prepared import PlaneConverter

REF = (46.8, 8.2)
SIGMA_R, SIGMA_A = 50.0, math.radians(0.06)
SITES = [("A", 46.3, 7.4), ("B", 47.4, 8.3), ("C", 46.5, 9.2)]  # around the aircraft, 60–90 km away
H_TRUE, PRIOR_M, PRIOR_SD_M = 10_500.0, 6000.0, 3500.0


def _setup(sites=SITES):
    plane = SystemPlane(*REF)
    radars = [Radar(rid, lat, lon, 600.0, SIGMA_R, SIGMA_A, 10.0, 250e3) for rid, lat, lon in sites]
    frames = {r.id: RadarFrame(r.lat, r.lon, r.height_m, plane) for r in radars}
    return plane, radars, frames, PlaneConverter(radars, frames, plane)


def _plots(plane, radars, frames, rng, duration=120.0, biases=(0.0, 0.0, 0.0), start=(-20e3, 5e3), v=(220.0, 40.0),
           h_true=H_TRUE):
    """(time, radar row, ρ, θ) of a straight flight at ``h_true`` seen by every radar every 10 s (staggered),
    from exact polar geometry, with noise and the radars' range ``biases``."""
    out = []
    for k, r in enumerate(radars):
        for t in np.arange(3.0 * k, duration, r.period_s):
            p = np.array([start[0] + v[0] * t, start[1] + v[1] * t])
            lat, lon = plane.to_geodetic(p[0], p[1])
            rho, theta, _ = frames[r.id].polar(lat, lon, h_true)
            rho, theta = rho + biases[k] + rng.normal(0, SIGMA_R), theta + rng.normal(0, SIGMA_A)
            out.append((float(t), k, float(rho), float(theta)))
    return sorted(out)


def _row(conv, k, z, C, rho, h, sd_c):
    """The PlotRow of one plot of radar row ``k`` converted at height ``h`` ± ``sd_c`` (no azimuth bias), its
    second-order term with g₂ = −c/ρ (held to finite differences below)."""
    g2 = -C[0, :, 0] / rho[0]
    R = C[0] @ conv.W[k] @ C[0].T + 0.75 * sd_c**4 * np.outer(g2, g2)
    return PlotRow(z[0], R, height_gradient(C, rho, h, conv.height[[k]])[0], C[0, :, 0], float(h[0]))


def _run_filter(conv, plots, config, prior_m=PRIOR_M, prior_sd_m=PRIOR_SD_M, sd_b=1e-3):
    """A height filter fed every plot, each converted at the filter's own height (the prior, for the first);
    range biases 0 ± ``sd_b``."""
    filt = None
    for t, k, rho, theta in plots:
        h_c = prior_m if filt is None else float(filt.s[4])
        rows, r, a, h = np.array([k]), np.array([rho]), np.array([theta]), np.array([h_c])
        z, C, _, ok = conv.convert(rows, r, a, h)
        assert ok.all()
        row = _row(conv, k, z, C, r, h, prior_sd_m if filt is None else 0.0)
        if filt is None:
            filt = HeightFilter.start(t, row, k, sd_b, prior_m, prior_sd_m, config)
        else:
            filt.update(t, row, k, sd_b)
    return filt


def _heights(filters, sd_b=1e-3):
    """(ĥ, σ_h) of each filter from the joint solve over ``filters`` (three radars)."""
    return joint_heights(filters, 3, sd_b)[2]


def test_height_gradient_is_the_conversion_derivative():
    _, radars, _, conv = _setup()
    rows = np.array([0, 1, 2, 0])
    rho, theta, h = np.array([30e3, 90e3, 180e3, 240e3]), np.array([0.3, 2.0, 4.0, 5.5]), np.full(4, 9000.0)
    z, C, _, _ = conv.convert(rows, rho, theta, h)
    z1, *_ = conv.convert(rows, rho, theta, h + 0.5)
    z0, *_ = conv.convert(rows, rho, theta, h - 0.5)
    np.testing.assert_allclose(height_gradient(C, rho, h, conv.height[rows]), z1 - z0, rtol=5e-3, atol=1e-5)
    z2, *_ = conv.convert(rows, rho, theta, h + 200.0)
    z_2, *_ = conv.convert(rows, rho, theta, h - 200.0)
    np.testing.assert_allclose(-C[:, :, 0] / rho[:, None], (z2 - 2 * z + z_2) / 200.0**2, rtol=0.1)  # ∂²z/∂h²


def test_height_matches_batch_least_squares_over_exact_geometry():
    """No process noise: the filter (an extended Kalman filter re-linearised at each plot) ends where a batch
    fit of (x₀, y₀, vx, vy, h) to every plot's slant range and azimuth through pyproj's geometry does: started
    500 ± 600 m off; from the 4.5 ± 3.5 km of ``primary_altitude_m`` the first plots' linearisation costs up to
    about 1 σ."""
    plane, radars, frames, conv = _setup()
    plots = _plots(plane, radars, frames, np.random.default_rng(3))
    cfg = HeightConfig(q=0.0, q_height=0.0, prior_sd_velocity_mps=1e4)
    (h, sd), = _heights([_run_filter(conv, plots, cfg, H_TRUE - 500.0, 600.0)])
    (far, _), = _heights([_run_filter(conv, plots, cfg)])

    def residuals(v):
        out = []
        for t, k, rho, theta in plots:
            lat, lon = plane.to_geodetic(v[0] + v[2] * t, v[1] + v[3] * t)
            r, a, _ = frames[radars[k].id].polar(lat, lon, v[4])
            out += [(rho - r) / SIGMA_R, (math.remainder(theta - a, 2 * math.pi)) / SIGMA_A]
        return out + [(v[4] - (H_TRUE - 500.0)) / 600.0]  # the filter's prior on h

    fit = least_squares(residuals, [-20e3, 5e3, 200.0, 50.0, 8000.0], x_scale=[1e3, 1e3, 10, 10, 1e3])
    cov = np.linalg.inv(fit.jac.T @ fit.jac)
    assert abs(h - fit.x[4]) < 0.1 * math.sqrt(cov[4, 4])
    assert abs(far - fit.x[4]) < 1.5 * math.sqrt(cov[4, 4])
    assert sd == pytest.approx(math.sqrt(cov[4, 4]), rel=0.1)
    assert sd < 300.0  # three radars around the aircraft: observable


def test_one_radar_leaves_the_height_unobservable():
    plane, radars, frames, conv = _setup(SITES[:1])
    filt = _run_filter(conv, _plots(plane, radars, frames, np.random.default_rng(4)), HeightConfig(), sd_b=500.0)
    (_, sd), = joint_heights([filt], 1, 500.0)[2]
    assert sd > HeightConfig().observable_sd_m


# aircraft of one Monte Carlo run: start (m), velocity (m/s), height (m); the first is the one judged
FLEET = [((-20e3, 5e3), (220.0, 40.0), 10_500.0), ((30e3, -40e3), (-150.0, 180.0), 11_300.0),
         ((-50e3, -30e3), (200.0, -60.0), 9_400.0), ((10e3, 40e3), (-30.0, -230.0), 11_900.0),
         ((40e3, 20e3), (-210.0, -90.0), 10_100.0), ((-30e3, 45e3), (120.0, -170.0), 9_800.0)]


def _fly_fleet(conv, plots, n, config, sd_b, every=10.0):
    """As the manager does: the filters of ``n`` aircraft fed their plots ((time, aircraft, radar row, ρ, θ),
    in time order), each converted at its aircraft's height of the last joint solve (the prior before one),
    the joint solve every ``every`` seconds; the filters after a last solve."""
    filters: list = [None] * n
    boundary = every
    for t, i, k, rho, theta in plots:
        if t >= boundary and all(f is not None for f in filters):
            for f, (h, sd) in zip(filters, joint_heights(filters, 3, sd_b)[2]):
                f.fix = (h, sd, boundary)
            boundary += every
        f = filters[i]
        h_c = PRIOR_M if f is None or f.fix is None else f.height(t)[0]
        rows, r, a, h = np.array([k]), np.array([rho]), np.array([theta]), np.array([h_c])
        z, C, _, ok = conv.convert(rows, r, a, h)
        assert ok.all()
        row = _row(conv, k, z, C, r, h, PRIOR_SD_M if f is None or f.fix is None else f.height(t)[1])
        if f is None or (not f.settled and f.fix is not None):  # restarted once, converted at the first fix
            filters[i] = HeightFilter.start(t, row, k, sd_b, PRIOR_M, PRIOR_SD_M, config)
            if f is not None:
                filters[i].fix, filters[i].settled = f.fix, True
        else:
            f.update(t, row, k, sd_b)
    return filters


def _mean_nees(runs: int, seed: int, sd_bias: float, duration: float) -> float:
    """Mean NEES of the first aircraft's height over ``runs`` runs of :data:`FLEET` (known biases: one aircraft
    alone), each radar's range bias drawn N(0, ``sd_bias``²) and the filters told so; the filters without
    process noise, as the flights fly (:func:`_fly_fleet`)."""
    plane, radars, frames, conv = _setup()
    rng = np.random.default_rng(seed)
    nees = []
    for _ in range(runs):
        biases = rng.normal(0.0, sd_bias, 3) if sd_bias else np.zeros(3)
        fleet = FLEET if sd_bias else FLEET[:1]
        plots = sorted((t, i, k, rho, theta) for i, (p0, v, h) in enumerate(fleet)
                       for t, k, rho, theta in _plots(plane, radars, frames, rng, duration, biases, p0, v, h))
        filters = _fly_fleet(conv, plots, len(fleet), HeightConfig(q=0.0, q_height=0.0), sd_bias or 1e-3)
        (h, sd), *_ = joint_heights(filters, 3, sd_bias or 1e-3)[2]
        nees.append(((h - fleet[0][2]) / sd) ** 2)
    return float(np.mean(nees))


def _band(runs: int) -> tuple[float, float]:
    return chi2.ppf(0.025, runs) / runs, chi2.ppf(0.975, runs) / runs


@pytest.mark.parametrize("sd_bias", [0.0, 100.0])
def test_height_nees_inside_its_band_short(sd_bias):
    lo, hi = _band(20)
    assert lo <= _mean_nees(20, 11, sd_bias, 120.0) <= hi


@pytest.mark.slow
@pytest.mark.parametrize("sd_bias", [0.0, 100.0])
def test_height_nees_inside_its_band_monte_carlo(sd_bias):
    lo, hi = _band(100)
    assert lo <= _mean_nees(100, 12, sd_bias, 240.0) <= hi


def test_traffic_with_mode_c_is_unchanged():
    """Every plot with altitude: no height filter, the same events with the height stage on or off."""
    data = build_scenario("demo", seed=2, duration=90.0).run()
    assert np.isfinite(data.plots.altitude_m.astype(float)).all()
    runs = []
    for enabled in (True, False):
        mgr = make_manager(data.radars, data.reference, ManagerConfig(height=HeightConfig(enabled=enabled)))
        runs.append([(e.time, e.track, e.kind, e.state) for e in mgr.process_many(scenario_stream(data))])
        assert all(tr.height is None for tr in mgr.tracks.values())
    assert runs[0] == runs[1]


def test_heights_survive_a_snapshot(tmp_path):
    """Primary-only traffic under overlapping radars: tracks get heights, and a snapshot taken midway restores
    them, so the rest of the run gives the same events as without the interruption."""
    data = traffic_scenario(seed=3, duration=300.0, aircraft=20, radars=4, spacing_km=80.0, period_s=(8.0, 10.0),
                            altitude_m=(9000.0, 12000.0), speed_mps=(200.0, 250.0), adsb_share=0.0,
                            transponder="none").run()
    items = list(scenario_stream(data))
    half = len(items) // 2
    whole = make_manager(data.radars, data.reference, ManagerConfig())
    events = [(e.time, e.track, e.kind, e.state) for e in whole.process_many(items)]
    assert any(tr.height is not None and tr.altitude_m is not None for tr in whole.tracks.values())
    first = make_manager(data.radars, data.reference, ManagerConfig())
    head = [(e.time, e.track, e.kind, e.state) for item in items[:half] for e in first.process(item)]
    first.snapshot(tmp_path / "s.rtsnap")
    second = restore_manager(tmp_path / "s.rtsnap")
    tail = [(e.time, e.track, e.kind, e.state) for e in second.process_many(items[half:])]
    assert head + tail == events


def test_altitude_sd_is_the_height_sigma_or_the_quantisation(tmp_path):
    """A track's ``altitude_sd_m`` is the σ of its ``altitude_m``: an estimated height's σ_h of the last joint
    solve (at most ``observable_sd_m``), a reported altitude's quantisation step / √12 (100 ft Mode C, 25 ft
    ADS-B: the steps written here), none where there is no altitude; kept by a snapshot."""
    from radartracker.domain import AdsbReport, Plot
    from radartracker.tracking.track import Track

    data = traffic_scenario(seed=3, duration=240.0, aircraft=20, radars=4, spacing_km=80.0, period_s=(8.0, 10.0),
                            altitude_m=(9000.0, 12000.0), speed_mps=(200.0, 250.0), adsb_share=0.0,
                            transponder="none").run()
    mgr = make_manager(data.radars, data.reference, ManagerConfig())
    mgr.process_many(scenario_stream(data))
    tracks = list(mgr.tracks.values())
    estimated = [tr for tr in tracks if tr.height is not None and tr.altitude_m is not None]
    assert estimated and all(tr.altitude_sd_m == tr.height.fix[1] <= 1000.0 for tr in estimated)
    assert all((tr.altitude_m is None) == (tr.altitude_sd_m is None) for tr in tracks)
    mgr.snapshot(tmp_path / "s.rtsnap")
    restored = restore_manager(tmp_path / "s.rtsnap").tracks
    assert [restored[tr.id].altitude_sd_m for tr in tracks] == [tr.altitude_sd_m for tr in tracks]

    tr = Track(1, tracks[0].filter, "confirmed", 0.0, 0.0)
    tr.took(Plot(1.0, "R1", 5e4, 0.5, altitude_m=3048.0), "plots")
    assert tr.altitude_sd_m == pytest.approx(100 * 0.3048 / math.sqrt(12))
    tr.took(AdsbReport(2.0, "abc123", 48.0, 2.0, altitude_m=3050.0), "adsb")
    assert (tr.altitude_m, tr.altitude_sd_m) == (3050.0, pytest.approx(25 * 0.3048 / math.sqrt(12)))

"""Plots linearised at the bias estimate (radartracker.tracking.frame): exact conversion of the corrected
plot, and a radar with a 2 km / 2° bias estimated within 3σ (issue 30)."""

from __future__ import annotations

import math

import attrs
import numpy as np

from radartracker.domain import Plot
from radartracker.geometry.plane import RadarFrame
from radartracker.pipeline.stream import scenario_stream
from radartracker.registry import make_manager
from radartracker.simulation.scenarios import build_scenario
from radartracker.tracking.config import ManagerConfig
from radartracker.tracking.frame import FrameBuilder


def test_a_plot_corrected_by_the_estimate_is_the_plot_converted_without_its_bias():
    """With ς̂ = (Δr̂, Δθ̂) of each radar, z − C_s ς̂ is the plot at (ρ − Δr̂, θ − Δθ̂) converted by its radar's
    own RadarFrame, and C_s is that RadarFrame's Jacobian there (oracle: one plot at a time)."""
    data = build_scenario("paris", seed=2, duration=300.0).run()
    mgr = make_manager(data.radars, data.reference, ManagerConfig())
    estimate = {r.id: np.array([300.0 * (k + 1), math.radians(0.5 * (k + 1))]) for k, r in enumerate(data.radars)}
    builder = FrameBuilder(mgr.frames.converter, mgr.config.primary_altitude_m, mgr.config.primary_altitude_sd_m,
                           lambda rid: (estimate[rid], np.eye(2)))
    plots = [it for it in scenario_stream(data) if isinstance(it, Plot) and it.altitude_m is not None][:200]
    frame = builder.build(0.0, 1.0, plots, [])
    assert len(frame.plots) == 200
    for row, p in enumerate(frame.plots):
        r, b = mgr.radars[p.radar], estimate[p.radar]
        rf = RadarFrame(r.lat, r.lon, r.height_m, mgr.plane)
        rho, theta, alt = (np.array([v]) for v in (p.range_m - b[0], p.azimuth_rad - b[1], p.altitude_m))
        z, ok = rf.to_plane(rho, theta, alt)
        C = rf.bias_jacobian(z, rho, alt)[0]
        assert bool(ok[0]) == bool(frame.valid[row])
        np.testing.assert_allclose(frame.meas.C[row], C, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(frame.meas.z[row] - C @ b, z[0], rtol=0, atol=1e-6)
        np.testing.assert_allclose(frame.linearised_at[row], b, rtol=0, atol=0)


def test_a_two_kilometre_two_degree_bias_is_estimated_within_three_sigma():
    """One radar of `paris` given Δr = 2000 m, Δθ = 2°: the manager's estimate of it is within 3σ of the
    truth in range and azimuth (its reported σ against the simulated value), and the others' too."""
    sim = build_scenario("paris", seed=1, duration=400.0)
    sim.radars[0] = attrs.evolve(sim.radars[0], range_bias_m=2000.0, azimuth_bias_rad=math.radians(2.0))
    data = sim.run()
    mgr = make_manager(data.radars, data.reference, ManagerConfig())
    mgr.process_many(scenario_stream(data))
    for sr in sim.radars:
        state = mgr.estimator.bias(sr.radar.id)
        (dr, dth), P = np.asarray(state.bias, float)[:2], np.asarray(state.cov, float)
        z = ((dr - sr.range_bias_m) / math.sqrt(P[0, 0]), (dth - sr.azimuth_bias_rad) / math.sqrt(P[1, 1]))
        assert abs(z[0]) <= 3.0 and abs(z[1]) <= 3.0, (sr.radar.id, z)

"""Antenna phases and sweeps of the TrackManager (radartracker.tracking.coverage.AntennaSweep)."""

import math

import numpy as np

from radartracker.domain import Radar
from radartracker.tracking.coverage import AntennaSweep


def _radars(n, rng):
    return [Radar(f"r{k}", 48.0 + 0.3 * k, 2.0 + 0.2 * k, 100.0, 50.0, 1e-3, period_s=float(rng.uniform(4, 12)),
                  max_range_m=float(rng.uniform(1e5, 2.5e5))) for k in range(n)]


def test_phase_recurrence_is_the_python_loop():
    """observe() keeps p ← 0.98 p + exp(i(θ − 2πt/T)) per radar, in order (oracle: that loop)."""
    rng = np.random.default_rng(3)
    radars = _radars(5, rng)
    ant = AntennaSweep(radars, rng.normal(0, 1e5, (5, 2)), rng.normal(0, 0.01, 5))
    rows = rng.integers(0, 4, 200)  # radar 4 never plotted
    t, theta = np.sort(rng.uniform(0, 100, 200)), rng.uniform(0, 2 * np.pi, 200)
    want = [0j] * 5
    for r, tk, th in zip(rows, t, theta):
        want[r] = want[r] * 0.98 + complex(math.cos(th - 2 * math.pi * tk / radars[r].period_s),
                                           math.sin(th - 2 * math.pi * tk / radars[r].period_s))
    ant.observe(rows, t, theta)
    np.testing.assert_allclose(ant.phase, want, rtol=1e-12, atol=1e-12)
    assert ant.phased.tolist() == [True, True, True, True, False]


def test_sweep_is_the_geometry_written_out():
    """swept[r, i]: radar r has a phase, the track is within 0.98 of its range and its grid azimuth from
    north lies in the sector the antenna swept in [t_a, t_b); covered[i]: within some radar's range
    (oracle: numpy written from the definitions)."""
    rng = np.random.default_rng(5)
    radars = _radars(6, rng)
    xy, north = rng.normal(0, 1e5, (6, 2)), rng.normal(0, 0.02, 6)
    ant = AntennaSweep(radars, xy, north)
    ant.observe(np.arange(5), np.full(5, 3.0), rng.uniform(0, 2 * np.pi, 5))
    pos = rng.normal(0, 2e5, (400, 2))
    t_a, t_b = 10.0, 10.5
    swept, covered = ant.sweep(pos, t_a, t_b)
    for r, radar in enumerate(radars):
        d = pos - xy[r]
        rng_r = np.hypot(d[:, 0], d[:, 1])
        az = np.mod(np.arctan2(d[:, 0], d[:, 1]) - north[r], 2 * np.pi)
        start = np.angle(ant.phase[r]) + 2 * np.pi * t_a / radar.period_s
        want = (np.mod(az - start, 2 * np.pi) < 2 * np.pi * (t_b - t_a) / radar.period_s) & (rng_r < 0.98 * radar.max_range_m)
        assert swept[r].tolist() == (want & ant.phased[r]).tolist()
    want_cov = np.zeros(400, bool)
    for r, radar in enumerate(radars):
        want_cov |= np.hypot(*(pos - xy[r]).T) <= radar.max_range_m
    assert covered.tolist() == want_cov.tolist() and 0 < covered.sum() < 400 and swept.any()

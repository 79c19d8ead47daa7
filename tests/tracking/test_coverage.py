"""Antenna phases and sweeps of the TrackManager (radartracker.tracking.coverage.AntennaSweep)."""

import math

import numpy as np

from radartracker.domain import Radar
from radartracker.tracking.coverage import AntennaSweep


def _radars(n, rng):
    return [Radar(f"r{k}", 48.0 + 0.3 * k, 2.0 + 0.2 * k, 100.0, 50.0, 1e-3, period_s=float(rng.uniform(4, 12)),
                  max_range_m=float(rng.uniform(1e5, 2.5e5))) for k in range(n)]


def test_phase_recurrence_is_the_python_loop():
    """observe() keeps p ← 0.98 p + exp(i(θ − 2πt/T)) per radar, in order, with the lock's gate (oracle: that
    loop, written with angles)."""
    rng = np.random.default_rng(3)
    radars = _radars(5, rng)
    ant = AntennaSweep(radars, rng.normal(0, 1e5, (5, 2)), rng.normal(0, 0.01, 5))
    rows = rng.integers(0, 4, 200)  # radar 4 never plotted
    t, theta = np.sort(rng.uniform(0, 100, 200)), rng.uniform(0, 2 * np.pi, 200)
    want, last = [0j] * 5, [-math.inf] * 5
    for r, tk, th in zip(rows, t, theta):
        e = complex(math.cos(th - 2 * math.pi * tk / radars[r].period_s), math.sin(th - 2 * math.pi * tk / radars[r].period_s))
        if abs(want[r]) > 5 and math.cos(math.atan2(e.imag, e.real) - math.atan2(want[r].imag, want[r].real)) < math.cos(0.2):
            if tk - last[r] <= radars[r].period_s:
                continue  # a locked phase ignores a plot more than 0.2 rad away
            want[r] = 0j  # unless a revolution passed without an agreeing one
        want[r], last[r] = want[r] * 0.98 + e, tk
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


def _rotating(radar: Radar, phase: float, t: np.ndarray, rng) -> np.ndarray:
    """Azimuths of plots a rotating antenna of ``phase`` makes at times ``t`` (0.1° of noise)."""
    return (phase + 2 * np.pi * t / radar.period_s + rng.normal(0, np.radians(0.1), len(t))) % (2 * np.pi)


def test_a_flood_at_a_wrong_phase_leaves_a_locked_phase_alone():
    """A radar's plots lock its phase; a thousand plots at one time and another azimuth (a flood, a
    spoofer) do not move it, and the plots after them keep it (before, the flood took the estimate)."""
    rng = np.random.default_rng(8)
    radar = _radars(1, rng)[0]
    ant = AntennaSweep([radar], np.zeros((1, 2)), np.zeros(1))
    t = np.sort(rng.uniform(0, 120, 300))
    ant.observe(np.zeros(300, int), t, _rotating(radar, 1.0, t, rng))
    before = np.angle(ant.phase[0])
    ant.observe(np.zeros(1000, int), np.full(1000, 121.0), np.full(1000, 2.0))
    assert abs(np.angle(ant.phase[0]) - before) < 1e-12
    t2 = np.sort(rng.uniform(121, 130, 20))
    ant.observe(np.zeros(20, int), t2, _rotating(radar, 1.0, t2, rng))
    assert abs(np.angle(np.exp(1j * (np.angle(ant.phase[0]) - 1.0)))) < 0.01


def test_a_radar_whose_phase_changed_is_reacquired_after_a_revolution():
    """The antenna restarts with another phase: its plots disagree with the lock; after a whole revolution
    without an agreeing plot the estimate starts again and follows the new phase."""
    rng = np.random.default_rng(9)
    radar = _radars(1, rng)[0]
    ant = AntennaSweep([radar], np.zeros((1, 2)), np.zeros(1))
    t = np.sort(rng.uniform(0, 120, 300))
    ant.observe(np.zeros(300, int), t, _rotating(radar, 1.0, t, rng))
    t2 = np.sort(rng.uniform(121, 121 + 5 * radar.period_s, 100))
    ant.observe(np.zeros(100, int), t2, _rotating(radar, 3.0, t2, rng))
    assert abs(np.angle(np.exp(1j * (np.angle(ant.phase[0]) - 3.0)))) < 0.01

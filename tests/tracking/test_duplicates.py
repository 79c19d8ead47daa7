"""Two tracks on one aircraft: a lost track taken over by the younger track that found its aircraft,
under the older number; a twin of a healthy track dropped; different aircraft never merged."""

import math

import numpy as np
import pytest

from radartracker.domain import Aircraft, Radar
from radartracker.geometry.plane import SystemPlane
from radartracker.pipeline.stream import scenario_stream
from radartracker.registry import make_manager
from radartracker.simulation.simulator import RecordedTrajectory, SimAircraft, SimRadar, Simulator
from radartracker.tracking.config import ManagerConfig
from radartracker.tracking.duplicates import LOST, TWIN, relation
from radartracker.tracking.track import Track

REF = (48.0, 2.0)


def jumping_aircraft(jump_m: float, seed: int = 4):
    """One aircraft flying north at 230 m/s, 60 km east of a radar (4 s period), that steps ``jump_m``
    forward at t = 300 s (across the radar's line of sight, where no range bias can explain it): a path
    no filter follows, as stale positions in a recording make one. Its plots carry Mode C and nothing
    else, so only kinematics associate them."""
    plane = SystemPlane(*REF)
    lat, lon = plane.to_geodetic(0.0, 0.0)
    radar = Radar("R", float(lat), float(lon), 100.0, 40.0, math.radians(0.05), 4.0, 250e3)
    lat2, lon2 = plane.to_geodetic(120e3, 0.0)
    radar2 = Radar("S", float(lat2), float(lon2), 100.0, 40.0, math.radians(0.05), 5.0, 250e3)
    t = np.arange(0.0, 601.0, 1.0)
    x = np.full_like(t, 60e3)
    y = -60e3 + 230.0 * t + np.where(t >= 300.0, jump_m, 0.0)
    traj = RecordedTrajectory(t, x, y, np.full_like(t, 10000.0), smooth=False)
    ac = SimAircraft(Aircraft("3c0001", "JMP", None, transponder="mode_a_c"), traj)
    return Simulator(REF, [SimRadar(radar, pd=1.0), SimRadar(radar2, pd=1.0, phase_rad=2.0)], [ac], 0.0, 600.0,
                     seed=seed).run()


def run(data, **settings):
    mgr = make_manager(data.radars, data.reference, ManagerConfig(**settings))
    events = mgr.process_many(scenario_stream(data))
    return events, mgr.track_counts()


def test_a_lost_track_goes_on_under_its_number():
    data = jumping_aircraft(1500.0)
    events, counts = run(data)
    updated = {e.track for e in events if e.kind == "updated"}
    merged = [e for e in events if e.kind == "merged"]
    assert counts == {"tracks_merged_lost": 1} and len(merged) == 1 and merged[0].status == "deleted"
    assert len(updated) == 1  # one number from the first plot to the last
    (tid,) = updated
    assert max(e.time for e in events if e.kind == "updated" and e.track == tid) > 590.0
    # without merging (a distance no duplicate is ever within) the same plots give two numbers
    events, counts = run(data, merge_distance_m=1.0)
    assert not counts and len({e.track for e in events if e.kind == "updated"}) == 2


class _Filter:
    """A filter that holds one estimate (time, χ, P)."""

    def __init__(self, t, x, P):
        self.value = (t, np.asarray(x, float), np.asarray(P, float))

    def estimate(self):
        return self.value


def track(tid, x, *, t=100.0, sd=50.0, status="confirmed", created=0.0, last=100.0, **ident):
    P = np.diag([sd**2, sd**2, 10.0**2, 10.0**2])
    return Track(tid, _Filter(t, x, P), status, created, last, **ident)


def test_relation_lost_twin_or_none():
    new = track(9, [0.0, 0.0, 230.0, 0.0], created=90.0, status="tentative")
    # an older track without a measurement since the new one began, 1.2 km away, velocity 40 m/s off: lost
    # (the older tracks' estimates are at 85 s: x₀ = x(100 s) − 15 s · vx)
    assert relation(track(1, [-1800.0, -300.0, 200.0, 20.0], t=85.0, last=85.0, status="coasting"), new, 2500.0) == LOST
    assert relation(track(1, [-450.0, 0.0, 230.0, 0.0], t=85.0, last=85.0), new, 2500.0) is None  # 3 km: too far
    assert relation(track(1, [3950.0, 0.0, -230.0, 0.0], t=85.0, last=85.0), new, 2500.0) is None  # head-on
    # updated during the new track's life: one aircraft only when the states agree within their covariances
    assert relation(track(1, [40.0, -30.0, 232.0, 1.0]), new, 2500.0) == TWIN
    assert relation(track(1, [900.0, 0.0, 230.0, 0.0]), new, 2500.0) is None  # a second aircraft, 900 m on
    # identities that differ: never one aircraft
    lost = dict(t=85.0, last=85.0, status="coasting")
    assert relation(track(1, [-3350.0, 0.0, 230.0, 0.0], mode_3a="1234", **lost),
                    track(9, [0.0, 0.0, 230.0, 0.0], created=90.0, mode_3a="4321"), 2500.0) is None
    assert relation(track(1, [-3350.0, 0.0, 230.0, 0.0], altitude_m=10000.0, **lost),
                    track(9, [0.0, 0.0, 230.0, 0.0], created=90.0, altitude_m=10300.0), 2500.0) is None


def _turned(rate_deg_s: float, dt: float, v: float = 200.0) -> np.ndarray:
    """[x, y, vx, vy] after ``dt`` s of a turn at a constant rate from (0, 0) heading north at ``v``, by
    integrating the velocity in 10,000 steps (the oracle of the closed form in relation)."""
    w, h = math.radians(rate_deg_s), dt / 10_000
    heading = w * h * (np.arange(10_000) + 0.5)  # counterclockwise from north, at each step's middle
    return np.array([np.sum(-v * np.sin(heading)) * h, np.sum(v * np.cos(heading)) * h,
                     -v * math.sin(w * dt), v * math.cos(w * dt)])


@pytest.mark.parametrize("rate, expected", [(3.0, LOST), (-3.0, LOST), (1.2, LOST), (6.0, None)])
def test_a_track_lost_in_a_turn_is_found_where_the_turn_took_its_aircraft(rate, expected):
    """The aircraft turned at ``rate`` °/s for 26 s after its track's last update (78° at 3°/s: 4.1 km off the
    straight line); a turn faster than a standard rate's 3°/s is not assumed. After the 78° turn, the same place
    with the velocity mirrored (heading as if it had turned the other way: no turn gives both) is not its
    aircraft (after 31° at 1.2°/s the tolerances, 2.5 km and half the speed, cannot tell that from straight on)."""
    old = track(1, [0.0, 0.0, 0.0, 200.0], t=74.0, last=74.0, status="coasting")
    x = _turned(rate, 26.0)
    assert relation(old, track(9, x, created=90.0, status="tentative"), 2500.0) == expected
    if abs(rate) == 3.0:
        assert relation(old, track(9, [*x[:2], -x[2], x[3]], created=90.0, status="tentative"), 2500.0) is None


@pytest.mark.parametrize("jump_m", [4000.0])
def test_a_jump_beyond_the_merge_distance_is_a_new_track(jump_m):
    events, counts = run(jumping_aircraft(jump_m))
    assert not counts and len({e.track for e in events if e.kind == "updated"}) == 2

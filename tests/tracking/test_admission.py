"""Robust stream clock: a far-off time stamp is rejected and costs no good input (issue 12 §2)."""

import math
import statistics

import numpy as np
import pytest

from radartracker.registry import make_manager
from radartracker.domain import Plot
from radartracker.pipeline.stream import scenario_stream
from radartracker.clock import ClockConfig, StreamClock

YEARS_10 = 10 * 365.25 * 86400.0


def jittered_times(n: int = 400, seed: int = 0) -> np.ndarray:
    """A stream every 0.5 s with up to ±1 s of arrival jitter (out of order within the window)."""
    rng = np.random.default_rng(seed)
    return np.arange(n) * 0.5 + rng.uniform(-1.0, 1.0, n)


@pytest.mark.parametrize("ahead", [YEARS_10, 1800.0])
@pytest.mark.parametrize("where", [1, 3, 200])
def test_one_far_future_time_is_the_only_rejection(ahead, where):
    times = jittered_times()
    bad = times.copy()
    bad[where] += ahead
    clock = StreamClock()
    admitted = np.array([clock.admit(t) for t in bad])
    assert not admitted[where]
    assert admitted[np.arange(len(bad)) != where].all()


def test_clean_jittered_stream_fully_admitted():
    clock = StreamClock()
    assert all(clock.admit(t) for t in jittered_times())


def test_stream_resuming_after_a_pause_steps_after_a_few_inputs():
    cfg = ClockConfig()
    times = np.concatenate([np.arange(50.0), 5000.0 + np.arange(50.0)])
    clock = StreamClock(cfg)
    admitted = np.array([clock.admit(t) for t in times])
    # the price of a genuine step: step_after − 1 inputs; everything after it is admitted
    assert (~admitted).sum() == cfg.step_after - 1
    assert admitted[50 + cfg.step_after - 1:].all()


def test_a_source_with_a_wrong_clock_never_drags_the_stream():
    """Every third input 30 min ahead (one radar with a wrong clock): all of those are rejected,
    none of the good ones, because good inputs interleave and break every run."""
    t = np.arange(300) * 1.0
    wrong = np.arange(300) % 3 == 0
    t[wrong] += 1800.0
    clock = StreamClock()
    admitted = np.array([clock.admit(x) for x in t])
    assert admitted[~wrong].all()
    assert not admitted[wrong][1:].any()  # the very first input has nothing to be judged against


def test_non_finite_time_rejected():
    clock = StreamClock()
    assert clock.admit(0.0)
    assert not clock.admit(math.inf)
    assert not clock.admit(math.nan)


def test_state_dict_round_trip():
    a, b = StreamClock(), StreamClock()
    for t in jittered_times(30):
        a.admit(t)
    a.admit(1e9)
    b.load_state_dict(a.state_dict())
    assert [a.admit(t) for t in (20.0, 2e9, 2e9 + 1)] == [b.admit(t) for t in (20.0, 2e9, 2e9 + 1)]


class _RuleClock:
    """The rule of the module docstring taken literally: the median of the window for every input."""

    def __init__(self, cfg: ClockConfig) -> None:
        self.cfg, self.recent, self.run = cfg, [], []

    def admit(self, t: float) -> bool:
        if not math.isfinite(t):
            return False
        if not self.recent or t <= statistics.median_low(self.recent) + self.cfg.max_ahead_s:
            self.recent, self.run = (self.recent + [t])[-self.cfg.window:], []
            return True
        self.run = ([] if self.run and abs(t - self.run[0]) > self.cfg.max_ahead_s else self.run) + [t]
        if len(self.run) < self.cfg.step_after:
            return False
        self.recent, self.run = self.run[-self.cfg.window:], []
        return True


@pytest.mark.parametrize("seed", range(12))
def test_clock_decisions_are_those_of_the_median_rule(seed):
    """The clock admits most inputs on a lower bound of its window; every decision and the state must be
    those of taking the median each time (oracle above), on streams with jitter, backward times, far-off
    stamps, runs that step the clock, non-finite stamps and a state round trip halfway."""
    rng = np.random.default_rng(seed)
    cfg = ClockConfig(max_ahead_s=float(rng.choice([5.0, 300.0])), window=int(rng.integers(1, 12)),
                      step_after=int(rng.integers(1, 5)))
    # forwards or backwards in time (every input below the window's least time), from far before time 0
    noise = float(rng.choice([0.1, 8.0]))
    t = (seed % 2 * 2 - 1) * np.cumsum(rng.exponential(1.0, 3000)) + rng.uniform(-noise, noise, 3000) - 1e6
    far = rng.random(3000) < 0.05  # far off, and just within or beyond max_ahead_s of the others
    t[far] += rng.choice([-1e4, 1e4, 1e9, -1.0, 1.0, 0.3], far.sum()) + cfg.max_ahead_s * rng.choice([0.0, 1.0], far.sum())
    for start in rng.integers(0, 3000, 4):  # a recording resuming later: the whole stream steps
        t[start:] += 1e5
    t[rng.integers(0, 3000, 5)] = rng.choice([math.nan, math.inf, -math.inf], 5)
    clock, rule = StreamClock(cfg), _RuleClock(cfg)
    got, want = [], []
    for i, x in enumerate(t.tolist()):
        if i == 1500:
            clock2 = StreamClock(cfg)
            clock2.load_state_dict(clock.state_dict())
            clock = clock2
        got.append(clock.admit(x))
        want.append(rule.admit(x))
        assert clock.state_dict() == {"recent": rule.recent, "run": rule.run}
    assert got == want and 0 < sum(want) < len(want)


def _reference_release(times: list[float], window: float) -> tuple[list[int], int]:
    """The reordering rule taken literally: an input waits until the third newest time pushed (the stream's
    confirmed time) is ``window`` past it, inputs go in (time, arrival) order, and one at or before the last
    time gone is late. Arrival numbers in the order they go, and the number of late inputs."""
    waiting, gone, horizon, pushed, late = [], [], -math.inf, [], 0
    for k, t in enumerate(times):
        if t <= horizon:
            late += 1
            continue
        waiting = sorted(waiting + [(t, k)])
        pushed.append(t)
        confirmed = sorted(pushed)[-3] if len(pushed) >= 3 else -math.inf
        while waiting and waiting[0][0] <= confirmed - window:
            horizon, k_gone = waiting.pop(0)
            gone.append(k_gone)
    return gone + [k for _, k in waiting], late


@pytest.mark.parametrize("seed", range(4))
def test_manager_releases_in_time_then_arrival_order(demo_data, seed):
    """Most inputs come in order and wait in a queue, the others in a heap: the frames must get them in
    (time, arrival) order all the same, with many equal times, and late ones counted (oracle above)."""
    rng = np.random.default_rng(seed)
    n = 3000
    times = (np.round(np.arange(n) * 0.05 + rng.choice([0.0, 0.0, -1.0, -2.5], n) * rng.random(n), 1)).tolist()
    radar = demo_data.radars[0].id
    items = [Plot(t, radar, 1000.0 + k, 1.0) for k, t in enumerate(times)]  # distinct: no duplicates
    mgr = make_manager(demo_data.radars, demo_data.reference)
    got: list[Plot] = []

    def run_frame(frame: int) -> None:  # the frames' inputs as they are handed over, not tracked
        got.extend(mgr.gathered)
        mgr.gathered = []

    mgr._run_frame = run_frame
    for item in items:
        mgr.process(item)
    mgr.flush()
    want, late = _reference_release(times, mgr.config.reorder_window_s)
    assert [items[k] for k in want] == got
    assert mgr.counts.get("plots_late", 0) == late > 0
    assert len(got) + late == n


def _plots(demo_data, limit_s: float) -> list[Plot]:
    p = demo_data.plots
    out = [Plot(float(p.time[i]), p.radar[i], float(p.range_m[i]), float(p.azimuth_rad[i]),
                None if math.isnan(p.altitude_m[i]) else float(p.altitude_m[i]), p.mode_s[i], p.mode_3a[i])
           for i in range(len(p)) if p.time[i] < limit_s]
    return sorted(out, key=lambda x: x.time)


def _jitter(plots: list[Plot], seed: int) -> list[Plot]:
    """Arrival order shuffled by up to ±1 s (the manager's reorder window is 2 s)."""
    rng = np.random.default_rng(seed)
    keys = [p.time + rng.uniform(-1.0, 1.0) for p in plots]
    return [plots[i] for i in np.argsort(keys)]


@pytest.mark.parametrize("ahead", [YEARS_10, 1800.0])
def test_manager_far_future_plot_costs_no_good_input(demo_data, ahead):
    """Through the API: one plot 30 min (or 10 years) ahead in a jittered stream is counted as a time
    jump; every other plot is used exactly as in the run without it (oracle: that run)."""
    stream = _jitter(_plots(demo_data, 200.0), seed=4)
    k = len(stream) // 3
    bad = stream[:k] + [Plot(stream[k].time + ahead, stream[k].radar, stream[k].range_m, stream[k].azimuth_rad,
                             stream[k].altitude_m, stream[k].mode_s)] + stream[k:]

    def counts(items):
        mgr = make_manager(demo_data.radars, demo_data.reference)
        mgr.process_many(items)
        return mgr.accounting(), mgr

    clean, clean_mgr = counts(stream)
    dirty, dirty_mgr = counts(bad)
    assert dirty.pop("plots_time_jump") == 1
    assert dirty == clean
    for rid in demo_data.truth_biases:
        np.testing.assert_array_equal(dirty_mgr.estimator.bias(rid).bias, clean_mgr.estimator.bias(rid).bias)


def test_reader_skips_the_far_future_row_only(demo_data, tmp_path):
    """Reading with skip_bad: the one plot dated 10 years ahead is skipped as a time jump; none of the
    good rows after it becomes "time_backwards" (it made 355 of 371 of one radar's plots so)."""
    from radartracker.errors import FormatError
    from radartracker.io.scenario import read_scenario, write_scenario

    folder = tmp_path / "scenario"
    write_scenario(folder, demo_data)
    path = folder / "plots.csv"
    lines = path.read_text().splitlines()
    col = lines[0].split(",").index("time")
    k = len(lines) // 3
    fields = lines[k].split(",")
    fields[col] = repr(float(fields[col]) + YEARS_10)
    lines[k] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")
    data = read_scenario(folder, skip_bad=True)
    assert data.skipped == {"plots.csv:time_jump": 1}
    assert len(data.plots) == len(demo_data.plots) - 1
    with pytest.raises(FormatError, match=f"line {k + 1}.*time"):
        read_scenario(folder)


def test_labelled_replay_far_future_adsb_costs_no_good_input(demo_data):
    """The labelled path applies the same clock: one ADS-B report dated 10 years ahead is counted as a
    time jump and the biases are bit-equal to the run without it."""
    import attrs

    from radartracker.pipeline.config import RunConfig
    from radartracker.pipeline.run import run

    a = demo_data.adsb
    k = len(a) // 2
    t = a.time.copy()
    t[k] += YEARS_10
    dirty = attrs.evolve(demo_data, adsb=attrs.evolve(a, time=t))
    keep = np.arange(len(a)) != k
    clean = attrs.evolve(demo_data, adsb=attrs.evolve(a, **{f.name: getattr(a, f.name)[keep]
                                                          for f in attrs.fields(type(a))}))
    cfg = RunConfig(association="labels", estimator="coupled-sparse")
    res, ref = run(dirty, cfg, progress=False), run(clean, cfg, progress=False)
    assert res.counts.pop("adsb_time_jump") == 1
    assert res.counts == ref.counts
    for rid in demo_data.truth_biases:
        np.testing.assert_array_equal(res.final_biases[rid].bias, ref.final_biases[rid].bias)


def test_manager_time_jump_is_not_remembered_as_a_duplicate(demo_data):
    """A plot the stream clock rejects leaves no trace among the keys for duplicates: sent again later it
    is judged again (a time jump again), while an admitted plot sent again is a duplicate."""
    stream = _plots(demo_data, 100.0)
    k = len(stream) // 2
    p = stream[k]
    ahead = Plot(p.time + 1800.0, p.radar, p.range_m, p.azimuth_rad, p.altitude_m, p.mode_s)
    mgr = make_manager(demo_data.radars, demo_data.reference)
    mgr.process_many(stream[:k] + [ahead] + stream[k:k + 20] + [ahead, stream[k + 20]] + stream[k + 20:])
    assert mgr.counts["plots_time_jump"] == 2
    assert mgr.counts["plots_duplicate"] == 1


@pytest.mark.parametrize("pause_s", [400.0, 7200.0, 30 * 86400.0])
def test_a_pause_of_any_length_costs_no_input(demo_data, pause_s):
    """A recording that resumes after a pause (400 s, 2 h, a month): the inputs after it step the stream
    clock and are all admitted, the first ones held until then; nothing is counted as a time jump and the
    tracks after the pause are those of the same stream without the pause (oracle: that run, shifted)."""
    import attrs

    from radartracker.registry import make_manager

    items = scenario_stream(demo_data)
    half = len(items) // 2
    cut = items[half].time
    paused = items[:half] + [attrs.evolve(i, time=i.time + pause_s) for i in items[half:]]
    mgr = make_manager(demo_data.radars, demo_data.reference)
    events = mgr.process_many(paused)
    counts = mgr.accounting()
    assert not any(k.endswith("time_jump") for k in counts), counts
    assert sum(counts.values()) == len(items)
    after = [e for e in events if e.time > cut + pause_s and e.kind == "updated"]
    assert len(after) > 100 and len({e.track for e in after}) >= 6


def test_one_spoofed_time_stamp_is_held_then_counted_and_moves_nothing(demo_data):
    """One plot 20 minutes ahead among good ones (beyond the clock's 300 s): held while it could start a
    jump, counted as a time jump once the next good input shows it was alone; the events are those of the
    stream without it."""
    import attrs

    from radartracker.registry import make_manager

    items = scenario_stream(demo_data)[:3000]
    k = next(i for i, it in enumerate(items) if isinstance(it, Plot) and i > 1500)
    spoofed = items[:k] + [attrs.evolve(items[k], time=items[k].time + 1200.0)] + items[k + 1:]
    clean = items[:k] + items[k + 1:]
    a, b = make_manager(demo_data.radars, demo_data.reference), make_manager(demo_data.radars, demo_data.reference)
    assert a.process_many(spoofed) == b.process_many(clean)
    counts = a.accounting()
    assert counts.pop("plots_time_jump") == 1 and counts == b.accounting()


def _spoof_at(items: list, k: int, ahead: float) -> tuple[list, object]:
    import attrs

    spoof = attrs.evolve(items[k], time=items[k].time + ahead)
    return items[:k] + [spoof] + items[k + 1:], spoof


def test_a_lone_record_just_inside_the_clock_costs_only_itself(demo_data):
    """One plot 290 s ahead (inside the clock's 300 s, so admitted) in the middle of a jittered stream that
    goes on past its time: no good plot becomes late (it made 14–19 late in the service, issue 33), every
    other input is accounted exactly as in the stream without it, and the spoof is accounted once."""
    stream = _jitter(_plots(demo_data, 600.0), seed=5)
    k = next(i for i, p in enumerate(stream) if p.time > 150.0)
    dirty, _ = _spoof_at(stream, k, 290.0)
    clean = stream[:k] + stream[k + 1:]
    a, b = make_manager(demo_data.radars, demo_data.reference), make_manager(demo_data.radars, demo_data.reference)
    a.process_many(dirty)
    b.process_many(clean)
    got, want = a.accounting(), b.accounting()
    assert got.get("plots_late", 0) == want.get("plots_late", 0)
    assert sum(got.values()) == sum(want.values()) + 1
    assert len(a.confirmed_tracks()) == len(b.confirmed_tracks())


@pytest.mark.parametrize("end", [True, False])
def test_a_lone_record_ahead_at_the_end_never_advances_the_tracks(demo_data, end):
    """The stream ends (a recording, or a service's stop) with one plot 290 s ahead still waiting: the flush
    releases up to the stream's settled time only, so the events and tracks are those of the stream without
    it (before, the flush advanced time to the spoof and deleted every track). At the end of a recording it is
    counted a time jump; at a stop it stays waiting, in the snapshot, for the stream that resumes."""
    items = scenario_stream(demo_data)[:3000]
    k = next(i for i in range(len(items) - 1, 0, -1) if isinstance(items[i], Plot))
    dirty, spoof = _spoof_at(items, k, 290.0)
    clean = items[:k] + items[k + 1:]
    a, b = make_manager(demo_data.radars, demo_data.reference), make_manager(demo_data.radars, demo_data.reference)
    ev_a = [e for it in dirty for e in a.process(it)] + a.flush(end=end)
    ev_b = [e for it in clean for e in b.process(it)] + b.flush()
    assert ev_a == ev_b and not any(e.kind == "deleted" for e in ev_a[-50:])
    assert [t.id for t in a.confirmed_tracks()] == [t.id for t in b.confirmed_tracks()] != []
    got, want = a.accounting(), b.accounting()
    assert got.pop("plots_time_jump" if end else "waiting_in_reorder_window") == 1 and got == want


def _flood_run(demo_data, cfg, n: int):
    """A stream with ``n`` distinct plots at one time, 1 s ahead of it, in the middle: (manager, clean manager
    of the stream alone, the peak lengths of the window, of a frame and of the tracks, the number of inputs)."""
    from radartracker.tracking.config import ManagerConfig

    stream = _plots(demo_data, 300.0)
    k = next(i for i, p in enumerate(stream) if p.time > 100.0)
    rid = demo_data.radars[0].id
    flood = [Plot(stream[k].time + 1.0, rid, 20_000.0 + 3.0 * j, 4.0 + 1e-4 * j) for j in range(n)]
    mgr, clean = make_manager(demo_data.radars, demo_data.reference, cfg), make_manager(demo_data.radars, demo_data.reference)
    peak = {"window": 0, "frame": 0, "tracks": 0}
    for item in stream[:k] + flood + stream[k:]:
        mgr.process(item)
        for what, n in (("window", len(mgr.window)), ("frame", len(mgr.gathered)), ("tracks", len(mgr.tracks))):
            peak[what] = max(peak[what], n)
    mgr.flush()
    clean.process_many(stream)
    assert ManagerConfig().reorder_capacity == 100_000 and ManagerConfig().max_tracks == 10_000
    return mgr, clean, peak, len(stream) + len(flood)


def test_a_flood_sharing_one_time_stamp_is_bounded_and_costs_no_good_input(demo_data):
    """6,000 plots into a window and frames of 1,000 inputs: both stay within the bound; the full window
    drops its newest inputs (the flood's: ``plots_reorder_overflow``), so every good plot is used as without
    the flood and none is late (the flood, at a wrong antenna phase, does not move the radar's phase
    estimate either: before, it marked tracks missed and cost 6 good plots); every input is accounted for."""
    from radartracker.tracking.config import ManagerConfig

    mgr, clean, peak, n = _flood_run(demo_data, ManagerConfig(reorder_capacity=1000), 6_000)
    assert peak["window"] <= 1000 and peak["frame"] <= 1000
    counts, want = mgr.accounting(), clean.accounting()
    assert sum(counts.values()) == n
    assert counts.get("plots_late", 0) == want.get("plots_late", 0) and counts["plots_used"] == want["plots_used"]
    assert 5_000 <= counts["plots_reorder_overflow"] < 6_000


def test_a_flood_of_plausible_plots_is_bounded_by_the_track_capacity(demo_data):
    """The flood with room in the window but 300 tracks at most: the tracks never exceed it, the plots that
    would start one more are counted ``plots_track_capacity``, every input is accounted for."""
    from radartracker.tracking.config import ManagerConfig

    mgr, _, peak, n = _flood_run(demo_data, ManagerConfig(max_tracks=300), 6_000)
    assert peak["tracks"] <= 300
    counts = mgr.accounting()
    assert sum(counts.values()) == n and counts["plots_track_capacity"] > 5_000


@pytest.mark.parametrize("end", [True, False])
def test_three_records_an_hour_ahead_cost_no_good_input_and_no_track(demo_data, end):
    """Issue 33: three records 1 h ahead, one after the other, make a clock step (they look like a stream
    resuming after a pause), and the window followed them: every good input after them was late, and a stop
    advanced time an hour and deleted every track. Now they stop counting for the window once nine good
    inputs have come: the events are those of the stream without them, and at the end they are counted as
    time jumps (a recording) or stay waiting (a stop)."""
    import attrs

    items = scenario_stream(demo_data)[:3000]
    k = next(i for i, it in enumerate(items) if isinstance(it, Plot) and i > 1500)
    spoofs = [attrs.evolve(items[k], time=items[k].time + 3600.0 + j) for j in range(3)]
    a, b = make_manager(demo_data.radars, demo_data.reference), make_manager(demo_data.radars, demo_data.reference)
    ev_a = [e for it in items[:k] + spoofs + items[k:] for e in a.process(it)] + a.flush(end=end)
    ev_b = b.process_many(items)
    assert ev_a == ev_b and [t.id for t in a.confirmed_tracks()] == [t.id for t in b.confirmed_tracks()] != []
    got, want = a.accounting(), b.accounting()
    assert got.pop("plots_time_jump" if end else "waiting_in_reorder_window") == 3 and got == want

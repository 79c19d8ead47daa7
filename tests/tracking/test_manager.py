"""TrackManager against the simulation's truth: association, life cycle, accounting, robustness."""

import math
import random
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from radartracker.registry import make_manager
from radartracker.domain import AdsbReport, Plot
from radartracker.tracking.config import ManagerConfig
from radartracker.estimation.base import PlaneMeasurement
from radartracker.simulation.scenarios import build_scenario
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.run import run
from radartracker.pipeline.stream import scenario_stream


@pytest.fixture(scope="module")
def tracking_data():
    return build_scenario("tracking", seed=11, duration=900.0).run()


@pytest.fixture(scope="module")
def tracking_result(tracking_data):
    return run(tracking_data, RunConfig(association="manager", estimator="coupled"), progress=False)


def test_crossing_parallel_turns_false_plots(tracking_result, tracking_data):
    """Same-code crossing and 3 NM parallel pairs, a primary-only target, 3°/s turns, Pd 0.9,
    2 false plots per scan: no swap, no false confirmed track, continuity ≥ 99 %."""
    m = tracking_result.summary()["tracking"]
    assert len(m["per_target"]) == len(tracking_data.aircraft)
    assert m["swaps"] == 0
    assert m["false_tracks"] == 0
    assert m["confirmed_tracks"] == len(tracking_data.aircraft)
    assert m["continuity_min"] >= 0.99
    assert m["position_rmse_m"] < 300.0


def test_biases_estimated_while_tracking(tracking_result, tracking_data):
    for rid, b in tracking_result.summary()["biases"].items():
        true_r, true_a = tracking_data.truth_biases[rid]
        assert abs(b["range_bias_m"] - true_r) < 4 * b["sd_range_m"] + 1.0
        assert abs(math.radians(b["azimuth_bias_deg"]) - true_a) < 4 * math.radians(b["sd_azimuth_deg"]) + 1e-5


def test_every_input_accounted_for(tracking_result, tracking_data):
    counts = tracking_result.counts
    assert sum(counts.values()) == len(tracking_data.plots) + len(tracking_data.adsb)
    false_plots = sum(t is None for t in tracking_data.plots.target)
    assert counts["plots_in_dropped_tentative_tracks"] + counts.get("plots_in_tentative_tracks", 0) >= 0.9 * false_plots


def test_events_returned_and_called_back(tracking_data):
    seen = []
    mgr = make_manager(tracking_data.radars, tracking_data.reference, ManagerConfig(), on_event=seen.append)
    items = [i for i in scenario_stream(tracking_data) if i.time < 200]
    returned = mgr.process_many(items)
    assert returned == seen and {e.kind for e in returned} >= {"created", "confirmed", "updated", "deleted"}
    confirmed = {e.track for e in returned if e.kind == "confirmed"}
    assert all(any(e.track == t and e.kind == "created" for e in returned) for t in confirmed)


def test_out_of_order_within_window_late_and_duplicates(tracking_data):
    items = [i for i in scenario_stream(tracking_data) if i.time < 150]
    ref = make_manager(tracking_data.radars, tracking_data.reference)
    ref_events = ref.process_many(items)
    rng = random.Random(3)
    shuffled = sorted(items, key=lambda i: i.time + rng.uniform(-0.9, 0.9))  # within the 2 s window
    mgr = make_manager(tracking_data.radars, tracking_data.reference)
    assert mgr.process_many(shuffled) == ref_events
    late = Plot(10.0, "A", 50e3, 1.0)
    dup = items[-1]
    mgr2 = make_manager(tracking_data.radars, tracking_data.reference)
    for i in items:
        mgr2.process(i)
    mgr2.process(dup)
    mgr2.process(late)
    mgr2.flush()
    counts = mgr2.accounting()
    assert counts["plots_late"] == 1
    assert counts.get("plots_duplicate", 0) + counts.get("adsb_duplicate", 0) == 1
    assert sum(counts.values()) == len(items) + 2


def test_duplicates_caught_and_their_table_kept_small_on_a_long_stream():
    """Every input sent twice (the copy a second later, inside the reorder window) over a stream of
    >10 000 admission keys: each copy is counted a duplicate (oracle: the count sent), and the table of
    keys is swept of those before the horizon whenever it passes 10 000 (or twice what the window holds)."""
    from radartracker.simulation.traffic import traffic_scenario

    data = traffic_scenario(seed=3, duration=240.0, aircraft=100, radars=8).run()
    items = list(scenario_stream(data))
    assert len(items) > 10_000
    mgr = make_manager(data.radars, data.reference)
    copies, biggest = [], 0
    for i in items:
        while copies and copies[0].time <= i.time - 1.0:
            mgr.process(copies.pop(0))
        mgr.process(i)
        copies.append(i)
        biggest = max(biggest, len(mgr.admission.keys))
    for i in copies:
        mgr.process(i)
    mgr.flush()
    counts = mgr.accounting()
    assert counts.get("plots_duplicate", 0) + counts.get("adsb_duplicate", 0) == len(items)
    assert sum(counts.values()) == 2 * len(items)
    assert biggest <= 10_000  # swept as it passed 10 000 (the window holds a few hundred keys)


def test_snapshot_restore_in_a_fresh_process(tmp_path, tracking_data):
    """Half, snapshot, restore in a new interpreter, the rest == one uninterrupted replay (1e-12)."""
    from radartracker.io.scenario import write_scenario

    write_scenario(tmp_path / "scen", tracking_data)
    script = textwrap.dedent(f"""
        import pickle, sys
        from radartracker.io.scenario import read_scenario
        from radartracker.registry import make_manager, restore_manager
        from radartracker.tracking.config import ManagerConfig
        from radartracker.pipeline.stream import scenario_stream
        data = read_scenario({str(tmp_path / 'scen')!r})
        items = [i for i in scenario_stream(data) if i.time < 400]
        half = len(items) // 2
        if sys.argv[1] == "first":
            mgr = make_manager(data.radars, data.reference, ManagerConfig(estimator="coupled"))
            ev = [mgr.process(i) for i in items[:half]]
            mgr.snapshot({str(tmp_path / 'snap.pkl')!r})
        elif sys.argv[1] == "second":
            mgr = restore_manager({str(tmp_path / 'snap.pkl')!r})
            ev = [mgr.process(i) for i in items[half:]] + [mgr.flush()]
        else:
            mgr = make_manager(data.radars, data.reference, ManagerConfig(estimator="coupled"))
            ev = [mgr.process(i) for i in items] + [mgr.flush()]
        out = [e for batch in ev for e in batch]
        biases = {{r: (mgr.estimator.bias(r).bias.tolist(), mgr.estimator.bias(r).cov.tolist()) for r in mgr.estimator.radars}}
        pickle.dump((out, biases), open({str(tmp_path)!r} + "/" + sys.argv[1] + ".pkl", "wb"))
    """)
    (tmp_path / "run.py").write_text(script)
    for stage in ("first", "second", "whole"):
        subprocess.run([sys.executable, str(tmp_path / "run.py"), stage], check=True)
    import pickle

    first, _ = pickle.loads((tmp_path / "first.pkl").read_bytes())
    second, b_split = pickle.loads((tmp_path / "second.pkl").read_bytes())
    whole, b_whole = pickle.loads((tmp_path / "whole.pkl").read_bytes())
    split = first + second
    assert len(split) == len(whole) > 100
    for a, b in zip(split, whole):
        assert (a.time, a.track, a.kind, a.status) == (b.time, b.track, b.kind, b.status)
        np.testing.assert_allclose(a.state, b.state, rtol=1e-12, atol=1e-12)
    for r in b_whole:
        np.testing.assert_allclose(b_split[r][0], b_whole[r][0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(b_split[r][1], b_whole[r][1], rtol=1e-12, atol=1e-18)


def test_triangulated_position_feeds_a_track(tracking_data):
    """An unbiased position with covariance (e.g. a fix) is associated by gating and used."""
    items = [i for i in scenario_stream(tracking_data) if i.time < 120]
    mgr = make_manager(tracking_data.radars, tracking_data.reference)
    mgr.process_many(items)
    tr = next(t for t in mgr.tracks.values() if t.status == "confirmed" and t.mode_s is None)
    t0, x, _ = tr.filter.estimate()
    fix = PlaneMeasurement(t0 + 2.5, None, None, x[:2] + 2.5 * x[2:] + [30.0, -20.0], None, np.diag([900.0, 900.0]))
    before = tr.filter.estimate()[0]
    mgr.process(fix)
    mgr.flush()
    assert tr.filter.estimate()[0] > before
    assert mgr.accounting().get("positions_used") == 1


def _garbage():
    finite = st.floats(-1e6, 1e6, allow_nan=False)
    plot = st.builds(lambda t, r, rng, az, alt: (t, r, rng, az, alt),
                     st.one_of(st.floats(0, 600), st.just(1e300), st.floats(-1e9, 0)),
                     st.sampled_from(["A", "B", "Z", ""]), st.floats(0, 3e5), st.floats(0, 2 * math.pi - 1e-9),
                     st.one_of(st.none(), finite))
    other = st.one_of(st.none(), st.integers(), st.text(max_size=5), st.floats(allow_nan=True))
    return st.lists(st.one_of(plot, other), max_size=25)


@settings(max_examples=25, deadline=None)
@given(_garbage())
def test_garbage_never_corrupts_state(tracking_data, junk):
    items = [i for i in scenario_stream(tracking_data) if i.time < 60]
    mgr = make_manager(tracking_data.radars, tracking_data.reference, ManagerConfig(estimator="coupled"))
    stream = list(items)
    for k, g in enumerate(junk):
        if isinstance(g, tuple):
            try:
                g = Plot(*g)
            except ValueError:
                continue
        stream.insert((k * 7919) % (len(stream) + 1), g)
    for item in stream:
        mgr.process(item)
        for tr in mgr.tracks.values():
            _, x, P = tr.filter.estimate()
            assert np.all(np.isfinite(x)) and np.all(np.isfinite(P))
            np.testing.assert_allclose(P, P.T, rtol=1e-9, atol=1e-6)
            assert np.all(np.linalg.eigvalsh(0.5 * (P + P.T)) > 0)
    mgr.flush()
    for r in mgr.estimator.radars:
        b = mgr.estimator.bias(r)
        assert np.all(np.isfinite(b.bias)) and np.all(np.linalg.eigvalsh(b.cov) > 0)
    assert sum(mgr.accounting().values()) == sum(isinstance(i, (Plot, AdsbReport)) for i in stream) + sum(
        not isinstance(i, (Plot, AdsbReport)) for i in stream)


def test_the_estimator_feed_applies_its_operations_in_order_as_new_stacked_arrays():
    """Oracle: the operations queued, replayed by hand. Additions, each run of measurements (one
    update_many with np.array stacks of their z, C, R: new arrays, not the caller's) and removals reach the
    estimator in the order queued; the coupling graph and the counts follow."""
    from collections import Counter

    from radartracker.estimation.coupling import CouplingGraph
    from radartracker.tracking.feed import AddAircraft, EstimatorFeed, Measure, RemoveAircraft

    calls = []

    class Log:
        name = "log"

        def add_aircraft(self, key, time, x, P):
            calls.append(("add", key))

        def remove_aircraft(self, key):
            calls.append(("remove", key))

        def update_many(self, time, aircraft, radar, z, C, R):
            calls.append(("update", tuple(aircraft), z.copy(), C.copy(), R.copy(), z, C, R))

    rng = np.random.default_rng(5)
    z, C, R = rng.normal(size=(4, 2)), rng.normal(size=(4, 2, 2)), rng.normal(size=(4, 2, 2))
    counts = Counter()
    feed = EstimatorFeed(Log(), CouplingGraph(["a"]), counts, None)
    ops = [AddAircraft(0.0, 1, np.zeros(4), np.eye(4)), Measure(0.1, 1, "a", z[0], C[0], R[0], "plots"),
           Measure(0.2, 1, None, z[1], C[1], R[1], "adsb"), AddAircraft(0.3, 2, np.zeros(4), np.eye(4)),
           Measure(0.4, 2, "a", z[2], C[2], R[2], "plots"), RemoveAircraft(0.5, 1)]
    for op in ops:
        feed.add(op)
    feed.flush()
    assert [c[:2] for c in calls] == [("add", 1), ("update", (1, 1)), ("add", 2), ("update", (2,)), ("remove", 1)]
    for call, rows in ((calls[1], [0, 1]), (calls[3], [2])):
        for got, want, mine in zip(call[2:5], (z[rows], C[rows], R[rows]), (z, C, R)):
            np.testing.assert_array_equal(got, want)
        assert not any(np.shares_memory(a, b) for a in call[5:] for b in (z, C, R))
    assert counts == Counter({"plots_used": 2, "adsb_used": 1}) and feed.pending == []


def test_a_frames_estimator_work_comes_at_its_end_and_a_refused_measurement_costs_only_itself(tracking_data):
    """The bias estimate the manager reads is constant within a frame (the frame's measurements reach the
    estimator at its end, through update_many); a measurement the estimator refuses as
    singular in the middle of such a batch is counted once and the batch's later ones are still used."""
    from radartracker.estimation.kalman import SingularInnovation
    from radartracker_plugins.decoupled import DecoupledEstimator

    reads: dict[tuple[str, int], set] = {}
    received: list[float] = []

    class Spy(DecoupledEstimator):
        name = "spy"
        frame = None

        def bias(self, radar):
            b = super().bias(radar)
            reads.setdefault((radar, Spy.frame), set()).add((*b.bias.tolist(), *b.cov.ravel().tolist()))
            return b

        def update(self, m):
            if len(received) == 500:  # one refusal, inside some frame's batch
                received.append(math.nan)
                raise SingularInnovation("refused by the test")
            received.append(m.time)
            return super().update(m)

    mgr = make_manager(tracking_data.radars, tracking_data.reference, ManagerConfig(), estimator=Spy())
    run_frame = mgr._run_frame

    def spy_frame(frame):
        Spy.frame = frame
        run_frame(frame)

    mgr._run_frame = spy_frame
    items = [i for i in scenario_stream(tracking_data) if i.time < 300]
    mgr.process_many(items)
    assert len(received) > 900 and math.isnan(received[500])
    assert all(len(values) == 1 for values in reads.values())  # one bias value per radar and frame
    assert len({frame for _, frame in reads}) > 100
    counts = mgr.accounting()
    assert counts.get("plots_singular", 0) + counts.get("adsb_singular", 0) == 1
    used = sum(v for k, v in counts.items() if k.endswith("_used"))
    assert used == len(received) - 1  # everything after the refusal in its batch was applied
    assert sum(counts.values()) == len(items)


def test_the_frame_prediction_is_each_tracks_straight_line():
    """Prediction.position (all tracks at once) and Track.state_at (one track) are the one straight line
    p + v·max(t − t₀, 0) from each track's estimate (t₀, χ): computed here from estimate() itself."""
    from radartracker.tracking.frame import Prediction

    data = build_scenario("demo", seed=3, duration=60.0).run()
    mgr = make_manager(data.radars, data.reference)
    items = scenario_stream(data)
    for item in items[: len(items) // 2]:
        mgr.process(item)
    tracks = list(mgr.tracks.values())
    assert len(tracks) >= 3
    epochs = np.array([tr.estimate()[0] for tr in tracks])
    for t in (epochs.min() - 5.0, float(np.median(epochs)), epochs.max() + 7.5):
        want = np.array([x[:2] + x[2:4] * max(t - t0, 0.0) for t0, x, _ in (tr.estimate() for tr in tracks)])
        np.testing.assert_allclose(Prediction(tracks, t).position, want, rtol=1e-12)
        np.testing.assert_allclose([tr.state_at(t)[:2] for tr in tracks], want, rtol=1e-12)

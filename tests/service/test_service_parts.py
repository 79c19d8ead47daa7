"""The service's parts: time of day to absolute time, the decoder's accounting, the bounded queue,
checkpoints and resume, endpoints; and ``asterix-import --day-start``."""

from __future__ import annotations

import math
import queue
import socket
import time

import pytest

from radartracker.cli import main
from radartracker.errors import ConfigurationError
from radartracker.io.asterix import CAT048, CAT062, DAY, cat048_record, cat062_record, datablocks
from radartracker.io.asterix_reader import read_asterix
from radartracker.io.scenario import read_scenario, write_scenario
from radartracker.service import parse_endpoint
from radartracker.service.checkpoints import checkpoints, read_checkpoint, write_checkpoint
from radartracker.service.decoder import DayClock, Decoder, ReceiveClock
from radartracker.service.endpoints import open_receiver
from radartracker.service.receiver import Receiver
from radartracker.service.service import build_manager


def _local_service(tmp_path, **manager):
    """A Service of the built-in tracking scenario's radars on a loopback port, its state under ``tmp_path``:
    (service, config, endpoint)."""
    from radartracker.service import Service, ServiceConfig
    from radartracker.simulation.scenarios import build_scenario

    radars = build_scenario("tracking", seed=1, duration=60).run().radars
    ep = parse_endpoint("udp://127.0.0.1:0")
    cfg = ServiceConfig((ep,), parse_endpoint("udp://127.0.0.1:9"), tmp_path / "state", day_start=0.0)
    return Service(cfg, radars, {(0, 1): radars[0].id}, manager=manager or None), cfg, ep


@pytest.mark.parametrize("received, tod, expected", [
    (10 * DAY + 3600.0, 3599.5, 10 * DAY + 3599.5),          # same day
    (10 * DAY + 0.4, DAY - 0.3, 10 * DAY - 0.3),              # record just before midnight, received after
    (10 * DAY - 0.2, 0.1, 10 * DAY + 0.1),                    # receive clock a little behind the sensor's
])
def test_receive_clock_picks_the_nearest_day(received, tod, expected):
    assert ReceiveClock()(tod, received) == pytest.approx(expected, abs=1e-6)


def test_day_clock_adds_a_day_at_the_wrap():
    clock = DayClock(5 * DAY)
    assert [clock(t, 0.0) for t in (DAY - 2.0, DAY - 1.0, 0.5)] == [6 * DAY - 2.0, 6 * DAY - 1.0, 6 * DAY + 0.5]


def test_decoder_counts_every_datagram_and_record():
    good = next(datablocks(CAT048, [cat048_record(10.0, 0, 1, 50_000.0, 1.0, 9000.0, "abc123", "1234"),
                                    cat048_record(10.5, 0, 9, 60_000.0, 2.0)]))  # SIC 9: no such radar
    d = Decoder({(0, 1): "A"}, DayClock(0.0))
    items = d.decode(good, 0.0)
    assert len(items) == 1 and items[0].radar == "A" and items[0].mode_3a == "1234" and items[0].mode_s == "abc123"
    assert math.isclose(items[0].range_m, 50_000.0, abs_tol=1852 / 512)
    assert d.decode(good[:-3], 0.0) == []  # length field says more than there is
    other = next(datablocks(CAT062, [cat062_record(1.0, 0, 1, 1, 48.0, 2.0, 0.0, 0.0, 0.0, 0.0)]))
    assert d.decode(other + good, 0.0) == items  # two blocks in one datagram
    assert dict(d.counts) == {"datagrams_decoded": 2, "datagrams_malformed": 1, "cat048_records": 4,
                              "cat048_unknown_sac_sic": 2, "records_to_tracker": 2, "blocks_other_category": 1}


def test_full_queue_drops_are_counted_and_never_block_the_reader():
    ep = parse_endpoint("udp://127.0.0.1:0")
    sock = open_receiver(ep)
    port = sock.getsockname()[1]
    q: queue.Queue = queue.Queue(maxsize=3)
    rx = Receiver({ep: sock}, q)
    rx.start()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        for k in range(20):
            tx.sendto(bytes([k]), ("127.0.0.1", port))
    end = time.monotonic() + 30
    while rx.counts["datagrams_received"] < 20 and time.monotonic() < end:
        time.sleep(0.05)
    rx.stop()
    rx.join(5)
    sock.close()
    assert rx.counts["datagrams_received"] == 20 and rx.counts["datagrams_dropped_queue_full"] == 17
    assert [q.get_nowait()[3] for _ in range(3)] == [b"\x00", b"\x01", b"\x02"]  # the first ones kept, in order


def test_endpoints_are_checked():
    assert parse_endpoint("udp://239.1.2.3:8600").multicast
    assert not parse_endpoint("udp://127.0.0.1:8600").multicast
    for bad in ("tcp://127.0.0.1:1", "udp://127.0.0.1", "127.0.0.1:80", "udp://127.0.0.1:99999"):
        with pytest.raises(ConfigurationError):
            parse_endpoint(bad)


def test_checkpoints_are_whole_and_the_newest_two_kept(tmp_path):
    from radartracker.simulation.scenarios import build_scenario
    from radartracker.pipeline.stream import scenario_stream

    data = build_scenario("tracking", seed=1, duration=60).run()
    mgr = build_manager(data.radars)
    items = scenario_stream(data)
    for it in items[: len(items) // 2]:
        mgr.process(it)
    for seq in (1, 2, 3):
        write_checkpoint(tmp_path, seq, mgr, {"counts": {"records_to_tracker": seq}})
    (tmp_path / ".checkpoint-000004.partial").mkdir()  # a crash while writing the 4th
    assert [n for n, _ in checkpoints(tmp_path)] == [2, 3]
    back, state = read_checkpoint(checkpoints(tmp_path)[-1][1])
    assert state == {"counts": {"records_to_tracker": 3}}
    rest = items[len(items) // 2:]
    ev_a = [e for it in rest for e in mgr.process(it)] + mgr.flush()
    ev_b = [e for it in rest for e in back.process(it)] + back.flush()
    assert ev_a == ev_b and len(ev_a) > 0  # the restored manager continues exactly


def test_asterix_import_day_start(tmp_path, capsys):
    from radartracker.simulation.scenarios import build_scenario

    write_scenario(tmp_path / "sc", build_scenario("tracking", seed=1, duration=30).run())
    assert main(["asterix-export", str(tmp_path / "sc"), "--out", str(tmp_path / "r.ast")]) == 0
    assert main(["asterix-import", str(tmp_path / "r.ast"), "--out", str(tmp_path / "back"),
                 "--day-start", "2026-12-01"]) == 0
    day = 1_796_083_200.0  # 2026-12-01 00:00 UTC
    back, ref = read_scenario(tmp_path / "back"), read_asterix(tmp_path / "r.ast")
    assert back.plots.time == pytest.approx(ref.plots.time + day, abs=1e-3)
    assert any(a.mode_3a for a in back.aircraft)
    assert {a.icao24: a.mode_3a for a in back.aircraft} == {a.icao24: a.mode_3a for a in ref.aircraft}
    with pytest.raises(SystemExit):  # argparse: one line naming the option
        main(["asterix-import", str(tmp_path / "r.ast"), "--out", str(tmp_path / "x"), "--day-start", "tomorrow"])


@pytest.fixture(scope="module")
def replayed_records():
    """A replay of 15 minutes of traffic over 4 radars (its plane centred on the radars' mean position, as the
    service's) and its reported states as CAT062 records would carry them (positions as WGS-84), numbered by
    track id."""
    import attrs
    import numpy as np

    from radartracker.pipeline.config import RunConfig
    from radartracker.pipeline.run import run
    from radartracker.simulation.traffic import traffic_scenario

    data = traffic_scenario(seed=2, duration=900.0, aircraft=30, radars=4).run()  # aircraft come and go
    data = attrs.evolve(data, reference=(float(np.mean([r.lat for r in data.radars])),
                                         float(np.mean([r.lon for r in data.radars]))))
    res = run(data, RunConfig(association="manager"), progress=False)
    ev = res.events
    lat, lon = res.plane.to_geodetic(ev.state[:, 0], ev.state[:, 1])
    records = [{"sac": 0, "sic": 100, "track_number": int(ev.track[i]), "time": float(ev.time[i]),
                "x_m": ev.state[i, 0], "y_m": ev.state[i, 1], "vx_mps": ev.state[i, 2], "vy_mps": ev.state[i, 3],
                "lat": float(lat[i]), "lon": float(lon[i]), "ended": ev.kind[i] == "deleted"}
               for i in range(len(ev.time)) if ev.kind[i] in ("confirmed", "updated", "deleted")]
    return data, res, records


def _scores_as_replay(got: dict, expected: dict) -> None:
    assert got["positions"] == "I105 (WGS-84)"
    assert expected["confirmed_tracks"] > 0
    for key in ("continuity_min", "swaps", "breaks", "false_tracks", "confirmed_tracks", "position_rmse_m"):
        # positions go through WGS-84 and back (I105): micrometres
        assert got[key] == pytest.approx(expected[key], rel=1e-6), key


def test_cat062_scoring_is_the_replays_evaluation_of_the_same_states(replayed_records):
    """Records carrying a replay's reported states (positions as WGS-84) score as the replay evaluates itself."""
    from radartracker.service.score import score_cat062

    data, res, records = replayed_records
    _scores_as_replay(score_cat062(records, data), res.evaluation["tracking"])


def test_cat062_scoring_with_reused_track_numbers(replayed_records):
    """The same records numbered as a tracker with a pool of numbers does it (a deleted track's number goes back
    to the pool, a new track takes the lowest free one): one number names several tracks over the capture, and
    the score is still the replay's own evaluation (a number is a track only until its TSE record)."""
    from radartracker.service.score import score_cat062

    data, res, records = replayed_records
    number, free, renumbered = {}, [], []
    for r in records:
        if r["track_number"] not in number:
            number[r["track_number"]] = min(free) if free else len(number) + 1
            free = [n for n in free if n != number[r["track_number"]]]
        renumbered.append(r | {"track_number": number[r["track_number"]]})
        if r["ended"]:
            free.append(number[r["track_number"]])
    named = {}  # number → the tracks with updates under it
    for r, new in zip(records, renumbered):
        if not r["ended"]:
            named.setdefault(new["track_number"], set()).add(r["track_number"])
    assert max(len(v) for v in named.values()) >= 2  # a number named two confirmed tracks
    _scores_as_replay(score_cat062(renumbered, data), res.evaluation["tracking"])


@pytest.mark.parametrize("reference", ["centroid", "away"])
def test_score_command_scores_a_cat062_capture_as_the_replay_evaluates_itself(tmp_path, capsys, reference):
    """The replay's reported states written as CAT062 (its resolutions: 1/128 s, I105 180°/2²⁵, 0.5 m,
    0.25 m/s) and scored by ``radartracker score``: the replay's own evaluation, the RMSE within the
    quantisation, whether the replay's plane is the radars' centroid's or centred 1.5° away (issue 33:
    scoring I100 there gave 8 false tracks and 1 675 m on the demo)."""
    import json

    import attrs
    import numpy as np

    from radartracker.pipeline.config import RunConfig
    from radartracker.pipeline.run import run
    from radartracker.service.codec import blocks, cat062_bytes
    from radartracker.simulation.scenarios import build_scenario

    data = build_scenario("tracking", seed=3, duration=120).run()
    lat0, lon0 = float(np.mean([r.lat for r in data.radars])), float(np.mean([r.lon for r in data.radars]))
    data = attrs.evolve(data, reference=(lat0, lon0) if reference == "centroid" else (lat0 + 1.0, lon0 - 1.5))
    write_scenario(tmp_path / "sc", data)
    res = run(data, RunConfig(association="manager"), progress=False)
    ev = res.events
    lat, lon = res.plane.to_geodetic(ev.state[:, 0], ev.state[:, 1])
    recs = [cat062_bytes(float(ev.time[i]), 0, 100, int(ev.track[i]), float(lat[i]), float(lon[i]),
                         *map(float, ev.state[i]), ended=ev.kind[i] == "deleted")
            for i in range(len(ev.time)) if ev.kind[i] in ("confirmed", "updated", "deleted")]
    (tmp_path / "out.ast").write_bytes(b"".join(blocks(62, recs, 1472)))
    assert main(["score", str(tmp_path / "out.ast"), "--scenario", str(tmp_path / "sc")]) == 0
    got = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    expected = res.evaluation["tracking"]
    assert got["records"] == len(recs) and expected["confirmed_tracks"] > 0
    for key in ("swaps", "breaks", "false_tracks", "confirmed_tracks"):
        assert got[key] == expected[key], key
    assert got["continuity_min"] == pytest.approx(expected["continuity_min"], abs=0.02)
    assert got["position_rmse_m"] == pytest.approx(expected["position_rmse_m"], rel=0.01)
    assert got["positions"] == "I105 (WGS-84)"
    (tmp_path / "empty.ast").write_bytes(b"")
    assert main(["score", str(tmp_path / "empty.ast"), "--scenario", str(tmp_path / "sc")]) == 2


def test_a_capture_without_i105_is_refused():
    """Updates with only I100 plane positions cannot be placed: the capture does not name its plane."""
    from radartracker.errors import InputError
    from radartracker.geometry.plane import SystemPlane
    from radartracker.service.score import placed

    rec = {"track_number": 1, "time": 0.0, "x_m": 0.0, "y_m": 0.0, "vx_mps": 0.0, "vy_mps": 0.0, "ended": False}
    with pytest.raises(InputError, match="1 of 2 CAT062 track updates have no I105"):
        placed([rec | {"lat": 48.0, "lon": 2.0}, rec | {"lat": None, "lon": None}], SystemPlane(48.0, 2.0))
    ended = rec | {"lat": None, "lon": None, "ended": True}  # a track end needs no position
    assert placed([ended], SystemPlane(48.0, 2.0)) == [ended]


def test_lateness_histogram_counts_how_out_of_order_records_arrive(tmp_path):
    """Records at 10, 12, 11, 13, 9.5 s arrive 0, 0, 1, 0, 3.5 s behind the newest before them; with a
    0.5 s window the tracker has released up to 10.5 s (the third newest time less the window) when 9.5
    arrives, so that one alone is late."""

    svc, cfg, ep = _local_service(tmp_path, reorder_window_s=0.5)
    try:
        for t in (10.0, 12.0, 11.0, 13.0, 9.5):
            svc._handle(time.time(), time.monotonic(), ep,
                        next(datablocks(CAT048, [cat048_record(t, 0, 1, 50_000.0, 1.0)])))
    finally:
        for sock in [*svc.sockets.values(), svc.publisher.sock]:
            sock.close()
    sample = svc.metrics.registry.get_sample_value
    assert sample("radartracker_input_lateness_seconds_count") == 5
    assert sample("radartracker_input_lateness_seconds_sum") == pytest.approx(4.5)
    assert sample("radartracker_input_lateness_seconds_bucket", {"le": "0.0"}) == 3
    assert sample("radartracker_input_lateness_seconds_bucket", {"le": "1.0"}) == 4
    assert svc.manager.accounting().get("plots_late") == 1
    assert svc.decoder.counts["records_to_tracker"] == 5


def test_send_goes_on_when_nobody_listens(tmp_path, capsys):
    """To a loopback port with no listener each datagram draws "port unreachable", which the kernel
    reports on the next send: those are counted as refused and sending goes on to the end."""
    import json

    recs = [cat048_record(10.0 + k, 0, 1, 50_000.0, 1.0) for k in range(6)]
    (tmp_path / "r.ast").write_bytes(b"".join(next(datablocks(CAT048, [r])) for r in recs))
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    assert main(["send", str(tmp_path / "r.ast"), "--to", f"udp://127.0.0.1:{port}", "--speed", "0"]) == 0
    sent = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert sent["datagrams"] + sent["datagrams_refused"] == 6 and sent["datagrams_refused"] > 0
    assert sent["records"] == sent["datagrams"]  # one record each: refused ones are not counted as sent


def test_a_damaged_newest_checkpoint_falls_back_to_the_older_one(tmp_path):
    """Issue 33: one flipped bit in the newest snapshot, or a damaged service.json, stopped every restart
    although the older checkpoint was intact. resume() skips what does not read back, naming it, and
    takes the newest whole one; leftovers of failed writes go; numbering goes past 999 999."""
    from radartracker.pipeline.stream import scenario_stream
    from radartracker.service.checkpoints import resume
    from radartracker.simulation.scenarios import build_scenario

    data = build_scenario("tracking", seed=1, duration=40).run()
    mgr = build_manager(data.radars)
    for it in scenario_stream(data)[:300]:
        mgr.process(it)
    write_checkpoint(tmp_path, 999_999, mgr, {"counts": {"records_to_tracker": 1}})
    newest = write_checkpoint(tmp_path, 1_000_000, mgr, {"counts": {"records_to_tracker": 2}})
    assert [n for n, _ in checkpoints(tmp_path)] == [999_999, 1_000_000]  # ordered as numbers
    snap = newest / "manager.snapshot"
    body = bytearray(snap.read_bytes())
    body[len(body) // 2] ^= 0x10
    snap.write_bytes(bytes(body))
    (tmp_path / ".checkpoint-1000001.partial").mkdir()
    found, skipped = resume(tmp_path)
    assert found[0] == 999_999 and found[3] == {"counts": {"records_to_tracker": 1}}
    assert len(skipped) == 1 and skipped[0].startswith("checkpoint-1000000:")
    assert not (tmp_path / ".checkpoint-1000001.partial").exists()
    older = checkpoints(tmp_path)[0][1] / "service.json"
    for bad in ('{"counts": {"records_to_tracker": 1', '{"written": 1}', '{"counts": {"records": "7"}}',
                '{"counts": {"records": -1}}', '[]', ''):
        older.write_text(bad)
        found, skipped = resume(tmp_path)
        assert found is None and len(skipped) == 2 and "service.json" in skipped[1], (bad, skipped)


def test_a_failed_checkpoint_write_leaves_no_partial_folder(tmp_path, monkeypatch):
    from radartracker.service import checkpoints as ck
    from radartracker.simulation.scenarios import build_scenario

    mgr = build_manager(build_scenario("tracking", seed=1, duration=10).run().radars)

    def full_disk(*_a, **_k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(ck, "write_json_atomic", full_disk)
    with pytest.raises(OSError):
        write_checkpoint(tmp_path, 1, mgr, {"counts": {}})
    assert list(tmp_path.iterdir()) == []


def test_a_stop_drains_for_a_bounded_time_and_counts_the_rest(tmp_path, monkeypatch):
    """Issue 33: SIGTERM after a flood drained the whole queue (273 s) before the final checkpoint. The
    stop now processes the backlog for STOP_DRAIN_S, drops and counts the rest, and still writes the
    final checkpoint; the datagram accounting balances."""
    import threading

    from radartracker.service import service as service_module

    svc, cfg, ep = _local_service(tmp_path, reorder_window_s=0.5)
    block = next(datablocks(CAT048, [cat048_record(10.0, 0, 1, 50_000.0, 1.0)]))
    for _ in range(500):
        svc.queue.put((time.time(), time.monotonic(), ep, block))
    monkeypatch.setattr(service_module, "STOP_DRAIN_S", 0.0)  # a backlog that cannot be drained in time
    stop = threading.Event()
    stop.set()
    started = time.monotonic()
    summary = svc.run(stop)
    assert time.monotonic() - started < 30.0
    dg = summary["datagrams"]
    assert dg["dropped_at_stop"] == 500 and dg.get("decoded", 0) == 0
    assert svc._counts(False)["datagrams_received"] == 500  # every datagram processed or counted
    assert (cfg.state_dir / summary["last_checkpoint"] / "manager.snapshot").is_file()


def test_a_stop_looks_at_its_deadline_after_each_datagram(tmp_path, monkeypatch):
    """The drain's deadline was looked at after batches of 64 datagrams: under a flood of new tracks one batch
    took 16 s and the stop 33 s. Each datagram here takes 50 ms: a 0.3 s drain handles a handful, not 64."""
    import threading

    from radartracker.service import service as service_module

    svc, cfg, ep = _local_service(tmp_path, reorder_window_s=0.5)
    block = next(datablocks(CAT048, [cat048_record(10.0, 0, 1, 50_000.0, 1.0)]))
    for _ in range(200):
        svc.queue.put((time.time(), time.monotonic(), ep, block))
    handle = svc._handle
    monkeypatch.setattr(svc, "_handle", lambda *entry: (time.sleep(0.05), handle(*entry)))
    monkeypatch.setattr(service_module, "STOP_DRAIN_S", 0.3)
    stop = threading.Event()
    stop.set()
    summary = svc.run(stop)
    dg = summary["datagrams"]
    assert 1 <= dg["decoded"] <= 10 and dg["decoded"] + dg["dropped_at_stop"] == 200
    assert summary["stop_s"]["drain"] < 1.0


def test_a_checkpoint_still_being_written_at_the_stop_is_superseded(tmp_path):
    """The final checkpoint waited for the periodic one being written by a child process (seconds under
    load, past systemd's stop timeout); that child is now ended, its partial folder removed and the
    final checkpoint written whole."""
    import os
    import threading


    svc, cfg, ep = _local_service(tmp_path)
    svc.checkpoint_seq += 1  # a periodic checkpoint being written: its partial folder and a child that takes long
    partial = cfg.state_dir / f".checkpoint-{svc.checkpoint_seq:06d}.partial"
    partial.mkdir(parents=True)
    pid = os.fork()
    if pid == 0:
        time.sleep(60)
        os._exit(0)
    svc._child, svc._child_started = pid, time.monotonic()
    stop = threading.Event()
    stop.set()
    started = time.monotonic()
    summary = svc.run(stop)
    assert time.monotonic() - started < 20.0
    assert summary["checkpoints"].get("superseded") == 1 and not partial.exists()
    assert (cfg.state_dir / summary["last_checkpoint"] / "manager.snapshot").is_file()
    assert summary["last_checkpoint"] == f"checkpoint-{svc.checkpoint_seq:06d}"


def test_a_full_disk_degrades_the_service_instead_of_stopping_it(tmp_path, monkeypatch):
    """Issue 33: the first publication's biases.json write raised on a full disk and the service exited.
    Now the write is counted as failed, /health says "degraded" with the reason, CAT062 goes on, and the
    status is ok again once a write succeeds; a final checkpoint that cannot be written leaves the
    previous one standing and the summary is still returned."""
    import threading

    from radartracker.service import checkpoints as ck
    from radartracker.service import service as service_module

    svc, cfg, ep = _local_service(tmp_path)
    write = service_module.write_json_atomic

    def full_disk(*_a, **_k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(service_module, "write_json_atomic", full_disk)
    monkeypatch.setattr(ck, "write_json_atomic", full_disk)
    svc._publish()
    health = svc.health()
    assert health["status"] == "degraded" and "biases.json" in health["reason"]
    assert svc.publisher.counts.get("publications", 0) >= 1  # CAT062 went out
    stop = threading.Event()
    stop.set()
    summary = svc.run(stop)  # the final checkpoint and summary.json fail too: counted, no exception
    assert summary["checkpoints"]["failed"] == 1 and not list(cfg.state_dir.glob("checkpoint-*"))
    assert svc._counts(True)["state_writes_failed"] >= 2
    monkeypatch.setattr(service_module, "write_json_atomic", write)
    svc._write_state("biases.json", {})
    assert svc.health()["status"] == "ok"


def test_the_http_endpoint_holds_against_half_sent_requests(monkeypatch):
    """Issue 33: 3 000 half-sent requests made 3 000 threads. Now a few pooled threads serve (100 half-sent
    requests here), a silent
    connection is closed after the timeout, connections beyond the pending bound are closed at once,
    and /health still answers."""
    import json
    import threading
    import urllib.request

    from radartracker.service import http as http_module

    monkeypatch.setattr(http_module, "TIMEOUT_S", 0.25)

    class Fake:
        def health(self):
            return {"status": "ok"}

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = http_module.serve_http(Fake(), "127.0.0.1", port)
    before = threading.active_count()
    clients = []
    try:
        for _ in range(100):
            c = socket.create_connection(("127.0.0.1", port), timeout=5)
            c.sendall(b"GET /health HTTP/1.1\r\nHost: x\r\n")  # never finished
            clients.append(c)
        time.sleep(0.5)
        assert threading.active_count() <= before + http_module.WORKERS
        deadline = time.monotonic() + 60
        while True:  # the pool works through the silent ones, a timeout each, then answers
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=10) as r:
                    assert json.loads(r.read()) == {"status": "ok"}
                break
            except OSError:
                assert time.monotonic() < deadline
    finally:
        for c in clients:
            c.close()
        server.shutdown()
        server.server_close()


def test_http_connections_beyond_the_pending_bound_are_closed_at_once():
    from http.server import BaseHTTPRequestHandler

    from radartracker.service.http import MAX_PENDING, PooledHTTPServer

    server = PooledHTTPServer(("127.0.0.1", 0), BaseHTTPRequestHandler)
    try:
        for _ in range(MAX_PENDING):  # every pending slot taken
            server.pending.acquire()
        a, b = socket.socketpair()
        server.process_request(a, ("127.0.0.1", 0))
        assert server.refused == 1 and a.fileno() == -1 and b.recv(1) == b""
        b.close()
    finally:
        server.server_close()


def test_the_datagram_queue_is_bounded_in_bytes_as_well():
    """Issue 33: a queue bounded only in datagrams held 3.5 GB of 64 kB datagrams. A put beyond the byte
    bound is refused (the receiver counts it dropped_queue_full) and a take gives the bytes back."""
    from radartracker.service.receiver import DatagramQueue

    q = DatagramQueue(100, 1000)
    entry = (0.0, 0.0, None, b"x" * 600)
    q.put_nowait(entry)
    with pytest.raises(queue.Full):
        q.put_nowait(entry)
    assert q.bytes == 600
    assert q.get_nowait() is entry and q.bytes == 0
    q.put_nowait(entry)
    q.put_nowait((0.0, 0.0, None, b"y" * 400))
    assert q.bytes == 1000 and q.qsize() == 2


def test_a_receiver_counts_datagrams_the_byte_bound_refuses():
    from radartracker.service.receiver import DatagramQueue, Receiver

    rx_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx_sock.bind(("127.0.0.1", 0))
    rx_sock.setblocking(False)
    ep = parse_endpoint(f"udp://127.0.0.1:{rx_sock.getsockname()[1]}")
    q = DatagramQueue(1000, 3 * 1000)
    rx = Receiver({ep: rx_sock}, q)
    rx.start()
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
            for _ in range(10):
                tx.sendto(b"z" * 1000, rx_sock.getsockname())
        deadline = time.monotonic() + 10
        while rx.counts["datagrams_received"] < 10 and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        rx.stop()
        rx.join()
        rx_sock.close()
    assert rx.counts["datagrams_received"] == 10 and q.qsize() == 3 and q.bytes == 3000
    assert rx.counts["datagrams_dropped_queue_full"] == 7


def test_a_receiver_takes_only_the_allowed_senders():
    """Issue 33, a source filter: with --allow-from 127.0.0.2 a datagram from 127.0.0.2 is queued and one from
    127.0.0.1 is refused and counted (both received); a stop counts what is still in the socket's buffer."""
    from radartracker.service.receiver import DatagramQueue, Receiver

    rx_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx_sock.bind(("127.0.0.1", 0))
    rx_sock.setblocking(False)
    ep = parse_endpoint(f"udp://127.0.0.1:{rx_sock.getsockname()[1]}")
    q = DatagramQueue(1000, 1 << 20)
    rx = Receiver({ep: rx_sock}, q, frozenset({"127.0.0.2"}))
    rx.start()
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as a, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as b:
            b.bind(("127.0.0.2", 0))
            a.sendto(b"anyone", rx_sock.getsockname())
            b.sendto(b"allowed", rx_sock.getsockname())
            deadline = time.monotonic() + 10
            while rx.counts["datagrams_received"] < 2 and time.monotonic() < deadline:
                time.sleep(0.01)
        rx.stop()
        rx.join()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as a:
            a.sendto(b"late", rx_sock.getsockname())
        time.sleep(0.1)
        assert rx.discard_unread() == 1
    finally:
        rx.stop()
        rx.join()
        rx_sock.close()
    assert rx.counts["datagrams_received"] == 2 and rx.counts["datagrams_refused_sender"] == 1
    assert [e[3] for e in list(q.queue)] == [b"allowed"]


def test_allow_from_takes_ipv4_addresses_only(tmp_path):
    from radartracker.service import ServiceConfig

    ep = parse_endpoint("udp://127.0.0.1:0")
    assert ServiceConfig((ep,), ep, tmp_path, allow_from=["10.0.0.1"]).allow_from == ("10.0.0.1",)
    with pytest.raises(ValueError, match="allow_from"):
        ServiceConfig((ep,), ep, tmp_path, allow_from=["radar-1"])


def test_a_multicast_listener_takes_only_its_group():
    """Issue 33: a multicast --listen bound 0.0.0.0:port and decoded unicast datagrams from anyone. Bound
    to the group, it receives what is sent to the group and not what is sent to the port directly."""
    from radartracker.service.endpoints import open_receiver, open_sender

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    ep = parse_endpoint(f"udp://239.255.77.1:{port}")
    rx = open_receiver(ep, "127.0.0.1")
    try:
        with open_sender(ep, interface="127.0.0.1") as tx, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as uni:
            uni.sendto(b"unicast", ("127.0.0.1", port))
            tx.send(b"group")
            got, deadline = [], time.monotonic() + 5
            while time.monotonic() < deadline and b"group" not in got:
                try:
                    got.append(rx.recv(100))
                except BlockingIOError:
                    time.sleep(0.01)
        assert got == [b"group"]
    finally:
        rx.close()


def test_health_is_degraded_while_the_feed_is_refused_and_ok_again_after(tmp_path):
    """Issue 33: while every input was refused (a frozen clock) /health said "ok". Now a view in which most
    records were refused for their time stamps makes it "degraded" with the reason, and a view in which
    they are used again makes it "ok"."""

    svc, cfg, ep = _local_service(tmp_path)

    def feed(times) -> None:
        for t in times:
            svc._handle(time.time(), time.monotonic(), ep,
                        next(datablocks(CAT048, [cat048_record(t, 0, 1, 50_000.0 + t, 1.0)])))
        svc._refresh_view()

    try:
        feed([100.0 + k for k in range(20)])
        assert svc.health()["status"] == "ok"
        feed([50.0 + 0.1 * k for k in range(20)])  # all behind the reordering horizon: late
        health = svc.health()
        assert health["status"] == "degraded" and "20 of the last 20 records" in health["reason"]
        feed([120.0 + k for k in range(20)])
        assert svc.health()["status"] == "ok"
    finally:
        for sock in [*svc.sockets.values(), svc.publisher.sock]:
            sock.close()

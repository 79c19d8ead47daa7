"""End to end on loopback (127.0.0.1): a scenario exported with ``asterix-export``, sent with
``send``, tracked by ``serve``, its CAT062 received by a test listener and decoded by an independent
decoder (``asterix4py``), compared with the replay of the same recording.

"Match" (docs/service.md, "What the output is checked against"), with the CAT062 resolutions
(I070 1/128 s, I100 0.5 m, I185 0.25 m/s) as tolerances (half a unit):

1. every published update of track n equals a state the replay's track n reported (a *confirmed*
   or *updated* event) at the same time;
2. the final publication (after SIGTERM) holds exactly the replay's confirmed and coasting tracks
   at its end, each with the replay's final estimate, CST set exactly for the coasting ones;
3. every track published as ended (TSE) was deleted by the replay at that time.

Accounting: every datagram and record sent is in ``summary.json``, each record used or counted under
a reason, and the manager's reasons add up to the records handed to it.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import asterix4py  # the independent decoder (test dependency)
import pytest

from radartracker.cli import main
from radartracker.io.asterix_reader import read_asterix, read_cat062, read_sites
from radartracker.io.scenario import write_scenario
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.run import run
from radartracker.service import Service, ServiceConfig, parse_endpoint

T_TOL, XY_TOL, V_TOL = 1 / 256 + 1e-9, 0.25 + 1e-6, 0.125 + 1e-6
DEADLINE_S = 180.0  # the machine may be shared: generous, but every wait is bounded


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    """The tracking scenario, its Mode S aircraft falling silent at 50 s (radar and ADS-B), so that a
    published track ends within the recording."""
    import attrs
    import numpy as np

    from radartracker.io.tables import AdsbTable
    from radartracker.simulation.scenarios import build_scenario

    data = build_scenario("tracking", seed=2, duration=120).run()
    p, a = data.plots, data.adsb
    silent = sorted({c for c in p.mode_s if c is not None})[0]
    keep = np.flatnonzero(~((p.mode_s == silent) & (p.time > 50.0)))
    keep_a = ~((a.icao24 == silent) & (a.time > 50.0))
    data = attrs.evolve(data, plots=p.take(keep),
                        adsb=AdsbTable(**{f.name: getattr(a, f.name)[keep_a] for f in attrs.fields(AdsbTable)}))
    d = tmp_path_factory.mktemp("e2e")
    write_scenario(d / "sc", data)
    assert main(["asterix-export", str(d / "sc"), "--out", str(d / "rec.ast")]) == 0
    return d / "rec.ast"


class Listener(threading.Thread):
    """Collects every datagram arriving on a loopback port (or a multicast ``group`` joined on the
    loopback) until stopped."""

    def __init__(self, group: str | None = None) -> None:
        super().__init__(daemon=True)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        if group is None:
            self.sock.bind(("127.0.0.1", 0))
        else:
            self.sock.bind((group, 0))
            self.sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP,
                                 socket.inet_aton(group) + socket.inet_aton("127.0.0.1"))
        self.sock.settimeout(0.1)
        self.port = self.sock.getsockname()[1]
        self.datagrams: list[bytes] = []
        self.halt = threading.Event()

    def run(self) -> None:
        while not self.halt.is_set():
            try:
                self.datagrams.append(self.sock.recv(65535))
            except TimeoutError:
                pass

    def finish(self) -> list[bytes]:
        time.sleep(0.3)
        self.halt.set()
        self.join(5)
        self.sock.close()
        return self.datagrams


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(cond, what: str, limit_s: float = DEADLINE_S) -> None:
    end = time.monotonic() + limit_s
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.1)


def send(recording: Path, port: int, capsys) -> dict:
    capsys.readouterr()
    assert main(["send", str(recording), "--to", f"udp://127.0.0.1:{port}", "--speed", "60"]) == 0
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def check_against_replay(recording: Path, summary: dict, datagrams: list[bytes], sent: dict) -> None:
    # accounting: nothing lost, every record used or counted under a reason
    dg, rec = summary["datagrams"], summary["records"]
    assert dg["received"] == sent["datagrams"] == dg["decoded"]
    assert dg.get("dropped_queue_full", 0) == dg.get("dropped_kernel", 0) == dg.get("malformed", 0) == 0
    assert rec["cat048_records"] + rec["cat021_records"] == sent["records"]
    rejected = sum(v for k, v in rec.items() if k not in ("cat048_records", "cat021_records", "records_to_tracker"))
    assert rec["records_to_tracker"] + rejected == sent["records"]
    assert sum(summary["tracker"].values()) == rec["records_to_tracker"]

    data = read_asterix(recording, day_start=0.0)
    assert sum(1 for a in data.aircraft if a.mode_3a) > 0  # Mode 3/A kept by the import
    replay = run(data, RunConfig(association="manager", estimator=summary["estimator"],
                                 motion_model=summary["motion_model"], manager=summary["tracker_settings"]),
                 progress=False)
    assert summary["tracker"] == replay.counts

    records = [r for d in datagrams for r in asterix4py.AsterixParser(d).get_result().values()]
    assert all(r["cat"] == 62 for r in records)
    assert len(records) == summary["published"]["records"] > 0
    ev = replay.events
    reported: dict[int, list] = {}
    deleted: dict[int, float] = {}
    last: dict[int, tuple] = {}  # track -> (time, state) of its last estimate, status of its last event
    for i in range(len(ev.time)):
        n, kind = int(ev.track[i]), ev.kind[i]
        if kind in ("confirmed", "updated"):
            reported.setdefault(n, []).append((ev.time[i], ev.state[i]))
        elif kind == "deleted":
            deleted[n] = ev.time[i]
        if n in reported:
            last[n] = (*reported[n][-1], ev.status[i])
    live = {n: v for n, v in last.items() if n not in deleted}

    def same(r, t, x) -> bool:
        return (abs(r["070"]["ToT"] - t) <= T_TOL and abs(r["100"]["X"] - x[0]) <= XY_TOL
                and abs(r["100"]["Y"] - x[1]) <= XY_TOL and abs(r["185"]["Vx"] - x[2]) <= V_TOL
                and abs(r["185"]["Vy"] - x[3]) <= V_TOL)

    assert any(r["080"].get("TSE") for r in records)  # a track ended: rule 3 is exercised
    for r in records:  # 1 and 3
        n = r["040"]["TrkN"]
        if r["080"].get("TSE"):
            assert abs(deleted[n] - r["070"]["ToT"]) <= T_TOL
        else:
            assert any(same(r, t, x) for t, x in reported.get(n, ())), f"track {n} at {r['070']['ToT']}: not in the replay"
    final = [r for r in records[len(records) - summary["last_publication_records"]:] if not r["080"].get("TSE")]
    assert sorted(r["040"]["TrkN"] for r in final) == sorted(live) and live  # 2
    for r in final:
        t, x, status = live[r["040"]["TrkN"]]
        assert same(r, t, x)
        assert bool(r["080"].get("CST")) == (status == "coasting")


def published_late(recording: Path, summary: dict, datagrams: list[bytes]) -> list[tuple[int, float, float]]:
    """The replay's track updates (track, time) not published within the on-update bound, with the
    bound: a frame [k·fs, (k+1)·fs) is processed while the datagram whose records carry the newest
    time past (k+1)·fs + W is handled, and its tracks are sent at that datagram's end with their
    latest update, so an update at t is published with a time t' ∈ [t, t + fs + W + Δ], Δ the
    largest step of the newest record time over one datagram of the recording (in send order)."""
    from radartracker.service.decoder import DayClock, Decoder
    from radartracker.service.sender import datagrams as recording_datagrams

    _, sites = read_sites(Path(str(recording) + ".radars.csv"))
    decoder, newest, step = Decoder(sites, DayClock(0.0)), -float("inf"), 0.0
    for _, _, payload in recording_datagrams(recording):
        times = [i.time for i in decoder.decode(payload, 0.0)]
        if times and newest > -float("inf"):
            step = max(step, max(times) - newest)
        newest = max([newest, *times])
    bound = summary["tracker_settings"]["frame_s"] + summary["tracker_settings"]["reorder_window_s"] + step
    published: dict[int, list[float]] = {}
    for d in datagrams:
        for r in asterix4py.AsterixParser(d).get_result().values():
            published.setdefault(r["040"]["TrkN"], []).append(r["070"]["ToT"])
    data = read_asterix(recording, day_start=0.0)
    ev = run(data, RunConfig(association="manager", estimator=summary["estimator"], motion_model=summary["motion_model"],
                             manager=summary["tracker_settings"]), progress=False).events
    return [(int(ev.track[i]), float(ev.time[i]), bound) for i in range(len(ev.time))
            if ev.kind[i] in ("confirmed", "updated")
            and not any(ev.time[i] - T_TOL <= t <= ev.time[i] + bound for t in published.get(int(ev.track[i]), ()))]


@pytest.mark.parametrize("mode", ["update", "periodic"])
def test_serve_in_a_thread_matches_the_replay(recording, tmp_path, capsys, mode):
    radars, sites = read_sites(Path(str(recording) + ".radars.csv"))
    listener = Listener()
    listener.start()
    port = free_port()
    http = free_port()
    cfg = ServiceConfig((parse_endpoint(f"udp://127.0.0.1:{port}"),), parse_endpoint(f"udp://127.0.0.1:{listener.port}"),
                        tmp_path / "state", http=("127.0.0.1", http), period_s=0.5, checkpoint_s=1.0, day_start=0.0,
                        publish_mode=mode)
    service = Service(cfg, radars, sites)
    stop, out = threading.Event(), {}
    th = threading.Thread(target=lambda: out.update(service.run(stop)), daemon=True)
    th.start()
    sent = send(recording, port, capsys)
    wait_for(lambda: service.view["datagrams"].get("decoded", 0) >= sent["datagrams"], "the service to read everything")
    wait_for(lambda: service.tracks_json["tracks"], "a publication with tracks")

    def get(path: str):
        with urllib.request.urlopen(f"http://127.0.0.1:{http}{path}", timeout=30) as r:
            return r.headers["Content-Type"], r.read().decode()

    ctype, body = get("/tracks")
    rows = json.loads(body)["tracks"]
    assert ctype == "application/json" and rows and {"track_number", "lat", "lon", "status", "mode_s"} <= rows[0].keys()
    assert set(json.loads(get("/biases")[1])["radars"]) == {r.id for r in radars}
    ctype, metrics = get("/metrics")
    assert ctype.startswith("text/plain") and "radartracker_processing_latency_seconds_bucket" in metrics
    assert f'radartracker_records_total{{outcome="records_to_tracker"}} {float(sent["records"])}' in metrics
    with pytest.raises(urllib.error.HTTPError):
        get("/nothing")
    stop.set()
    th.join(DEADLINE_S)
    assert not th.is_alive()
    datagrams = listener.finish()
    summary = json.loads((tmp_path / "state" / "summary.json").read_text())
    assert summary["datagrams"] == out["datagrams"]
    check_against_replay(recording, summary, datagrams, sent)
    # the service's output read back by our own reader agrees with the independent decoder
    (tmp_path / "out.ast").write_bytes(b"".join(datagrams))
    ours = read_cat062(tmp_path / "out.ast")
    theirs = [r for d in datagrams for r in asterix4py.AsterixParser(d).get_result().values()]
    assert [(o["track_number"], o["x_m"], o["coasting"], o["ended"]) for o in ours] == \
        [(r["040"]["TrkN"], r["100"]["X"], bool(r["080"].get("CST")), bool(r["080"].get("TSE"))) for r in theirs]
    biases = json.loads((tmp_path / "state" / "biases.json").read_text())
    assert set(biases["radars"]) == {r.id for r in radars}
    late = published_late(recording, summary, datagrams)
    if mode == "update":  # every update is sent as soon as its frame is processed
        assert not late, late[:5]
        assert summary["published"]["publications_on_update"] > 0
    else:  # the bound discriminates: a period of 0.5 s at 60x speed holds 30 s of data
        assert late and "publications_on_update" not in summary["published"]


@pytest.mark.slow
def test_serve_command_stops_on_sigterm_and_matches_the_replay(recording, tmp_path, capsys):
    listener = Listener()
    listener.start()
    port, http = free_port(), free_port()
    cmd = [sys.executable, "-c", "import sys; from radartracker.cli import main; sys.exit(main())", "serve",
           "--radars", f"{recording}.radars.csv", "--listen", f"udp://127.0.0.1:{port}",
           "--publish", f"udp://127.0.0.1:{listener.port}", "--state", str(tmp_path / "state"),
           "--http", f"127.0.0.1:{http}", "--period", "0.5", "--checkpoint-s", "1", "--day-start", "1970-01-01"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        def health() -> dict | None:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{http}/health", timeout=10) as r:
                    return json.loads(r.read())
            except OSError:
                assert proc.poll() is None, proc.stderr.read()
                return None

        wait_for(lambda: health() is not None, "the service to start")
        sent = send(recording, port, capsys)
        wait_for(lambda: (health() or {"datagrams": {}})["datagrams"].get("decoded", 0) >= sent["datagrams"],
                 "the service to read everything")
        with urllib.request.urlopen(f"http://127.0.0.1:{http}/metrics", timeout=5) as r:
            metrics = r.read().decode()
        assert f'radartracker_datagrams_total{{outcome="received"}} {float(sent["datagrams"])}' in metrics
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=DEADLINE_S)
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 0, err
    summary = json.loads((tmp_path / "state" / "summary.json").read_text())
    check_against_replay(recording, summary, listener.finish(), sent)


def _run_service(state: Path, radars, sites, payloads: list[bytes], listener_port: int) -> dict:
    """A service in a thread fed ``payloads`` over loopback until it has read them all, then stopped."""
    port = free_port()
    cfg = ServiceConfig((parse_endpoint(f"udp://127.0.0.1:{port}"),), parse_endpoint(f"udp://127.0.0.1:{listener_port}"),
                        state, period_s=0.5, checkpoint_s=0.5, day_start=0.0)
    service = Service(cfg, radars, sites)
    stop, out = threading.Event(), {}
    th = threading.Thread(target=lambda: out.update(service.run(stop)), daemon=True)
    th.start()
    base = service.view["datagrams"].get("decoded", 0)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        for k, p in enumerate(payloads):
            tx.sendto(p, ("127.0.0.1", port))
            if k % 20 == 19:
                time.sleep(0.01)
    wait_for(lambda: service.view["datagrams"].get("decoded", 0) >= base + len(payloads), "the service to read everything")
    stop.set()
    th.join(DEADLINE_S)
    assert not th.is_alive()
    return out


def test_a_restarted_service_continues_from_its_checkpoint(recording, tmp_path):
    from radartracker.service.sender import datagrams

    radars, sites = read_sites(Path(str(recording) + ".radars.csv"))
    payloads = [p for _, _, p in datagrams(recording)]
    half = len(payloads) // 2
    listener = Listener()
    listener.start()
    first = _run_service(tmp_path / "state", radars, sites, payloads[:half], listener.port)
    n_first = len(listener.datagrams)
    second = _run_service(tmp_path / "state", radars, sites, payloads[half:], listener.port)
    got = listener.finish()
    assert second["resumed_from"] == first["last_checkpoint"]
    # the counters continue: the two runs account for the whole recording
    assert second["datagrams"]["received"] == second["datagrams"]["decoded"] == len(payloads)
    data = read_asterix(recording, day_start=0.0)
    assert second["records"]["records_to_tracker"] == len(data.plots) + len(data.adsb)
    assert sum(second["tracker"].values()) == second["records"]["records_to_tracker"]
    # the tracks continue: aircraft published at the end of the first run keep their track numbers
    def tracks(dgs) -> list[tuple[int, int | None, bool]]:
        return [(r["040"]["TrkN"], r.get("380", {}).get("ADR"), bool(r["080"].get("TSE")))
                for d in dgs for r in asterix4py.AsterixParser(d).get_result().values()]

    final = {(n, a) for n, a, ended in tracks(got[:n_first])[-first["last_publication_records"]:] if not ended}
    after = {(n, a) for n, a, _ in tracks(got[n_first:])}
    assert final and final <= after  # every track alive at the stop is published again, same number and address


GROUP_IN, GROUP_OUT = "239.255.14.1", "239.255.14.2"  # administratively scoped; sent on the loopback only


def loopback_multicast_refused() -> str | None:
    """Why this host's loopback cannot carry multicast (None if it can): a group joined on 127.0.0.1,
    one datagram sent to it out of 127.0.0.1 (IP_MULTICAST_IF, IP_MULTICAST_LOOP; no route needed)."""
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        rx.bind((GROUP_IN, 0))
        rx.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, socket.inet_aton(GROUP_IN) + socket.inet_aton("127.0.0.1"))
        rx.settimeout(2.0)
        tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
        tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
        tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
        tx.sendto(b"probe", (GROUP_IN, rx.getsockname()[1]))
        return None if rx.recv(64) == b"probe" else "a different datagram came back"
    except TimeoutError:
        return "a datagram sent to a group joined on 127.0.0.1 did not come back within 2 s"
    except OSError as exc:
        return f"{type(exc).__name__}: {exc}"
    finally:
        rx.close()
        tx.close()


def test_multicast_in_and_out_on_the_loopback(recording, tmp_path, capsys):
    """``send`` to a multicast group, ``serve`` joined to it and publishing to another group, a
    listener joined to that one: everything sent is accounted for, and every CAT062 sent arrives."""
    why = loopback_multicast_refused()
    if why is not None:
        print(f"loopback multicast unavailable: {why}")
        pytest.skip(f"this host's loopback does not carry multicast: {why}")
    radars, sites = read_sites(Path(str(recording) + ".radars.csv"))
    listener = Listener(GROUP_OUT)
    listener.start()
    port = free_port()
    cfg = ServiceConfig((parse_endpoint(f"udp://{GROUP_IN}:{port}"),),
                        parse_endpoint(f"udp://{GROUP_OUT}:{listener.sock.getsockname()[1]}"), tmp_path / "state",
                        period_s=0.5, checkpoint_s=60.0, day_start=0.0, interface="127.0.0.1")
    service = Service(cfg, radars, sites)
    stop, out = threading.Event(), {}
    th = threading.Thread(target=lambda: out.update(service.run(stop)), daemon=True)
    th.start()
    capsys.readouterr()
    assert main(["send", str(recording), "--to", f"udp://{GROUP_IN}:{port}", "--interface", "127.0.0.1",
                 "--speed", "0"]) == 0
    sent = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    wait_for(lambda: service.view["datagrams"].get("decoded", 0) >= sent["datagrams"], "the service to read everything")
    stop.set()
    th.join(DEADLINE_S)
    assert not th.is_alive()
    got = listener.finish()
    dg, rec = out["datagrams"], out["records"]
    assert dg["received"] == dg["decoded"] == sent["datagrams"] and dg.get("dropped_queue_full", 0) == 0
    assert rec["cat048_records"] + rec["cat021_records"] == sent["records"]
    records = [r for d in got for r in asterix4py.AsterixParser(d).get_result().values()]
    assert out["published"]["datagrams_sent"] == len(got) > 0 and len(records) == out["published"]["records"]

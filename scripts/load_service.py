"""Load test of ``radartracker serve`` on loopback (127.0.0.1 only): national traffic in, CAT062 out.

The traffic is a recording made by ``radartracker simulate OUT --scenario traffic`` and
``asterix-export`` (``--recording``), or simulated here (:mod:`radartracker.simulation.traffic`).
Its records are packed into datagrams as radar heads and an ADS-B ground station send them (one
source and category per datagram, at most 0.25 s of data and 1472 bytes, sent at the time of its
last record). For each time scale in ``--speeds`` the script starts the service pinned to one core,
sends the datagrams on their own timing scaled by the speed, listens to the CAT062 output, stops
the service with SIGTERM and prints one JSON line:

* ``offered_records_per_s`` and whether anything was dropped (queue full, kernel buffer);
* ``processing_latency_s`` p50/p99: datagram receipt → its records handed to the tracker
  (the service's histogram);
* ``end_to_end_latency_s`` p50/p99: a record's datagram sent → the first CAT062 received for its
  aircraft (I380 address) with a track time (I070) at or after the record's time; it includes the
  tracker's reorder window, its 0.5 s frames and, unless the service publishes on update, the wait
  for the next periodic publication (``--period``);
* ``input_lateness_s`` and ``records_later_than_s``: how out of order the records arrive (the
  service's histogram: newest record time received before a record − its time), and how many a
  reorder window of each bucket's length could count as late (an upper bound); ``inputs_late``: those the tracker
  did count as late (``plots_late`` + ``adsb_late``) with the window of the run;
* ``service_cpu_s`` (its own and its checkpoint children's, from its first datagram: the start-up
  — imports, restore — is ``service_startup_cpu_s``), per record, and the rate one core
  would sustain at that cost (``one_core_capacity_records_per_s``) — on a shared machine the service
  gets only part of its core, and this is the figure that does not depend on how much;
  ``one_core_real_time_factor`` = the traffic's seconds ÷ that CPU time (≥ 1: one dedicated core
  keeps up with the traffic at 1×); ``load_avg_*``: the machine's load around the run.

``--kill-at S`` runs one more pass at the first speed: the service is killed with SIGKILL S seconds
into the run and restarted at once on the same state folder; the line says which records were lost
(sent − accounted in ``summary.json``), how many were sent between the last checkpoint and the
restart, and how many aircraft kept their track number across the restart.

Every loop is bounded in count and time. The machine may be shared: say so with the numbers.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from collections import defaultdict
from pathlib import Path

import numpy as np

from radartracker.io.asterix import sac_sic_of, write_sites
from radartracker.io.capture import iter_datablocks
from radartracker.service.codec import blocks, cat021_bytes, cat048_bytes, decode_block_fast, split_block_fast
from radartracker.simulation.traffic import traffic_scenario

WINDOW_S, MAX_DATAGRAM = 0.25, 1472
ADSB_SAC_SIC = (0, 200)


def scenario_records(data) -> list[tuple[float, object, int, bytes, str | None]]:
    """(time, source, category, record bytes, Mode S address) of a simulated scenario's plots and reports."""
    sac_sic = sac_sic_of(data)
    p, a = data.plots, data.adsb
    out = [(float(p.time[i]), p.radar[i], 48, cat048_bytes(float(p.time[i]), *sac_sic[p.radar[i]], p.range_m[i],
                                                           p.azimuth_rad[i], p.altitude_m[i], p.mode_s[i], p.mode_3a[i]),
            p.mode_s[i]) for i in range(len(p))]
    out += [(float(a.time[i]), "adsb", 21, cat021_bytes(float(a.time[i]), *ADSB_SAC_SIC, a.icao24[i], a.lat[i], a.lon[i],
                                                        a.altitude_m[i], int(a.nacp[i])), a.icao24[i])
            for i in range(len(a))]
    return out


def recording_records(path: Path) -> list[tuple[float, object, int, bytes, str | None]]:
    """The same from a CAT048/CAT021 recording (``asterix-export``'s output; times = time of day), its
    records' own bytes, read with the service's fast path."""
    out = []
    for _, block in iter_datablocks(path):
        fast, split = decode_block_fast(block), split_block_fast(block)
        if fast is None or split is None:
            raise SystemExit(f"{path}: a block the fast path cannot read (category {block[0]})")
        for d, (rec, tod) in zip(fast[1], split[1]):
            if fast[0] == 48:
                out.append((tod, (d["sac"], d["sic"]), 48, rec, d["mode_s"]))
            else:
                out.append((tod, "adsb", 21, rec, d["icao24"]))
    return out


def datagram_schedule(records) -> list[tuple[float, bytes, list[tuple[str, float]]]]:
    """(send time = time of its last record, payload, [(address, time) of its records]) in send order:
    each source's records in time order, cut into datagrams of at most WINDOW_S and MAX_DATAGRAM."""
    out: list = []
    open_: dict = {}

    def flush(key) -> None:
        cat, recs, keys = open_.pop(key)
        for payload in blocks(cat, recs, MAX_DATAGRAM):  # one block: recs fit by construction
            out.append((keys[-1][1], payload, keys))

    for t, key, cat, rec, addr in sorted(records, key=lambda r: r[0]):
        if key in open_:
            c, recs, keys = open_[key]
            if t - keys[0][1] > WINDOW_S or 3 + sum(map(len, recs)) + len(rec) > MAX_DATAGRAM:
                flush(key)
        c, recs, keys = open_.setdefault(key, (cat, [], []))
        recs.append(rec)
        keys.append((addr, t))
    for key in list(open_):
        flush(key)
    out.sort(key=lambda d: d[0])
    return out


class Listener(threading.Thread):
    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 16 * 2**20)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.got: list[tuple[float, bytes]] = []
        self.halt = threading.Event()

    def run(self) -> None:
        while not self.halt.is_set():
            try:
                self.got.append((time.time(), self.sock.recv(65535)))
            except TimeoutError:
                pass


def cat062_updates(got: list[tuple[float, bytes]]) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """address → (receipt times, track times I070, track numbers) of the CAT062 the service sent
    (its own layout: radartracker.service.codec.cat062_bytes)."""
    per: dict[str, list] = defaultdict(list)
    lengths = {0: 2, 2: 1, 3: 3, 4: 8, 5: 6, 6: 4, 8: 2, 11: 2, 16: 2}  # FRN index → octets
    for recv, d in got:
        off = 3
        while off < len(d):
            fspec = []
            while True:
                fspec.append(d[off])
                off += 1
                if not fspec[-1] & 1:
                    break
            frns = [7 * k + i for k, b in enumerate(fspec) for i in range(7) if b & (0x80 >> i)]
            tod = num = addr = None
            for frn in frns:
                if frn == 12:  # I080: extended
                    n = 1
                    while d[off + n - 1] & 1:
                        n += 1
                elif frn == 10:  # I380 with ADR only
                    n = 4
                    addr = f"{int.from_bytes(d[off + 1: off + 4], 'big'):06x}"
                else:
                    n = lengths[frn]
                if frn == 3:
                    tod = int.from_bytes(d[off: off + 3], "big") / 128
                elif frn == 11:
                    num = int.from_bytes(d[off: off + 2], "big")
                off += n
            if addr is not None:
                per[addr].append((recv, tod, num))
    return {k: tuple(np.array(c) for c in zip(*sorted(v))) for k, v in per.items()}


def end_to_end(sched, sent_wall: np.ndarray, updates) -> dict:
    """Datagram sent → first CAT062 for the record's aircraft with a track time at or after the record's:
    p50/p99/p99.9/max over the records of aircraft already published when the datagram left (a track
    update), and apart those of aircraft not yet published (track initiation: M of N scans first)."""
    lat, first, missing = [], [], 0
    for (_, _, keys), sw in zip(sched, sent_wall):
        for addr, t in keys:
            u = updates.get(addr)
            if u is None or np.isnan(sw):
                missing += 1
                continue
            recv, tod, _ = u
            k = np.searchsorted(np.maximum.accumulate(tod), t - 1 / 256)
            if k < len(recv):
                (lat if recv[0] < sw else first).append(recv[k] - sw)
            else:
                missing += 1

    def q(x: list[float], *ps: float) -> dict:
        return {f"p{p:g}".replace(".", ""): round(float(np.percentile(x, p)), 3) for p in ps} if x else {}

    return ({"records_reflected": len(lat) + len(first), "records_not_reflected": missing, "track_updates": len(lat)}
            | q(lat, 50, 99, 99.9) | ({"max": round(max(lat), 3)} if lat else {})
            | {"track_initiation": {"records": len(first)} | q(first, 50, 99)})


def histogram_quantiles(metrics: str, name: str = "radartracker_processing_latency_seconds") -> dict:
    b = sorted((float(m.group(1)), float(m.group(2))) for m in re.finditer(
        rf'{name}_bucket{{le="([^"]+)"}} ([0-9.e+]+)', metrics.replace('le="+Inf"', 'le="inf"')))
    total = b[-1][1] if b else 0.0
    out = {}
    for q in (0.5, 0.99):
        lo_le, lo_n = 0.0, 0.0
        for le, n in b:
            if n >= q * total:
                out[f"p{int(q * 100)}"] = (None if le == float("inf") else
                                           round(lo_le + (le - lo_le) * (q * total - lo_n) / max(n - lo_n, 1e-12), 4))
                break
            lo_le, lo_n = le, n
    return out | {"count": int(total)}


def later_than(metrics: str, name: str = "radartracker_input_lateness_seconds") -> dict[str, int]:
    """Records whose lateness (newest record time received before them − their time) exceeds each
    bucket bound: at most what a reorder window of that many seconds would count as late."""
    b = sorted((float(m.group(1)), float(m.group(2))) for m in re.finditer(
        rf'{name}_bucket{{le="([^"]+)"}} ([0-9.e+]+)', metrics.replace('le="+Inf"', 'le="inf"')))
    total = b[-1][1] if b else 0.0
    return {f"{le:g}": int(total - n) for le, n in b if le != float("inf")}


def get(url: str, timeout: float = 5.0) -> str | None:
    try:
        with urllib.request.urlopen(url, timeout=timeout) as r:
            return r.read().decode()
    except OSError:
        return None


def cpu_seconds(pid: int) -> float:
    f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return sum(int(v) for v in f[11:15]) / os.sysconf("SC_CLK_TCK")  # its own and its checkpoint children's


def start_service(args, work: Path, sites: Path, port: int, http: int, listener: Listener) -> subprocess.Popen:
    cmd = [sys.executable, "-c", "import sys; from radartracker.cli import main; sys.exit(main())", "serve",
           "--radars", str(sites), "--listen", f"udp://127.0.0.1:{port}", "--publish", f"udp://127.0.0.1:{listener.port}",
           "--state", str(work / "state"), "--http", f"127.0.0.1:{http}", "--period", str(args.period),
           "--checkpoint-s", str(args.checkpoint_s), "--day-start", "0"]
    if args.reorder_window is not None:
        cmd += ["--reorder-window", str(args.reorder_window)]
    if args.publish_mode is not None:
        cmd += ["--publish-mode", args.publish_mode]
    core = {args.core} if args.core is not None else None
    log = open(work / "service.log", "a")
    proc = subprocess.Popen(cmd, stdout=log, stderr=log, text=True,
                            preexec_fn=(lambda: os.sched_setaffinity(0, core)) if core else None)
    end = time.monotonic() + 180
    while get(f"http://127.0.0.1:{http}/health", 2) is None:
        if proc.poll() is not None or time.monotonic() > end:
            raise SystemExit(f"the service did not start (exit {proc.poll()}): see {work / 'service.log'}")
        time.sleep(0.2)
    return proc


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def one_run(args, sched, sites: Path, speed: float, kill_at: float | None = None) -> dict:
    work = Path(tempfile.mkdtemp(prefix="load_service_"))
    load_start = os.getloadavg()
    listener = Listener()
    listener.start()
    port, http = free_port(), free_port()
    proc = start_service(args, work, sites, port, http, listener)
    startup_cpu = cpu_seconds(proc.pid)  # imports and restore, before the first datagram: not per-record work
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # unconnected: a dead service costs no error here
    sent_wall = np.full(len(sched), np.nan)
    t0 = sched[0][0]
    start = time.monotonic()
    wall0 = time.time()
    holder, info = {"proc": proc}, {}
    if kill_at is not None:  # kill -9 and restart beside the sender, which keeps its schedule
        def kill_and_restart() -> None:
            time.sleep(max(0.0, start + kill_at - time.monotonic()))
            info["cpu_before_kill"] = cpu_seconds(proc.pid)
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(30)
            info["killed"] = time.time()
            last = sorted((work / "state").glob("checkpoint-*"))
            info["checkpoint"] = json.loads((last[-1] / "service.json").read_text()) if last else None
            holder["proc"] = start_service(args, work, sites, port, http, listener)
            info["startup_cpu_after_restart"] = cpu_seconds(holder["proc"].pid)
            info["restarted"] = time.time()

        killer = threading.Thread(target=kill_and_restart, daemon=True)
        killer.start()
    for k, (t, payload, _) in enumerate(sched):
        delay = start + (t - t0) / speed - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        tx.sendto(payload, ("127.0.0.1", port))
        sent_wall[k] = time.time()
    if kill_at is not None:
        killer.join(300)
        proc = holder["proc"]
    send_s = time.monotonic() - start
    end = time.monotonic() + 300  # let the service finish what it has queued (bounded)
    while time.monotonic() < end:
        h = get(f"http://127.0.0.1:{http}/health")
        if h is not None and json.loads(h)["queue_depth"] == 0:
            break
        time.sleep(0.5)
    metrics = get(f"http://127.0.0.1:{http}/metrics") or ""
    cpu = (info.get("cpu_before_kill", 0.0) + cpu_seconds(proc.pid)
           - startup_cpu - info.get("startup_cpu_after_restart", 0.0))
    run_s = time.monotonic() - start
    proc.send_signal(signal.SIGTERM)
    proc.wait(300)
    time.sleep(0.5)
    listener.halt.set()
    listener.join(5)
    summary = json.loads((work / "state" / "summary.json").read_text())
    records = sum(len(s[2]) for s in sched)
    data_s = sched[-1][0] - sched[0][0]
    dg, tracker = summary["datagrams"], summary["tracker"]
    out = {
        "speed": speed, "source": args.source, "data_s": round(data_s, 1),
        "datagrams_sent": len(sched), "records_sent": records,
        "offered_records_per_s": round(records / send_s, 1), "wall_s": round(send_s, 1),
        "service_cpu_s": round(cpu, 1), "service_startup_cpu_s": round(startup_cpu, 1),
        "service_cpu_share_of_a_core": round(cpu / run_s, 2),
        "service_cpu_ms_per_record": round(cpu / records * 1e3, 3),
        "one_core_capacity_records_per_s": round(records / cpu, 1),
        # the rate one dedicated core sustains at this cost ÷ the traffic's own rate (at 1×)
        "one_core_real_time_factor": round(data_s / cpu, 2),
        "dropped_queue_full": dg.get("dropped_queue_full", 0), "dropped_kernel": dg.get("dropped_kernel", 0),
        "records_accounted": summary["records"].get("cat048_records", 0) + summary["records"].get("cat021_records", 0),
        "inputs_late": tracker.get("plots_late", 0) + tracker.get("adsb_late", 0),
        "input_lateness_s": histogram_quantiles(metrics, "radartracker_input_lateness_seconds"),
        "records_later_than_s": later_than(metrics),
        "processing_latency_s": histogram_quantiles(metrics),
        "end_to_end_latency_s": end_to_end(sched, sent_wall, cat062_updates(listener.got)),
        "cat062_records_per_s": round(summary["published"].get("records", 0) / run_s, 1),
        "publish_mode": args.publish_mode or "default", "period_s": args.period,
        "reorder_window_s": args.reorder_window or "default", "tracks": summary["tracks_by_status"],
        "estimator": summary["estimator"], "motion_model": summary["motion_model"],
        "resumed_from": summary.get("resumed_from"), "cpus": os.cpu_count(), "load_avg_start": load_start,
        "load_avg_end": os.getloadavg(),
    }
    if kill_at is not None:
        out |= restart_report(sched, sent_wall, info, summary, listener.got)
    out["state_dir"] = str(work)
    return out


def restart_report(sched, sent_wall, info, summary, got) -> dict:
    killed, restarted, ck = info["killed"], info["restarted"], info["checkpoint"]
    recs = np.array([len(s[2]) for s in sched])
    ck_time = ck["written"] if ck else -np.inf
    since_ckpt = int(recs[(sent_wall > ck_time) & (sent_wall <= killed)].sum())
    down = int(recs[(sent_wall > killed) & (sent_wall <= restarted)].sum())
    upd = cat062_updates(got)
    kept = changed = 0
    for addr, (recv, _, num) in upd.items():
        pre, post = set(num[recv < killed].tolist()), set(num[recv > restarted].tolist())
        if pre and post:
            kept += bool(pre & post)
            changed += not (pre & post)
    return {"kill": {"killed_after_s": round(killed - sent_wall[0], 1), "restart_s": round(restarted - killed, 1),
                     "last_checkpoint_before_kill_age_s": round(killed - ck_time, 1) if ck else None,
                     "records_sent_after_that_checkpoint_until_kill": since_ckpt,
                     "records_sent_while_down": down,
                     "records_lost": int(recs.sum()) - (summary["records"].get("cat048_records", 0)
                                                        + summary["records"].get("cat021_records", 0)),
                     "resumed_from": summary.get("resumed_from"), "aircraft_same_track_number_across_restart": kept,
                     "aircraft_new_track_number_after_restart": changed}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--recording", type=Path, default=None,
                    help="a CAT048/CAT021 recording from asterix-export (its .radars.csv beside it); "
                         "default: traffic simulated here with --aircraft, --radars, --duration")
    ap.add_argument("--aircraft", type=int, default=2000)
    ap.add_argument("--radars", type=int, default=28)
    ap.add_argument("--duration", type=float, default=120.0, help="seconds of traffic per run")
    ap.add_argument("--publish-mode", default=None, choices=("update", "periodic", "both"),
                    help="the service's --publish-mode (default: its default)")
    ap.add_argument("--speeds", default="1,1.5", help="time scales to try, comma separated")
    ap.add_argument("--period", type=float, default=4.0, help="the service's CAT062 period (s; its default 4)")
    ap.add_argument("--checkpoint-s", type=float, default=10.0)
    ap.add_argument("--reorder-window", type=float, default=None, help="the tracker's reorder window (s; default 2)")
    ap.add_argument("--core", type=int, default=1, help="CPU the service is pinned to (-1: not pinned)")
    ap.add_argument("--kill-at", type=float, default=None, help="also a kill -9 run, killed this many seconds in")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    args.core = None if args.core < 0 else args.core
    if args.recording is not None:
        records = recording_records(args.recording)
        sites = Path(f"{args.recording}.radars.csv")
        args.source = str(args.recording)
    else:
        data = traffic_scenario(seed=args.seed, duration=args.duration, aircraft=args.aircraft, radars=args.radars).run()
        records = scenario_records(data)
        sites = Path(tempfile.mkdtemp(prefix="load_service_sites_")) / "radars.csv"
        write_sites(sites, data.radars, sac_sic_of(data))
        args.source = f"traffic: {args.aircraft} aircraft, {len(data.radars)} radars, {args.duration:g} s, seed {args.seed}"
    sched = datagram_schedule(records)
    if args.core is not None:
        os.sched_setaffinity(0, set(range(os.cpu_count() or 1)) - {args.core} or {args.core})
    data_s = sched[-1][0] - sched[0][0]
    n48 = sum(r[2] == 48 for r in records)
    print(json.dumps({"scenario": {"source": args.source, "data_s": round(data_s, 1), "plots": n48,
                                   "adsb": len(records) - n48, "datagrams": len(sched),
                                   "records_per_s": round(len(records) / data_s, 1)}}), flush=True)
    for speed in (float(s) for s in args.speeds.split(",")):
        print(json.dumps(one_run(args, sched, sites, speed)), flush=True)
    if args.kill_at is not None:
        print(json.dumps(one_run(args, sched, sites, float(args.speeds.split(",")[0]), args.kill_at)), flush=True)


if __name__ == "__main__":
    main()

"""Load test of ``radartracker serve`` on loopback (127.0.0.1 only): national traffic in, CAT062 out.

For each time scale in ``--speeds`` the script simulates national traffic
(:mod:`radartracker.simulation.traffic`), packs it into datagrams as radar heads and an ADS-B
ground station send them (one source and category per datagram, at most 0.25 s of data and 1472
bytes), starts the service pinned to one core, sends the datagrams on their own timing scaled by
the speed, listens to the CAT062 output, stops the service with SIGTERM and prints one JSON line:

* ``offered_records_per_s`` and whether anything was dropped (queue full, kernel buffer);
* ``processing_latency_s`` p50/p99: datagram receipt → its records handed to the tracker
  (the service's histogram);
* ``end_to_end_latency_s`` p50/p99: a record's datagram sent → the first CAT062 received for its
  aircraft (I380 address) with a track time (I070) at or after the record's time; it includes the
  tracker's 2 s reorder window, its 0.5 s frames and the wait for the next publication (``--period``);
* ``service_cpu_s`` (its own and its checkpoint children's), per record, and the rate one core
  would sustain at that cost (``one_core_capacity_records_per_s``) — on a shared machine the service
  gets only part of its core, and this is the figure that does not depend on how much.

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

from radartracker.io.asterix import _write_sites, sac_sic_of
from radartracker.service.codec import blocks, cat021_bytes, cat048_bytes
from radartracker.simulation.traffic import traffic_scenario

WINDOW_S, MAX_DATAGRAM = 0.25, 1472
ADSB_SAC_SIC = (0, 200)


def datagram_schedule(data) -> list[tuple[float, bytes, list[tuple[str, float]]]]:
    """(send time = time of its last record, payload, [(address, time) of its records]) in send order."""
    sac_sic = sac_sic_of(data)
    p, a = data.plots, data.adsb
    ev = sorted([(float(p.time[i]), 0, i) for i in range(len(p))] + [(float(a.time[i]), 1, i) for i in range(len(a))])
    out: list = []
    open_: dict = {}

    def flush(key) -> None:
        cat, recs, keys = open_.pop(key)
        for payload in blocks(cat, recs, MAX_DATAGRAM):  # one block: recs fit by construction
            out.append((keys[-1][1], payload, keys))

    for t, kind, i in ev:
        if kind == 0:
            key, cat = p.radar[i], 48
            rec = cat048_bytes(t, *sac_sic[key], p.range_m[i], p.azimuth_rad[i], p.altitude_m[i], p.mode_s[i],
                               p.mode_3a[i])
            addr = p.mode_s[i]
        else:
            key, cat = "adsb", 21
            rec = cat021_bytes(t, *ADSB_SAC_SIC, a.icao24[i], a.lat[i], a.lon[i], a.altitude_m[i], int(a.nacp[i]))
            addr = a.icao24[i]
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
    lat, missing = [], 0
    for (_, _, keys), sw in zip(sched, sent_wall):
        for addr, t in keys:
            u = updates.get(addr)
            if u is None or np.isnan(sw):
                missing += 1
                continue
            recv, tod, _ = u
            k = np.searchsorted(np.maximum.accumulate(tod), t - 1 / 256)
            if k < len(recv):
                lat.append(recv[k] - sw)
            else:
                missing += 1
    lat = np.array(lat)
    return {"records_reflected": len(lat), "records_not_reflected": missing,
            "p50": round(float(np.percentile(lat, 50)), 3) if len(lat) else None,
            "p99": round(float(np.percentile(lat, 99)), 3) if len(lat) else None}


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
    listener = Listener()
    listener.start()
    port, http = free_port(), free_port()
    proc = start_service(args, work, sites, port, http, listener)
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
    cpu = info.get("cpu_before_kill", 0.0) + cpu_seconds(proc.pid)
    proc.send_signal(signal.SIGTERM)
    proc.wait(300)
    time.sleep(0.5)
    listener.halt.set()
    listener.join(5)
    summary = json.loads((work / "state" / "summary.json").read_text())
    records = sum(len(s[2]) for s in sched)
    dg = summary["datagrams"]
    out = {
        "speed": speed, "aircraft": args.aircraft, "radars": args.radars, "data_s": args.duration,
        "datagrams_sent": len(sched), "records_sent": records,
        "offered_records_per_s": round(records / send_s, 1), "wall_s": round(send_s, 1),
        "service_cpu_s": round(cpu, 1), "service_cpu_ms_per_record": round(cpu / records * 1e3, 3),
        "one_core_capacity_records_per_s": round(records / cpu, 1),
        "dropped_queue_full": dg.get("dropped_queue_full", 0), "dropped_kernel": dg.get("dropped_kernel", 0),
        "records_accounted": summary["records"].get("cat048_records", 0) + summary["records"].get("cat021_records", 0),
        "processing_latency_s": histogram_quantiles(metrics),
        "end_to_end_latency_s": end_to_end(sched, sent_wall, cat062_updates(listener.got)),
        "period_s": args.period, "reorder_window_s": args.reorder_window or 2.0, "tracks": summary["tracks_by_status"], "estimator": summary["estimator"],
        "resumed_from": summary.get("resumed_from"), "cpus": os.cpu_count(), "load_avg": os.getloadavg(),
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
    ap.add_argument("--aircraft", type=int, default=2000)
    ap.add_argument("--radars", type=int, default=28)
    ap.add_argument("--duration", type=float, default=120.0, help="seconds of traffic per run")
    ap.add_argument("--speeds", default="1,1.5", help="time scales to try, comma separated")
    ap.add_argument("--period", type=float, default=1.0, help="the service's CAT062 period (s)")
    ap.add_argument("--checkpoint-s", type=float, default=10.0)
    ap.add_argument("--reorder-window", type=float, default=None, help="the tracker's reorder window (s; default 2)")
    ap.add_argument("--core", type=int, default=1, help="CPU the service is pinned to (-1: not pinned)")
    ap.add_argument("--kill-at", type=float, default=None, help="also a kill -9 run, killed this many seconds in")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    args.core = None if args.core < 0 else args.core
    data = traffic_scenario(seed=args.seed, duration=args.duration, aircraft=args.aircraft, radars=args.radars).run()
    sched = datagram_schedule(data)
    sites = Path(tempfile.mkdtemp(prefix="load_service_sites_")) / "radars.csv"
    _write_sites(sites, data.radars, sac_sic_of(data))
    if args.core is not None:
        os.sched_setaffinity(0, set(range(os.cpu_count() or 1)) - {args.core} or {args.core})
    print(json.dumps({"scenario": {"aircraft": args.aircraft, "radars": len(data.radars), "data_s": args.duration,
                                   "plots": len(data.plots), "adsb": len(data.adsb), "datagrams": len(sched),
                                   "records_per_s": round((len(data.plots) + len(data.adsb)) / args.duration, 1)}}),
          flush=True)
    for speed in (float(s) for s in args.speeds.split(",")):
        print(json.dumps(one_run(args, sched, sites, speed)), flush=True)
    if args.kill_at is not None:
        print(json.dumps(one_run(args, sched, sites, float(args.speeds.split(",")[0]), args.kill_at)), flush=True)


if __name__ == "__main__":
    main()

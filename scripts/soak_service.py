"""Soak test of ``radartracker serve`` on loopback (127.0.0.1 only): days of feed in minutes (issue 33).

The feed is the ``tracking`` scenario (three radars and ADS-B), packed into datagrams as
``load_service.py`` packs them and repeated in segments with the clock moved on, each sent ``speed``
times faster than its own time to a service run as a child process, as systemd would run it. Between
and inside the segments, what an ATC unit meets:

* **A**, then a **full disk** for a while inside it (the service's RLIMIT_FSIZE lowered with
  ``prlimit``: every write to a file fails with an OSError, as on a full disk);
* an outage of **20 minutes**; **B** with three **spoofed** records (290 s ahead, inside the stream
  clock's 300 s; 1 h ahead; 600 s behind), then a **stop (SIGTERM) and restart** while the 290 s one
  still waits;
* an outage of **2 hours** (the same process); **C**, **kill -9** halfway and an immediate restart,
  then a **flood** of 64 kB junk datagrams and a **reorder attack** (valid plots sharing one time stamp
  1 s ahead of the stream, more than the reordering window holds);
* an outage of **2 days** across a stop, the newest checkpoint **corrupted** (one byte of its
  snapshot flipped); a restart with the day two days on; **D**, and **SIGTERM under full load** (D's
  second half sent as fast as the loopback takes it, SIGTERM at once).

What :func:`soak` returns (and ``main`` prints as JSON): per segment after an outage the share of its
records the tracker used (handed on, not refused as late, time jump, duplicate, overflow or over the
track bound); what the spoofs cost; the datagrams sent against those the service accounted (received =
decoded + malformed + dropped, all reasons; plus the kernel's drops, those lost to kill -9 — processed
after the last checkpoint — and those only the corrupted checkpoint accounted for, after the older one
the restart falls back to); the peak RSS through the flood and the attack; the
processing latency; the stop under load. Every wait is bounded.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import attrs

sys.path.insert(0, str(Path(__file__).resolve().parent))
from load_service import Listener, datagram_schedule, free_port, get, histogram_quantiles, scenario_records  # noqa: E402

from radartracker.io.asterix import sac_sic_of, write_sites  # noqa: E402
from radartracker.service.checkpoints import checkpoints  # noqa: E402
from radartracker.service.codec import blocks, cat048_bytes  # noqa: E402
from radartracker.simulation.scenarios import build_scenario  # noqa: E402

DAY = 86_400.0
REFUSED = ("_late", "_time_jump", "_duplicate", "_reorder_overflow", "_track_capacity", "_unknown_radar")


class Service:
    """``radartracker serve`` as a child process on loopback ports (``after``: a restart of that service, on
    its ports), its log collected from a pipe (a pipe, unlike a file, is not limited by RLIMIT_FSIZE)."""

    def __init__(self, work: Path, sites: Path, publish_port: int, day_start: float,
                 after: "Service | None" = None) -> None:
        self.port, self.http = (after.port, after.http) if after else (free_port(), free_port())
        cmd = [sys.executable, "-c", "import sys; from radartracker.cli import main; sys.exit(main())", "serve",
               "--radars", str(sites), "--listen", f"udp://127.0.0.1:{self.port}",
               "--publish", f"udp://127.0.0.1:{publish_port}", "--state", str(work / "state"),
               "--http", f"127.0.0.1:{self.http}", "--period", "1", "--checkpoint-s", "1", "--queue-mb", "64",
               "--day-start", repr(day_start)]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        self.log: list[str] = []
        threading.Thread(target=lambda: self.log.extend(self.proc.stderr), daemon=True).start()
        end = time.monotonic() + 180
        while self.health() is None:
            if self.proc.poll() is not None or time.monotonic() > end:
                raise RuntimeError(f"the service did not start (exit {self.proc.poll()}): {''.join(self.log)[-2000:]}")
            time.sleep(0.2)

    def health(self) -> dict | None:
        h = get(f"http://127.0.0.1:{self.http}/health", 2)
        return None if h is None else json.loads(h)

    def counters(self) -> dict[str, float]:
        """Every singly labelled counter of ``/metrics`` as ``"family:label"`` → value, and the whole text
        as ``"_text"`` (for the latency histogram)."""
        from prometheus_client.parser import text_string_to_metric_families

        text = get(f"http://127.0.0.1:{self.http}/metrics", 5) or ""
        out: dict = {"_text": text}
        for fam in text_string_to_metric_families(text):
            for s in fam.samples:
                if s.labels and len(s.labels) == 1 and "le" not in s.labels:
                    out[f"{fam.name}:{next(iter(s.labels.values()))}"] = s.value
        return out

    def settle(self, limit_s: float = 120.0) -> dict[str, float]:
        """Wait until the queue is empty and the records handed to the tracker stop changing."""
        end, last = time.monotonic() + limit_s, None
        while time.monotonic() < end:
            c = self.counters()
            h = self.health() or {}
            key = c.get("radartracker_records:records_to_tracker")
            if h.get("queue_depth") == 0 and key == last:
                return c
            last = key
            time.sleep(0.5)
        raise RuntimeError(f"the service did not settle: exit {self.proc.poll()}, health {self.health()}, "
                           f"log: {''.join(self.log)[-3000:]}")

    def peak_rss_mb(self) -> float:
        for line in Path(f"/proc/{self.proc.pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
        return float("nan")

    def stop(self, limit_s: float = 120.0) -> tuple[dict, float]:
        """SIGTERM; (summary.json, seconds until the process exited)."""
        t0 = time.monotonic()
        self.proc.send_signal(signal.SIGTERM)
        self.proc.wait(limit_s)
        took = time.monotonic() - t0
        state = Path(self.proc.args[self.proc.args.index("--state") + 1])
        return json.loads((state / "summary.json").read_text()), took

    def kill(self) -> None:
        os.kill(self.proc.pid, signal.SIGKILL)
        self.proc.wait(30)


class Feed:
    """The scenario's datagrams, shifted in time, sent to a service; counts what was sent."""

    def __init__(self, seg_s: float, seed: int, work: Path) -> None:
        self.data = build_scenario("tracking", seed=seed, duration=seg_s).run()
        self.sites = work / "radars.csv"
        self.sac_sic = sac_sic_of(self.data)
        write_sites(self.sites, self.data.radars, self.sac_sic)
        self.tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.datagrams = self.records = 0

    def segment(self, start: float) -> list[tuple[float, bytes, list]]:
        """The scenario's datagram schedule with its time moved to begin at ``start``."""
        d = self.data
        shift = start - float(min(d.plots.time.min(), d.adsb.time.min()))
        moved = attrs.evolve(d, plots=attrs.evolve(d.plots, time=d.plots.time + shift),
                             adsb=attrs.evolve(d.adsb, time=d.adsb.time + shift))
        return datagram_schedule(scenario_records(moved))

    def send(self, sched: list, port: int, speed: float, at: dict | None = None) -> None:
        """Send ``sched`` paced ``speed`` times faster than its own clock (0: at once); ``at``: callbacks
        {fraction of the schedule: function(time of the datagram next)} run when that far."""
        at = dict(sorted((at or {}).items()))
        t0, start = sched[0][0], time.monotonic()
        for k, (t, payload, keys) in enumerate(sched):
            while at and k >= next(iter(at)) * len(sched):
                at.pop(next(iter(at)))(t)
                t0, start = t, time.monotonic()  # a callback may take a while: the pace restarts here
            delay = start + (t - t0) / speed - time.monotonic() if speed > 0 else 0.0
            if delay > 0:
                time.sleep(delay)
            self.raw(port, payload, len(keys))

    def raw(self, port: int, payload: bytes, records: int = 0) -> None:
        self.tx.sendto(payload, ("127.0.0.1", port))
        self.datagrams += 1
        self.records += records

    def plots_at(self, t: float, n: int, port: int, step_s: float = 0.0) -> None:
        """``n`` distinct plots of the first radar from time ``t``, ``step_s`` apart (0: a reorder attack, all
        at one time), in full datagrams."""
        sac, sic = self.sac_sic[self.data.radars[0].id]
        # distinct at CAT048's resolution (1/256 NM, 360/2^16 degrees): 4 096 azimuths × 8 m range steps
        recs = [cat048_bytes(t + step_s * j, sac, sic, 20_000.0 + 8.0 * (j // 4096), 4.0 + 1e-4 * (j % 4096))
                for j in range(n)]
        for block in blocks(48, recs, 1472):
            self.raw(port, block, (len(block) - 3) // len(recs[0]))


def accounted(counters: dict) -> int:
    """The datagrams a service's counters (``/metrics``, as :meth:`Service.counters` reads them) account for:
    received, or dropped by the kernel before reaching the socket's reader."""
    return int(counters.get("radartracker_datagrams:received", 0) + counters.get("radartracker_datagrams:dropped_kernel", 0))


def used_share(before: dict, after: dict, sent: int) -> dict:
    """What the tracker did with the ``sent`` records of a segment (counter deltas)."""
    delta = {k.split(":", 1)[1]: after.get(k, 0) - before.get(k, 0) for k in after
             if k.startswith("radartracker_tracker_inputs:")}
    refused = {k: int(v) for k, v in delta.items() if v and k.endswith(REFUSED)}
    return {"records": sent, "refused": refused, "used_share": round(1 - sum(refused.values()) / sent, 4)}


def spoof(feed: Feed, port: int, t: float) -> None:
    """Three spoofed plots of the first radar among a stream at time ``t``: 290 s ahead (inside the stream
    clock's 300 s), 1 h ahead and 600 s behind."""
    sac, sic = feed.sac_sic[feed.data.radars[0].id]
    for dt in (290.0, 3600.0, -600.0):
        feed.raw(port, blocks(48, [cat048_bytes(t + dt, sac, sic, 30_000.0, 1.0)], 1472)[0], 1)


def wait_checkpoint_after(state: Path, t: float, limit_s: float = 300.0) -> None:
    """Wait until a complete checkpoint written after wall time ``t`` exists. A periodic checkpoint is
    skipped while the previous one is still being written (seconds for thousands of tracks, more under load)
    and one in progress at a stop is superseded, so the checkpoint before the final one can predate the
    inputs just processed; a resume from it replays them, and their refusals would be counted as the next
    segment's."""
    end = time.monotonic() + limit_s
    while time.monotonic() < end:
        done = checkpoints(state)
        if done and json.loads((done[-1][1] / "service.json").read_text())["written"] > t:
            return
        time.sleep(0.5)
    raise RuntimeError(f"no checkpoint written within {limit_s:g} s after the segment settled")


def flip_newest_checkpoint(state: Path) -> str:
    """Flip one byte in the middle of the newest checkpoint's manager snapshot; its name."""
    newest = checkpoints(state)[-1][1]  # numbered in numeric order
    snap = newest / "manager.snapshot"
    b = bytearray(snap.read_bytes())
    b[len(b) // 2] ^= 0xFF
    snap.write_bytes(bytes(b))
    return newest.name


def full_disk(pid: int, on: bool) -> None:
    """Writes to files by ``pid`` fail (RLIMIT_FSIZE 0, as a full disk fails them) or work again."""
    inf = resource.RLIM_INFINITY
    resource.prlimit(pid, resource.RLIMIT_FSIZE, (0, inf) if on else (inf, inf))


def segment_a(feed: Feed, svc: Service, listener: Listener, start: float, speed: float, out: dict) -> None:
    """The first segment, with a full disk from 30 % to 70 % of it."""
    seen: dict = {}

    def disk_on(_t: float) -> None:
        full_disk(svc.proc.pid, True)
        seen["cat062_before"] = len(listener.got)
        seen["t"] = time.monotonic()

    def disk_off(_t: float) -> None:
        end = time.monotonic() + 10
        while (svc.health() or {}).get("status") != "degraded" and time.monotonic() < end:
            time.sleep(0.2)
        seen["health"] = svc.health()
        seen["cat062_during"] = len(listener.got) - seen["cat062_before"]
        full_disk(svc.proc.pid, False)
        seen["full_s"] = round(time.monotonic() - seen["t"], 1)

    before = svc.settle()
    sched = feed.segment(start)
    feed.send(sched, svc.port, speed, at={0.3: disk_on, 0.7: disk_off})
    after = svc.settle()
    end = time.monotonic() + 10
    while (svc.health() or {}).get("status") != "ok" and time.monotonic() < end:
        time.sleep(0.2)
    out["A"] = used_share(before, after, sum(len(d[2]) for d in sched)) | {"full_disk": {
        "seconds": seen["full_s"], "health_during": seen["health"]["status"],
        "reason": seen["health"].get("reason"), "cat062_datagrams_during": seen["cat062_during"],
        "health_after": (svc.health() or {}).get("status"),
        "checkpoints_failed": int(after.get("radartracker_checkpoints:failed", 0)),
        "state_writes_failed": int(after.get("radartracker_records:state_writes_failed", 0))}}


def segment_b(feed: Feed, holder: dict, start: float, speed: float, out: dict) -> None:
    """After 20 min: spoofs at 30 %, then a stop and a restart while the 290 s one waits."""
    svc = holder["svc"]
    seen: dict = {}

    def spoof_and_restart(t: float) -> None:
        spoof(feed, holder["svc"].port, t)
        c = holder["svc"].settle()
        seen["tracks_before_stop"] = (holder["svc"].health() or {}).get("tracks")
        summary, took = holder["svc"].stop()
        seen["stop_s"] = round(took, 1)
        seen["tracks_at_stop"] = summary["tracks_by_status"]
        seen["counts_at_stop"] = c
        holder["svc"] = Service(holder["work"], feed.sites, holder["publish"], 0.0, holder["svc"])
        seen["tracks_after_restart"] = (holder["svc"].health() or {}).get("tracks")

    before = svc.settle()
    sched = feed.segment(start)
    feed.send(sched, svc.port, speed, at={0.3: spoof_and_restart})
    after = holder["svc"].settle()
    share = used_share(before, after, sum(len(d[2]) for d in sched) + 3)
    by_time = sum(v for k, v in share["refused"].items() if k.endswith(("_late", "_time_jump")))
    out["B_after_20_min"] = share | {"spoofs": 3, "refused_by_time": by_time} | seen


def segment_c(feed: Feed, holder: dict, start: float, speed: float, flood: int, attack: int, out: dict) -> None:
    """After 2 h: kill -9 at half, restart; then a flood and a reorder attack at three quarters."""
    sched = feed.segment(start)
    half, three_q = len(sched) // 2, 3 * len(sched) // 4
    before = holder["svc"].settle()
    feed.send(sched[:half], holder["svc"].port, speed)
    sent_before_kill = feed.datagrams
    holder["svc"].kill()
    holder["svc"] = svc = Service(holder["work"], feed.sites, holder["publish"], 0.0, holder["svc"])
    resumed = svc.counters()
    lost = sent_before_kill - accounted(resumed)
    base = svc.settle()
    feed.send(sched[half:three_q], svc.port, speed)
    mid = svc.settle()
    rss_before = svc.peak_rss_mb()
    junk = os.urandom(64_000)
    for k in range(flood):
        feed.raw(svc.port, bytes([48, 0xFA, 0x00]) + junk[k % 7:])
    feed.plots_at(sched[three_q][0] + 1.0, attack, svc.port)
    feed.send(sched[three_q:], svc.port, speed)
    after = svc.settle(600)
    out["C_after_2_h"] = used_share(base, mid, sum(len(d[2]) for d in sched[half:three_q])) | {
        "kill_9": {"datagrams_sent_before": sent_before_kill - int(before.get("radartracker_datagrams:received", 0)),
                   "datagrams_lost_after_last_checkpoint": lost},
        "flood": {"datagrams": flood, "bytes_each": 64_003, "attack_plots_at_one_time": attack,
                  "dropped_queue_full": int(after.get("radartracker_datagrams:dropped_queue_full", 0)
                                            - mid.get("radartracker_datagrams:dropped_queue_full", 0)),
                  "malformed": int(after.get("radartracker_datagrams:malformed", 0)
                                   - mid.get("radartracker_datagrams:malformed", 0)),
                  "reorder_overflow": int(after.get("radartracker_tracker_inputs:plots_reorder_overflow", 0)),
                  "track_capacity": int(after.get("radartracker_tracker_inputs:plots_track_capacity", 0)),
                  "peak_rss_mb_before": round(rss_before, 1), "peak_rss_mb_after": round(svc.peak_rss_mb(), 1)},
        "processing_latency_s": histogram_quantiles(after["_text"])}
    out["lost_to_kill_9"] = lost


def segment_d(feed: Feed, holder: dict, start: float, speed: float, load: int, out: dict) -> dict:
    """After 2 days across a stop and a corrupted newest checkpoint: D, then SIGTERM under full load (D's
    second half and ``load`` new plots sent at once)."""
    state = holder["work"] / "state"
    holder["svc"].settle()
    wait_checkpoint_after(state, time.time())  # the checkpoint D falls back to holds all of C
    summary, took = holder["svc"].stop()
    damaged = flip_newest_checkpoint(state)
    holder["svc"] = svc = Service(holder["work"], feed.sites, holder["publish"], 2 * DAY, holder["svc"])
    resumed = (svc.health() or {}).get("resumed_from")
    # the datagrams only the corrupted checkpoint accounted for (those after the older one it falls back to)
    out["lost_to_corrupted_checkpoint"] = (summary["datagrams"]["received"] + summary["datagrams"].get("dropped_kernel", 0)
                                           - accounted(svc.counters()))
    sched = feed.segment(start)
    half = len(sched) // 2
    before = svc.settle()
    feed.send(sched[:half], svc.port, speed)
    after = svc.settle()
    feed.send(sched[half:], svc.port, 0)
    feed.plots_at(sched[-1][0] + 1.0, load, svc.port, 0.001)  # distinct plots, each a new track: a backlog
    time.sleep(0.5)
    backlog = (svc.health() or {}).get("queue_depth")
    final, stop_s = svc.stop()
    ck = state / final["last_checkpoint"]
    out["D_after_2_days"] = used_share(before, after, sum(len(d[2]) for d in sched[:half])) | {
        "stop_before_outage_s": round(took, 1), "corrupted": damaged, "resumed_from": resumed,
        "checkpoints_skipped_damaged": final["checkpoints"].get("skipped_damaged", 0)}
    out["stop_under_load"] = {"seconds": round(stop_s, 1), "phases_s": final.get("stop_s"), "queue_depth_at_sigterm": backlog,
                              "final_checkpoint": final["last_checkpoint"],
                              "final_checkpoint_whole": (ck / "manager.snapshot").exists() and (ck / "service.json").exists(),
                              "datagrams_dropped_at_stop": final["datagrams"].get("dropped_at_stop", 0)}
    return final


def soak(seg_s: float = 120.0, speed: float = 40.0, flood: int = 2_000, attack: int = 120_000, seed: int = 1,
         work: Path | None = None) -> dict:
    """Run the whole soak (module docstring); the figures as a dict."""
    work = Path(work or tempfile.mkdtemp(prefix="soak_service_"))
    feed = Feed(seg_s, seed, work)
    listener = Listener()
    listener.start()
    holder = {"work": work, "publish": listener.port}
    out: dict = {"segment_s": seg_s, "speed": speed}
    t0 = 10 * 3600.0
    b, c = t0 + seg_s + 1200.0, t0 + 2 * seg_s + 1200.0 + 7200.0
    d = c + seg_s + 2 * DAY
    t_start = time.monotonic()
    try:
        holder["svc"] = Service(work, feed.sites, listener.port, 0.0)
        segment_a(feed, holder["svc"], listener, t0, speed, out)
        segment_b(feed, holder, b, speed, out)
        segment_c(feed, holder, c, speed, flood, attack, out)
        final = segment_d(feed, holder, d, speed, attack // 4, out)
    except Exception:
        print(json.dumps(out, indent=1, default=str), file=sys.stderr)
        raise
    finally:
        svc = holder.get("svc")
        if svc is not None and svc.proc.poll() is None:
            svc.kill()
        listener.halt.set()
    dg = final["datagrams"]
    out["accounting"] = {"datagrams_sent": feed.datagrams, "received": dg["received"],
                         "decoded": dg.get("decoded", 0), "malformed": dg.get("malformed", 0),
                         "dropped_queue_full": dg.get("dropped_queue_full", 0),
                         "dropped_at_stop": dg.get("dropped_at_stop", 0), "dropped_kernel": dg.get("dropped_kernel", 0),
                         "lost_to_kill_9": out["lost_to_kill_9"],
                         "lost_to_corrupted_checkpoint": out["lost_to_corrupted_checkpoint"]}
    out["accounting"]["unaccounted"] = (feed.datagrams - dg["received"] - dg.get("dropped_kernel", 0)
                                        - out["lost_to_kill_9"] - out["lost_to_corrupted_checkpoint"])
    out["wall_s"] = round(time.monotonic() - t_start, 1)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--segment-s", type=float, default=1800.0, help="seconds of feed per segment")
    ap.add_argument("--speed", type=float, default=20.0, help="feed time per wall second")
    ap.add_argument("--flood", type=int, default=20_000, help="junk datagrams of 64 kB")
    ap.add_argument("--attack", type=int, default=300_000, help="plots sharing one time stamp")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    print(json.dumps(soak(args.segment_s, args.speed, args.flood, args.attack, args.seed), indent=1))


if __name__ == "__main__":
    main()

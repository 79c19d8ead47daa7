"""Latency of ``radartracker serve`` on one dedicated core, measured on a shared machine: a CPU-time replay.

On a machine shared by many processes the service gets a fraction of a core, so wall-clock
latencies measure the sharing, not the service. This script runs the service's own tracker loop
(:class:`radartracker.service.Service`: ``_handle`` per datagram — decode, TrackManager, on-update
CAT062 — and its periodic publication and view refresh) over the datagrams that
``scripts/load_service.py`` sends (the same packing), in one thread, and times each step with the
thread's CPU clock (``time.thread_time``, which does not advance while the thread waits for a core).
A single-server queue then gives when each step would finish on a core of its own:

    start_i = max(arrival_i, finish_{i−1}),   finish_i = start_i + cpu_i,

arrival_i = (time of the datagram's last record − the first's) / speed. A CAT062 sent during step j
leaves at finish_j; a record's end-to-end latency is, as in load_service.py, its datagram's arrival →
the first CAT062 for its aircraft (I380) with a track time at or after the record's. Left out: the
socket reader thread (tens of µs per datagram, measured apart in load_service.py's CPU total) and
the forked checkpoints. The first ``--warmup-s`` of the recording are replayed once, untimed, so
that compiled kernels (numba) are compiled and cached before the timed runs. CPU times measured
under contention are inflated by cache sharing, so the latencies are upper bounds for an idle core.
One JSON line per frame, reorder window and publish mode.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from load_service import cat062_updates, datagram_schedule, end_to_end, free_port, recording_records

from radartracker.io.asterix_reader import read_cat062, read_sites
from radartracker.io.scenario import read_scenario
from radartracker.service import Service, ServiceConfig, parse_endpoint
from radartracker.service.score import score_cat062


class Capture:
    """Stands in for the publisher's socket: keeps each datagram with the step that sent it."""

    def __init__(self) -> None:
        self.step = 0
        self.sent: list[tuple[int, bytes]] = []

    def send(self, payload: bytes) -> int:
        self.sent.append((self.step, payload))
        return len(payload)

    def close(self) -> None:
        pass


def replay(sched, radars, sites, mode: str, window: float, frame: float, period: float, speed: float,
           scenario: Path | None) -> dict:
    listen = parse_endpoint(f"udp://127.0.0.1:{free_port()}")
    cfg = ServiceConfig((listen,), parse_endpoint(f"udp://127.0.0.1:{free_port()}"),
                        Path(tempfile.mkdtemp(prefix="latency_replay_")), period_s=period, day_start=0.0,
                        publish_mode=mode)
    svc = Service(cfg, radars, sites, manager={"reorder_window_s": window, "frame_s": frame})
    for sock in svc.sockets.values():
        sock.close()
    svc.publisher.sock.close()
    svc.publisher.sock = cap = Capture()
    t0 = sched[0][0]
    arrival = np.array([(t - t0) / speed for t, _, _ in sched])
    finish: list[float] = []
    cpu_handle = cpu_other = 0.0
    free, next_pub, next_view = 0.0, period, 0.5

    def step(fn, at: float) -> float:
        cap.step = len(finish)
        c0 = time.thread_time()
        fn()
        c = time.thread_time() - c0
        finish.append(max(at, free) + c)
        return c

    wall0 = time.monotonic()
    for i, (_, payload, _) in enumerate(sched):
        while max(arrival[i], free) >= next_pub:  # the loop's periodic work falls due before this datagram
            cpu_other += step(lambda: svc._publish(send=mode != "update"), next_pub)
            free, next_pub = finish[-1], next_pub + period
        if max(arrival[i], free) >= next_view:
            cpu_other += step(svc._refresh_view, next_view)
            free, next_view = finish[-1], next_view + 0.5
        cpu_handle += step(lambda: svc._handle(float(arrival[i]), time.monotonic(), listen, payload), arrival[i])
        free = finish[-1]
    fin = np.array(finish)
    got = [(float(fin[s]), b) for s, b in cap.sent]
    records = sum(len(k) for _, _, k in sched)
    data_s = float(arrival[-1]) * speed
    cpu = cpu_handle + cpu_other
    tracker = svc.manager.accounting()
    return {"publish_mode": mode, "reorder_window_s": svc.manager.config.reorder_window_s,
            "frame_s": svc.manager.config.frame_s, "period_s": period, "speed": speed, "data_s": round(data_s, 1),
            "records": records, "cpu_s": round(cpu, 1), "cpu_ms_per_record": round(cpu / records * 1e3, 3),
            "cpu_share_publishing_and_views": round(cpu_other / cpu, 3),
            "one_core_real_time_factor": round(data_s / speed / cpu, 2) if cpu else None,
            "core_busy": round(cpu / max(fin[-1], float(arrival[-1])), 2),
            "backlog_at_end_s": round(max(0.0, fin[-1] - arrival[-1]), 2),
            "inputs_late": tracker.get("plots_late", 0) + tracker.get("adsb_late", 0),
            "end_to_end_latency_s": end_to_end(sched, arrival, cat062_updates(got)),
            "cat062_records": svc.publisher.counts["cat062_records"],
            "estimator": svc.manager.config.estimator, "motion_model": svc.manager.config.motion_model,
            "replay_wall_s": round(time.monotonic() - wall0, 1), "load_avg": os.getloadavg()} | score(got, scenario)


def score(got: list[tuple[float, bytes]], scenario: Path | None) -> dict:
    """The published tracks against the scenario's truth (``radartracker score``'s metrics)."""
    if scenario is None:
        return {}
    with tempfile.NamedTemporaryFile(suffix=".ast") as f:
        f.write(b"".join(b for _, b in got))
        f.flush()
        m = score_cat062(read_cat062(f.name), read_scenario(scenario))
    return {"score": {k: m[k] for k in ("confirmed_tracks", "continuity_min", "swaps", "breaks", "false_tracks",
                                        "position_rmse_m")}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("recording", type=Path, help="CAT048/CAT021 recording from asterix-export (.radars.csv beside it)")
    ap.add_argument("--modes", default="update,both,periodic", help="publish modes, comma separated")
    ap.add_argument("--windows", default="0.3,2", help="reorder windows (s), comma separated")
    ap.add_argument("--frames", default="0.5", help="tracker frame lengths (s), comma separated")
    ap.add_argument("--scenario", type=Path, default=None,
                    help="the simulated scenario folder the recording was exported from: score the output against its truth")
    ap.add_argument("--period", type=float, default=4.0)
    ap.add_argument("--speed", type=float, default=1.0)
    ap.add_argument("--max-data-s", type=float, default=math.inf, help="replay only this many seconds of the recording")
    ap.add_argument("--warmup-s", type=float, default=10.0, help="seconds of the recording replayed untimed first")
    args = ap.parse_args()
    radars, sites = read_sites(Path(f"{args.recording}.radars.csv"))
    sched = datagram_schedule(recording_records(args.recording))
    sched = [d for d in sched if d[0] - sched[0][0] <= args.max_data_s]
    print(json.dumps({"recording": str(args.recording), "datagrams": len(sched),
                      "records": sum(len(k) for _, _, k in sched), "cpus": os.cpu_count(),
                      "load_avg": os.getloadavg()}), flush=True)
    warm = [d for d in sched if d[0] - sched[0][0] <= args.warmup_s]
    replay(warm, radars, sites, "both", 2.0, 0.5, args.period, args.speed, None)
    for frame in (float(f) for f in args.frames.split(",")):
        for window in (float(w) for w in args.windows.split(",")):
            for mode in args.modes.split(","):
                print(json.dumps(replay(sched, radars, sites, mode, window, frame, args.period, args.speed,
                                        args.scenario)), flush=True)


if __name__ == "__main__":
    main()

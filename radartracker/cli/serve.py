"""CLI commands ``serve`` (the live surveillance service, docs/service.md), ``send`` (a recording
replayed onto the network) and ``score`` (a CAT062 capture scored against a scenario's truth) —
registered through ``radartracker.commands`` entry points."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from pathlib import Path

from radartracker.errors import ConfigurationError


def _host_port(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or not 0 <= int(port) <= 65_535:
        raise argparse.ArgumentTypeError(f"expected HOST:PORT with a port in 0..65535, got {text!r}")
    return host, int(port)


def register_serve(sub: argparse._SubParsersAction) -> None:
    from radartracker.cli.convert import _day_start

    p = sub.add_parser("serve", help="live service: ASTERIX CAT048/CAT021 over UDP in, CAT062 system tracks out")
    p.add_argument("--radars", type=Path, required=True,
                   help="radar sites CSV with sac and sic columns (as asterix-export writes beside its file)")
    p.add_argument("--listen", action="append", required=True, metavar="udp://HOST:PORT",
                   help="where CAT048/CAT021 datagrams arrive (a multicast group is joined); repeatable")
    p.add_argument("--publish", required=True, metavar="udp://HOST:PORT", help="where CAT062 system tracks go")
    p.add_argument("--state", type=Path, required=True, metavar="DIR",
                   help="checkpoints, biases.json, summary.json; resumes from its latest checkpoint")
    p.add_argument("--http", type=_host_port, default=None, metavar="HOST:PORT",
                   help="serve /health, /tracks, /biases and /metrics (Prometheus) here")
    p.add_argument("--estimator", default=None, help="estimator plugin (default: the best installed exact one, "
                                                     "coupled-sparse; on resume: the checkpoint's)")
    p.add_argument("--motion-model", default=None, help="track motion model plugin (default imm; on resume: the checkpoint's)")
    p.add_argument("--period", type=float, default=4.0,
                   help="seconds between periodic CAT062 publications of every track (default 4)")
    p.add_argument("--publish-mode", choices=("update", "periodic", "both"), default="both",
                   help="CAT062 on each track update (as soon as the tracker's frame is processed), every "
                        "--period, or both (default both: docs/service.md)")
    p.add_argument("--reorder-window", type=float, default=None, metavar="S",
                   help="seconds the tracker holds inputs to put them in time order (default 0.5 for live data; "
                        "a replay's is 2; on resume: the checkpoint's); inputs more out of order can be counted "
                        "as plots_late/adsb_late")
    p.add_argument("--frame-s", type=float, default=None, metavar="S",
                   help="seconds of input the tracker processes together (default 0.25 for live data; a replay's "
                        "is 0.5; on resume: the checkpoint's); an input waits for the end of its frame")
    p.add_argument("--checkpoint-s", type=float, default=60.0, help="seconds between checkpoints (default 60)")
    p.add_argument("--queue", type=int, default=50_000, help="datagrams the queue holds before dropping (default 50000)")
    p.add_argument("--queue-mb", type=float, default=256.0,
                   help="payload MiB the queue holds before dropping (default 256; 0.0625 to 8192)")
    p.add_argument("--day-start", type=_day_start, default=None, metavar="DATE|SECONDS",
                   help="UTC day of the first record, for a replayed recording (default: the receive clock)")
    p.add_argument("--sac", type=int, default=0, help="SAC of this tracker in CAT062 I010 (default 0)")
    p.add_argument("--sic", type=int, default=100, help="SIC of this tracker in CAT062 I010 (default 100)")
    p.add_argument("--interface", default="0.0.0.0",
                   help="IPv4 address of the interface that joins the listened multicast groups and sends to a "
                        "multicast --publish (127.0.0.1: the loopback)")
    p.add_argument("--allow-from", action="append", default=[], metavar="IP",
                   help="take datagrams only from this IPv4 address (repeatable; default: any sender); the others "
                        "are counted as datagrams refused_sender")
    p.set_defaults(func=_cmd_serve)


def _cmd_serve(args: argparse.Namespace) -> int:
    from radartracker.io.asterix_reader import read_sites
    from radartracker.settings import check_number
    from radartracker.service import Service, ServiceConfig, parse_endpoint

    radars, sites = read_sites(args.radars)
    if not radars:
        raise ConfigurationError(f"{args.radars}: no radar")
    try:
        config = ServiceConfig(tuple(parse_endpoint(e) for e in args.listen), parse_endpoint(args.publish), args.state,
                               args.http, args.period, args.checkpoint_s, args.queue,
                               int(check_number("--queue-mb", args.queue_mb, lo=0.0625, hi=8192.0) * (1 << 20)),
                               args.day_start, args.sac, args.sic, args.interface, args.publish_mode,
                               tuple(args.allow_from))
    except ValueError as exc:
        raise ConfigurationError(f"bad option: {exc}") from None
    # the tracker's own settings, bounded here: a frame of 0 s divided by zero only once the service ran
    if args.frame_s is not None:
        check_number("--frame-s", args.frame_s, lo=0.0, lo_open=True, hi=60.0)
    if args.reorder_window is not None:
        check_number("--reorder-window", args.reorder_window, lo=0.0, hi=3_600.0)
    stop = threading.Event()  # a signal during the start still gets a clean stop
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    manager = {k: v for k, v in (("reorder_window_s", args.reorder_window), ("frame_s", args.frame_s)) if v is not None}
    service = Service(config, radars, sites, estimator=args.estimator, motion_model=args.motion_model, manager=manager)
    print(json.dumps({"serving": [str(e) for e in config.listen], "publish": str(config.publish),
                      "estimator": service.manager.config.estimator, "resumed_from": service.resumed_from,
                      "checkpoints_skipped": service.skipped_checkpoints}),
          file=sys.stderr, flush=True)
    summary = service.run(stop)
    print(json.dumps({k: summary[k] for k in ("datagrams", "records", "tracker", "published", "last_checkpoint")}))
    return 0


def register_send(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("send", help="replay an ASTERIX recording onto the network with its original timing")
    p.add_argument("recording", type=Path, help="raw ASTERIX blocks (.ast), FINAL format or pcap")
    p.add_argument("--to", required=True, metavar="udp://HOST:PORT", help="destination (unicast or multicast)")
    p.add_argument("--speed", type=float, default=1.0,
                   help="time scale: 1 real time, 10 ten times faster, 0 as fast as possible (default 1)")
    p.add_argument("--interface", default="0.0.0.0",
                   help="IPv4 address of the interface a multicast --to is sent from (127.0.0.1: the loopback)")
    p.set_defaults(func=_cmd_send)


def _cmd_send(args: argparse.Namespace) -> int:
    from radartracker.settings import check_number
    from radartracker.service import parse_endpoint
    from radartracker.service.sender import send

    # 0: as fast as possible; else a time scale a recording's timing survives (1e-300 overflowed the waits)
    if check_number("--speed", args.speed, lo=0.0, hi=1e6) != 0.0 and args.speed < 1e-3:
        raise ConfigurationError(f"--speed: {args.speed!r} must be 0 (as fast as possible) or >= 0.001")
    try:
        sent = send(args.recording, parse_endpoint(args.to), args.speed, args.interface)
    except ValueError as exc:  # a malformed recording: the reader names file and byte offset
        raise ConfigurationError(str(exc)) from None
    print(json.dumps(sent))
    return 0


def register_score(sub: argparse._SubParsersAction) -> None:
    from radartracker.cli.convert import _day_start

    p = sub.add_parser("score", help="score a CAT062 capture (e.g. the service's output) against a scenario's truth")
    p.add_argument("capture", type=Path, help="CAT062 recording: raw ASTERIX blocks, FINAL format or pcap")
    p.add_argument("--scenario", type=Path, required=True,
                   help="the simulated scenario folder the tracked data came from (with truth and plot labels)")
    p.add_argument("--day-start", type=_day_start, default=0.0, metavar="DATE|SECONDS",
                   help="UTC day of the capture's first record, as given to serve (default 0; a pcap's own stamps win)")
    p.set_defaults(func=_cmd_score)


def _cmd_score(args: argparse.Namespace) -> int:
    from radartracker.io.asterix_reader import read_cat062
    from radartracker.io.scenario import read_scenario
    from radartracker.service.score import score_cat062

    try:
        records = read_cat062(args.capture, day_start=args.day_start)
    except ValueError as exc:  # a malformed capture: the reader names file and byte offset
        raise ConfigurationError(str(exc)) from None
    if not records:
        raise ConfigurationError(f"{args.capture}: no CAT062 track record")
    metrics = score_cat062(records, read_scenario(args.scenario))
    print(json.dumps({"records": len(records)} | metrics, default=float))
    return 0

"""The ``radartracker`` command line.

Sub-commands are discovered through the entry-point group ``radartracker.commands``: each entry
point names a function ``register(subparsers)`` that adds one sub-parser and sets ``func`` (a
callable taking the parsed ``argparse.Namespace`` and returning an exit code). The built-in
commands are registered in ``pyproject.toml`` exactly like a plugin's.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from importlib.metadata import entry_points
from pathlib import Path

from radartracker.errors import ConfigurationError, RadarTrackerError

COMMAND_GROUP = "radartracker.commands"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radartracker",
        description="Multi-radar surveillance: tracking with radar bias estimation.",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    parser.add_argument("--debug", action="store_true", help="show the traceback of every error")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for ep in sorted(entry_points(group=COMMAND_GROUP), key=lambda e: e.name):
        try:
            register = ep.load()
        except Exception as exc:  # a broken plugin must not take the whole CLI down
            print(f"radartracker: warning: command {ep.name!r} ({ep.value}) not loaded: {exc}", file=sys.stderr)
            continue
        register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        return int(args.func(args) or 0)
    except (RadarTrackerError, OSError) as exc:
        if isinstance(exc, BrokenPipeError):  # `radartracker compare | head`: the reader left
            sys.stderr.close()
            return 0
        if args.debug:
            raise
        print(f"radartracker {args.command}: error: {exc}", file=sys.stderr)
        return 2


# --- built-in commands -------------------------------------------------------------------------


def register_estimators(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("estimators", help="list the installed estimator, motion-model and reconstructor plugins with their options")
    p.set_defaults(func=_cmd_estimators)


def _cmd_estimators(args: argparse.Namespace) -> int:
    from radartracker.registry import plugin_listing

    print(plugin_listing())
    return 0


def register_simulate(sub: argparse._SubParsersAction) -> None:
    from radartracker.simulation.scenarios import STANDARD_SCENARIOS

    p = sub.add_parser("simulate", help="simulate a multi-radar scenario into a scenario folder")
    p.add_argument("out", type=Path, help="scenario folder to write (must not exist)")
    p.add_argument("--scenario", default="seed", choices=sorted([*STANDARD_SCENARIOS, "traffic"]),
                   help="built-in scenario (default: seed); 'traffic': national traffic of any size")
    p.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    p.add_argument("--duration", type=float, default=None, help="seconds to simulate")
    traffic = p.add_argument_group("traffic scenario (radartracker.simulation.traffic)")
    traffic.add_argument("--aircraft", type=int, help="mean number of airborne aircraft (default 200)")
    traffic.add_argument("--radars", type=int, help="number of radars on a 200 km grid (default 28)")
    traffic.add_argument("--adsb-share", type=float, help="share of aircraft with ADS-B (default 0.3)")
    traffic.add_argument("--primary-share", type=float, help="share of primary-only aircraft (default 0)")
    p.set_defaults(func=_cmd_simulate)


def _cmd_simulate(args: argparse.Namespace) -> int:
    from radartracker.io.scenario import write_scenario
    from radartracker.simulation.scenarios import build_scenario

    if args.out.exists():
        raise ConfigurationError(f"{args.out} already exists; choose a new folder")
    options = {k: getattr(args, k) for k in ("aircraft", "radars", "adsb_share", "primary_share")
               if getattr(args, k) is not None}
    if args.scenario == "traffic":
        from radartracker.simulation.traffic import traffic_scenario

        scenario = traffic_scenario(seed=args.seed, duration=args.duration, **options)
    elif options:
        raise ConfigurationError(f"--{next(iter(options)).replace('_', '-')} applies to --scenario traffic only")
    else:
        scenario = build_scenario(args.scenario, seed=args.seed, duration=args.duration)
    data = scenario.run()
    write_scenario(args.out, data)
    print(f"wrote {args.out}: {len(data.radars)} radars, {len(data.plots)} plots, "
          f"{len(data.adsb)} ADS-B reports")
    return 0


def register_replay(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="replay a scenario folder through an estimator")
    p.add_argument("scenario", type=Path, help="scenario folder (see docs/formats.md)")
    p.add_argument("--estimator", default="decoupled", help="estimator plugin name")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--q", type=float, default=None, help="process noise density q (m²/s³; default 5, 0 is the seed's noiseless model)")
    p.add_argument("--skip-bad", action="store_true",
                   help="skip (and count) malformed input rows instead of stopping")
    p.add_argument("--plots", action="store_true", help="write figures (bias estimates over time)")
    p.add_argument("--manager", action="store_true",
                   help="associate with the TrackManager even when plots carry truth labels")
    p.add_argument("--motion-model", default="cv", help="TrackManager motion model plugin (cv, imm, adaptive, ...)")
    p.set_defaults(func=_cmd_replay)


def _cmd_replay(args: argparse.Namespace) -> int:
    from radartracker.io.sources import read_source

    data = read_source(args.scenario, skip_bad=args.skip_bad)
    if args.manager or not data.plots.has_truth_labels:
        from radartracker.tracking.manager import ManagerConfig
        from radartracker.pipeline.track_replay import track_replay, write_track_outputs

        config = ManagerConfig(estimator=args.estimator, motion_model=args.motion_model)
        tresult = track_replay(data, config)
        write_track_outputs(tresult, args.out, figures=args.plots)
        summary = tresult.summary()
        print(json.dumps({k: summary[k] for k in ("counts", "biases")} | {"tracking": summary.get("tracking")},
                         indent=1, default=str))
    else:
        from radartracker.pipeline.replay import ReplayOptions, replay, write_outputs

        result = replay(data, args.estimator, ReplayOptions.for_scenario(data, q=args.q))
        write_outputs(result, args.out, figures=args.plots)
        print(result.summary_table())
    print(f"outputs in {args.out}")
    return 0


def register_demo(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="simulate and replay a built-in scenario; print true vs estimated biases")
    p.add_argument("--estimator", default=None, help="estimator plugin (default: the best installed)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", type=Path, default=None, help="also keep the scenario and outputs here")
    p.set_defaults(func=_cmd_demo)


def _cmd_demo(args: argparse.Namespace) -> int:
    import tempfile

    from radartracker.io.scenario import write_scenario
    from radartracker.io.sources import read_source
    from radartracker.registry import available_estimators
    from radartracker.pipeline.replay import ReplayOptions, replay, write_outputs
    from radartracker.simulation.scenarios import build_scenario

    installed = available_estimators()
    name = args.estimator or next(
        (n for n in ("coupled-sparse", "coupled", "blom", "decoupled") if n in installed), installed[0]
    )
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out or Path(tmp)
        scen_dir = root / "scenario"
        data = build_scenario("demo", seed=args.seed).run()
        write_scenario(scen_dir, data)
        data = read_source(scen_dir)  # through the public file format, as a user would
        print(f"demo: scenario 'demo' ({len(data.radars)} radars, {len(data.plots)} plots, "
              f"{len(data.adsb)} ADS-B reports), estimator '{name}'")
        result = replay(data, name, ReplayOptions.for_scenario(data))
        write_outputs(result, root / "replay", figures=args.out is not None)
        print(result.summary_table())
    return 0

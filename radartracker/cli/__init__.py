"""The ``radartracker`` command line.

Sub-commands are discovered through the entry-point group ``radartracker.commands``: each entry
point names a function ``register(subparsers)`` that adds one sub-parser and sets ``func`` (a
callable taking the parsed ``argparse.Namespace`` and returning an exit code). The built-in
commands are registered in ``pyproject.toml`` exactly like a plugin's.
"""

from __future__ import annotations

import argparse
import copy
import functools
import logging
import os
import sys
from collections.abc import Callable
from importlib.metadata import entry_points
from pathlib import Path

from radartracker.cli.replay import register_demo, register_replay  # noqa: F401 (entry points name them here)
from radartracker.entrypoints import path_state
from radartracker.errors import ConfigurationError, RadarTrackerError
from radartracker.settings import SCENARIOS

COMMAND_GROUP = "radartracker.commands"


def build_parser() -> argparse.ArgumentParser:
    """A new parser of the command line: the common options and one sub-command per entry point of
    :data:`COMMAND_GROUP` (in name order; one that fails to load is left out with a warning)."""
    registers, warnings = _commands()
    for w in warnings:
        print(w, file=sys.stderr)
    return _new_parser(registers)


def _commands() -> tuple[list[Callable[[argparse._SubParsersAction], None]], list[str]]:
    """The ``register`` functions of :data:`COMMAND_GROUP`'s entry points in name order, and a warning for
    each entry point that failed to load."""
    registers, warnings = [], []
    for ep in sorted(entry_points(group=COMMAND_GROUP), key=lambda e: e.name):
        try:
            registers.append(ep.load())
        except Exception as exc:  # a broken plugin must not take the whole CLI down
            warnings.append(f"radartracker: warning: command {ep.name!r} ({ep.value}) not loaded: {exc}")
    return registers, warnings


def _new_parser(registers: list[Callable[[argparse._SubParsersAction], None]]) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radartracker",
        description="Multi-radar surveillance: tracking with radar bias estimation.",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    parser.add_argument("--debug", action="store_true", help="show the traceback of every error")
    parser.add_argument("--quiet", action="store_true", dest="quiet_all",
                        help="no progress bars and no library logs (Dask...); errors only (also after a command)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for register in registers:
        register(sub)
    return parser


@functools.lru_cache(maxsize=4)
def _parser(state: tuple) -> tuple[argparse.ArgumentParser, tuple[str, ...]]:
    """The parser :func:`main` uses and the warnings of its building, built once per state of the path
    (:func:`radartracker.entrypoints.path_state`), so that a process calling ``main`` many times (embedding,
    tests, benchmarks) reads every installed distribution's entry points and builds the dozen sub-parsers
    once, not at each call. A command installed or removed between two calls makes or removes a dist-info
    folder in a folder of the path, which changes the state: a new parser is built. Parsing does not
    change a parser; help is formatted at the terminal's width of the moment."""
    registers, warnings = _commands()
    return _new_parser(registers), tuple(warnings)


QUIET_ENV = {"TQDM_DISABLE": "1", "DASK_LOGGING__DISTRIBUTED": "error"}  # progress bars, Dask's own loggers
QUIET_LOGGERS = ("", "distributed", "dask", "bokeh", "tornado", "asyncio", "py.warnings")


def main(argv: list[str] | None = None) -> int:
    parser, warnings = _parser(path_state())
    for w in warnings:  # a broken command, named at every call, not only at the one that built the parser
        print(w, file=sys.stderr)
    args = parser.parse_args(argv)
    # an option not given holds the cached parser's default object: a list changed in place by one call
    # (an ``append`` option) must not become the next call's default
    vars(args).update({k: copy.copy(v) for k, v in vars(args).items() if isinstance(v, (list, dict, set))})
    # a command's own --quiet default must not undo `radartracker --quiet COMMAND`
    args.quiet = args.quiet_all or bool(getattr(args, "quiet", False))
    logging.basicConfig(
        level=logging.ERROR if args.quiet else logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    saved_env = {k: os.environ.get(k) for k in QUIET_ENV}
    saved_levels = {name: logging.getLogger(name).level for name in QUIET_LOGGERS}
    if args.quiet:  # the environment reaches libraries imported later and Dask's worker processes
        os.environ.update(QUIET_ENV)
        for name in QUIET_LOGGERS:
            logging.getLogger(name).setLevel(logging.ERROR)
        logging.captureWarnings(True)
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
    finally:  # main() may be called again in the same process (tests, embedding): leave no trace
        if args.quiet:
            for k, v in saved_env.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
            for name, level in saved_levels.items():
                logging.getLogger(name).setLevel(level)
            logging.captureWarnings(False)


# --- built-in commands -------------------------------------------------------------------------


def register_estimators(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("estimators", help="list the installed estimator, motion-model and reconstructor plugins with their options")
    p.set_defaults(func=_cmd_estimators)


def _cmd_estimators(args: argparse.Namespace) -> int:
    from radartracker.registry import plugin_listing

    print(plugin_listing())
    return 0


def register_simulate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("simulate", help="simulate a multi-radar scenario into a scenario folder")
    p.add_argument("out", type=Path, help="scenario folder to write (must not exist)")
    p.add_argument("--scenario", default="seed", choices=sorted([*SCENARIOS, "traffic"]),
                   help="built-in scenario (default: seed); 'traffic': national traffic of any size")
    p.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    p.add_argument("--duration", type=float, default=None, help="seconds to simulate")
    p.add_argument("--format", choices=("csv", "parquet", "dataset"), default="csv",
                   help="CSV files (default), a Parquet file per table, or Parquet with plots and ADS-B reports as "
                        "datasets partitioned by hour and radar (docs/formats.md)")
    traffic = p.add_argument_group("traffic scenario (radartracker.simulation.traffic)")
    traffic.add_argument("--aircraft", type=int, help="mean number of airborne aircraft (default 200)")
    traffic.add_argument("--radars", type=int, help="number of radars on a 200 km grid (default 28)")
    traffic.add_argument("--adsb-share", type=float, help="share of aircraft with ADS-B (default 0.3)")
    traffic.add_argument("--primary-share", type=float, help="share of primary-only aircraft (default 0)")
    traffic.add_argument("--spacing-km", type=float, help="distance between neighbouring radars (default 200)")
    traffic.add_argument("--max-range-km", type=float, help="each radar's coverage (default 250)")
    traffic.add_argument("--period-s", type=float, nargs=2, metavar=("LO", "HI"),
                         help="rotation periods drawn from [LO, HI] (default 4 12)")
    traffic.add_argument("--range-bias-sd-m", type=float, help="σ of the radars' range biases (default 100)")
    traffic.add_argument("--azimuth-bias-sd-deg", type=float, help="σ of the radars' azimuth biases (default 0.1)")
    traffic.add_argument("--altitude-m", type=float, nargs=2, metavar=("LO", "HI"),
                         help="flight altitudes drawn from [LO, HI] (default 7000 12000)")
    traffic.add_argument("--speed-mps", type=float, nargs=2, metavar=("LO", "HI"),
                         help="ground speeds drawn from [LO, HI] (default 200 250)")
    traffic.add_argument("--transponder", choices=("mode_s", "mode_c", "none"),
                         help="what plots carry: Mode S + 3/A + C, Mode C altitude alone, or nothing (default mode_s)")
    p.add_argument("--sensor-error", action="append", default=[], metavar="RADAR:KEY=VALUE[,KEY=VALUE]",
                   help="give RADAR a range gain, time-stamp offset or drift (keys range_gain, time_offset_s, "
                        "drift_gain, drift_time; any scenario kind); repeatable")
    p.set_defaults(func=_cmd_simulate)


def _sensor_errors(specs: list[str]) -> dict[str, dict[str, float]]:
    """``--sensor-error`` values as {radar: {key: value}}; a malformed one is a ConfigurationError naming it."""
    from radartracker.settings import check_number

    out: dict[str, dict[str, float]] = {}
    for spec in specs:
        rid, sep, pairs = spec.partition(":")
        items = [p.partition("=") for p in pairs.split(",")] if sep else []
        if not rid or not items or any(not k or not eq for k, eq, _ in items):
            raise ConfigurationError(f"--sensor-error {spec!r}: expected RADAR:KEY=VALUE[,KEY=VALUE]")
        for key, _, text in items:
            try:
                value = float(text)
            except ValueError:
                raise ConfigurationError(f"--sensor-error {spec!r}: {text!r} is not a number") from None
            out.setdefault(rid, {})[key] = check_number(f"--sensor-error {rid}:{key}", value, lo=-1.0, hi=1e3)
    return out


def _cmd_simulate(args: argparse.Namespace) -> int:
    from radartracker.io.scenario import write_scenario
    from radartracker.simulation.scenarios import build_scenario, with_sensor_errors

    from radartracker.settings import check_number

    if args.out.exists():
        raise ConfigurationError(f"{args.out} already exists; choose a new folder")
    check_number("--seed", args.seed, lo=0, integer=True)
    if args.duration is not None:  # a week of traffic at most: beyond that, a typo, not a scenario
        check_number("--duration", args.duration, lo=0.0, lo_open=True, hi=7 * 86400.0)
    # counts a country's airspace can hold; the memory a size needs is checked by the simulator itself
    bounds = {"aircraft": (1, 10_000_000), "radars": (1, 10_000), "adsb_share": (0.0, 1.0),
              "primary_share": (0.0, 1.0), "spacing_km": (0.001, 1e4), "max_range_km": (0.001, 1e4),
              "period_s": (0.5, 3600.0), "range_bias_sd_m": (0.0, 1e4), "azimuth_bias_sd_deg": (0.0, 10.0),
              "altitude_m": (0.0, 3e4), "speed_mps": (1.0, 1000.0)}
    options = {k: getattr(args, k) for k in [*bounds, "transponder"] if getattr(args, k) is not None}
    for k, v in options.items():
        for x in (v if isinstance(v, list) else [v] if k in bounds else []):
            check_number(f"--{k.replace('_', '-')}", x, lo=bounds[k][0], hi=bounds[k][1])
    if args.scenario == "traffic":
        from radartracker.simulation.traffic import traffic_scenario

        scenario = traffic_scenario(seed=args.seed, duration=args.duration, **options)
    elif options:
        raise ConfigurationError(f"--{next(iter(options)).replace('_', '-')} applies to --scenario traffic only")
    else:
        scenario = build_scenario(args.scenario, seed=args.seed, duration=args.duration)
    data = with_sensor_errors(scenario, _sensor_errors(args.sensor_error)).run()
    if len(data.plots) == 0:  # nothing useful: say so instead of writing a scenario no command can read
        raise ConfigurationError(f"the simulation produced no plots (--duration {args.duration} s is shorter than "
                                 "a radar scan?); nothing written")
    write_scenario(args.out, data, format=args.format)
    print(f"wrote {args.out}: {len(data.radars)} radars, {len(data.plots)} plots, "
          f"{len(data.adsb)} ADS-B reports")
    return 0

"""CLI commands ``convert`` (seed 000 §2.6 ``tracks_plots_00``), ``write-recording``,
``asterix-import`` and ``asterix-export`` — registered through ``radartracker.commands`` entry points."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from radartracker.errors import ConfigurationError, InputError


def register_convert(sub: argparse._SubParsersAction) -> None:
    from radartracker.io.convert_options import ConvertOptions

    d = ConvertOptions()
    p = sub.add_parser("convert", help="convert a text recording (tracks.txt, plots.txt, plots_ads.txt) "
                                       "into per-aircraft .new4/.plt files")
    p.add_argument("recording", type=Path, help="folder with tracks.txt, plots.txt, plots_ads.txt")
    p.add_argument("--out", type=Path, required=True, help="output folder (must not exist), e.g. new")
    p.add_argument("--AZN_TRACKS_MAX", type=int, default=d.AZN_TRACKS_MAX,
                   help=f"at most this many aircraft (most ADS-B reports first; default {d.AZN_TRACKS_MAX})")
    p.add_argument("--AZN_TRACKS_MIN_MEASUR", type=int, default=d.AZN_TRACKS_MIN_MEASUR,
                   help=f"minimum ADS-B reports of a selected aircraft (default {d.AZN_TRACKS_MIN_MEASUR})")
    p.add_argument("--TRACKS_MIN_MEASUR", type=int, default=d.TRACKS_MIN_MEASUR,
                   help=f"tracks with fewer points are not written (default {d.TRACKS_MIN_MEASUR})")
    p.add_argument("--RADAR_SENSOR_ONLY", default=None,
                   help="keep only radar and monoradar records with this sensor value (default: all)")
    p.add_argument("--bucket-mb", type=float, default=d.bucket_bytes / 2**20,
                   help="size of one external-sort bucket in MiB (bounds the memory; default %(default)s)")
    p.set_defaults(func=_cmd_convert)


MAX_MB = 1e6  # a terabyte: beyond that a typo (write-recording --synthetic-mb 1e300 never ended)


def _cmd_convert(args: argparse.Namespace) -> int:
    from radartracker.io.convert import convert
    from radartracker.io.convert_options import ConvertOptions
    from radartracker.settings import check_number

    check_number("--bucket-mb", args.bucket_mb, lo=1 / 1024, hi=MAX_MB)  # inf reached int() as a traceback
    try:
        opts = ConvertOptions(args.AZN_TRACKS_MAX, args.AZN_TRACKS_MIN_MEASUR, args.TRACKS_MIN_MEASUR,
                              args.RADAR_SENSOR_ONLY, int(args.bucket_mb * 2**20))
    except ValueError as exc:
        raise ConfigurationError(f"bad option: {exc}") from None
    if not args.recording.is_dir():
        raise ConfigurationError(f"{args.recording}: not a recording folder")
    report = convert(args.recording, args.out, opts)
    print(f"wrote {args.out}: {len(report['selected_aircraft'])} aircraft in {report['seconds']} s")
    for name, f in report["files"].items():
        bad = f.get("malformed", 0) + f.get("truncated_last_line", 0)
        first = f" (first: {f['first_errors'][0]['error']})" if f.get("first_errors") else ""
        print(f"  {name}: {f['lines']} lines, {f.get('written', 0)} written, {bad} malformed{first}, "
              f"{f['output_files']} files")
    print(f"accounting: {args.out / 'report.json'}")
    if not report["selected_aircraft"]:  # refused work: exit 2 with one line saying why
        raise InputError(f"no aircraft has {opts.AZN_TRACKS_MIN_MEASUR} or more ADS-B reports in "
                         f"{args.recording / 'plots_ads.txt'}; only report.json was written")
    return 0


def register_asterix_import(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("asterix-import", help="read an ASTERIX CAT048/CAT021 recording (.ast or .pcap) "
                                              "into a scenario folder")
    p.add_argument("recording", type=Path, help="raw ASTERIX blocks (.ast), FINAL format or pcap")
    p.add_argument("--out", type=Path, required=True, help="scenario folder to write (must not exist)")
    p.add_argument("--day-start", type=_day_start, default=0.0, metavar="DATE|SECONDS",
                   help="UTC day of the first record (YYYY-MM-DD or seconds since 1970 of its midnight); "
                        "ASTERIX carries only the time of day (default 0: times are seconds of the day; "
                        "pcap files take the day from their packet time stamps)")
    p.add_argument("--skip-bad", action="store_true",
                   help="skip (and count) unreadable framing and plots of SAC/SIC the sidecar lacks")
    p.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS, help="no progress bars; errors only")
    p.set_defaults(func=_cmd_asterix_import)


def _day_start(text: str) -> float:
    from datetime import date, datetime, timezone

    try:
        value = float(text)
    except ValueError:
        pass
    else:
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"not a finite number of seconds: {text!r}")
        return value
    try:
        d = date.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a date (YYYY-MM-DD) nor seconds since 1970: {text!r}") from None
    return datetime(d.year, d.month, d.day, tzinfo=timezone.utc).timestamp()


def _cmd_asterix_import(args: argparse.Namespace) -> int:
    from radartracker.io.asterix_reader import read_asterix
    from radartracker.io.scenario import write_scenario
    from radartracker.io.tables import in_time_order

    if args.out.exists():
        raise ConfigurationError(f"{args.out} already exists; choose a new folder")
    # arrival order to time order: a scenario folder is time-ordered per radar, as replay reads it
    data = in_time_order(read_asterix(args.recording, day_start=args.day_start, skip_bad=args.skip_bad))
    write_scenario(args.out, data)
    print(f"wrote {args.out}: {len(data.radars)} radars, {len(data.plots)} plots, "
          f"{len(data.adsb)} ADS-B reports" + "".join(f"; {n} {k}" for k, n in sorted(data.skipped.items())))
    return 0


def register_asterix_export(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("asterix-export", help="write a scenario folder as ASTERIX CAT048 + CAT021 (.ast)")
    p.add_argument("scenario", type=Path, help="scenario folder (see docs/formats.md)")
    p.add_argument("--out", type=Path, required=True, help=".ast file to write (must not exist)")
    p.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS, help="no progress bar; errors only")
    p.set_defaults(func=_cmd_asterix_export)


def _cmd_asterix_export(args: argparse.Namespace) -> int:
    from radartracker.io.asterix import write_asterix
    from radartracker.io.scenario import read_scenario

    if args.out.exists():
        raise ConfigurationError(f"{args.out} already exists; choose a new file")
    n = write_asterix(args.out, read_scenario(args.scenario))
    print(f"wrote {args.out}: {n} ASTERIX records")
    return 0


def register_write_recording(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("write-recording", help="write a text recording (tracks.txt, plots.txt, plots_ads.txt) "
                                               "from a scenario folder or synthetic traffic of any size")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--scenario", type=Path, help="scenario folder (e.g. written by 'simulate')")
    src.add_argument("--synthetic-mb", type=float, help="synthetic traffic until the recording has this many MB")
    p.add_argument("--seed", type=int, default=0, help="random seed of the synthetic traffic")
    p.add_argument("--out", type=Path, required=True, help="recording folder to write (must not exist)")
    p.set_defaults(func=_cmd_write_recording)


def _cmd_write_recording(args: argparse.Namespace) -> int:
    from radartracker.io.recording import write_scenario_recording, write_synthetic_recording
    from radartracker.settings import check_number

    if args.synthetic_mb is not None:  # NaN/inf were tracebacks, ≤ 0 still wrote a recording
        check_number("--synthetic-mb", args.synthetic_mb, lo=0.0, lo_open=True, hi=MAX_MB)
    check_number("--seed", args.seed, lo=0, integer=True)

    if args.out.exists():
        raise ConfigurationError(f"{args.out} already exists; choose a new folder")
    if args.scenario is not None:
        from radartracker.io.scenario import read_scenario

        write_scenario_recording(args.out, read_scenario(args.scenario))
    else:
        write_synthetic_recording(args.out, target_bytes=int(args.synthetic_mb * 1e6), seed=args.seed,
                                  aircraft_per_batch=20)
    sizes = {p.name: p.stat().st_size for p in sorted(args.out.iterdir())}
    print(f"wrote {args.out}: " + ", ".join(f"{n} {s / 1e6:.1f} MB" for n, s in sizes.items()))
    return 0

"""``radartracker reconstruct``: multi-hypothesis trajectory reconstruction of every flight.

Input: one scenario folder (radar plots grouped per aircraft by truth label or Mode S address) or
``.new4`` files (one aircraft track each, isotropic noise ``--sigma``). Output per aircraft in
``OUT/<key>/``: ``track.csv``, ``track.plt``, ``segments.csv``, ``hypotheses.csv``, ``figure.png``
(see :mod:`radartracker_plugins.reconstruction.output`), plus ``OUT/summary.json``. Exit codes: 0
when a flight was reconstructed plausibly, 2 for bad input, a refused option or no such flight (one
line; ``summary.json`` names each failure).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from radartracker.api import ConfigurationError, InputError, atomic_open

MAX_GRID_POINTS = 1_000_000  # geometric-track points per flight: --grid finer than span/10⁶ is a typo
# option: (low, high) — finite, inclusive; beyond them a value is a typo, not a setting (exit 2, one line)
OPTION_BOUNDS = {"sigma": (1e-3, 1e6), "max_u": (1e-3, 100.0), "max_w": (1e-3, 100.0), "grid": (1e-3, 3600.0),
                 "hypotheses": (1, 1000), "batch_plots": (1, 10_000_000), "min_plots": (2, 10_000_000),
                 "workers": (1, 4096), "jump_sd": (0.0, 100.0)}


def register_reconstruct(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("reconstruct", help="reconstruct flown trajectories as constant-control segments")
    p.add_argument("inputs", type=Path, nargs="+", metavar="SCENARIO_DIR|NEW4_FILE",
                   help="a scenario folder, or one or more .new4 files")
    p.add_argument("--out", type=Path, required=True, help="output folder (must not exist or be empty)")
    p.add_argument("--engine", choices=("serial", "process", "dask"), default="process",
                   help="where flights run: this process, a local process pool (default), or Dask")
    p.add_argument("--workers", type=int, default=None, help="worker processes (default: one per core)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler address (implies --engine dask); default: a LocalCluster")
    p.add_argument("--batch-plots", type=int, default=500, help="plots per task (default 500)")
    p.add_argument("--sigma", type=float, default=100.0, help=".new4 input: position σ in metres (default 100)")
    p.add_argument("--min-plots", type=int, default=10, help="skip aircraft with fewer plots (default 10)")
    p.add_argument("--max-u", type=float, default=9.5,
                   help="lateral acceleration bound m/s² (default 9.5; the seed's 4 pins on real approaches: "
                        "docs/reconstruction.md, Control bounds)")
    p.add_argument("--max-w", type=float, default=3.0, help="longitudinal acceleration bound m/s² (default 3)")
    p.add_argument("--loss", choices=("gauss", "huber", "cauchy"), default="gauss",
                   help="track weight: Gaussian NLL or a robust loss (default gauss)")
    p.add_argument("--hypotheses", type=int, default=10, help="most hypotheses fitted per flight (default 10)")
    p.add_argument("--grid", type=float, default=1.0, help="geometric track spacing in seconds (default 1)")
    p.add_argument("--no-shooting", action="store_true",
                   help="skip the multiple-shooting refinement (about 3x faster, less accurate on long flights)")
    p.add_argument("--truth-biases", action="store_true",
                   help="scenario input: remove the radar biases of truth_biases.csv from the plots")
    p.add_argument("--biases", type=Path, default=None, metavar="BIASES_CSV",
                   help="remove the radar biases of a replay's biases.csv (last row per radar; its sd inflates R)")
    p.add_argument("--estimate-biases", action="store_true",
                   help="estimate the radar biases jointly with every flight's trajectory (the default for a "
                        "scenario folder without --truth-biases or --biases; for .new4 input with --radars on request)")
    p.add_argument("--components", default="", metavar="NAME,...",
                   help="with the joint estimate: bias components beyond the range and azimuth offsets, of every "
                        "radar (range_gain, time_offset; scenario input only: a range gain needs the slant ranges)")
    p.add_argument("--keep-biases", action="store_true",
                   help="scenario input: reconstruct the plots as they are, radar biases left in "
                        "(the behaviour before the joint estimate became the default)")
    p.add_argument("--radars", type=Path, default=None, metavar="RADARS_CSV",
                   help=".new4 input: radars.csv (scenario format); <radar>_r.new4 plots then get R from the "
                        "radar's range/azimuth sigma, and the plots of all radars of one folder are fused")
    p.add_argument("--flights", default=None, metavar="ID,...", help="reconstruct only these aircraft keys")
    p.add_argument("--jump-sd", type=float, default=None, metavar="MPS2",
                   help="prior sd of each control jump (m/s², MAP fit); 0: no prior "
                        "(default: ReconstructionConfig's 0, chosen by measurement in docs/reconstruction.md)")
    p.add_argument("--no-figures", action="store_true", help="skip the per-aircraft figures")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no Dask logs")
    p.set_defaults(func=_cmd_reconstruct)


def _load(inputs: list[Path], sigma: float, min_plots: int, radars_csv: Path | None = None):
    """(tracks, plane per key, truth per key, skipped counts, truth biases or None, radar ids or None)."""
    from radartracker.api import read_radars, read_scenario
    from radartracker_plugins.reconstruction.tracks import new4_set_tracks, scenario_tracks, scenario_truth

    for p in inputs:
        if not p.exists():
            raise ConfigurationError(f"{p}: no such file or folder")
    if _scenario_input(inputs):
        if radars_csv:
            raise ConfigurationError("--radars: only for .new4 input (a scenario folder has its radars.csv)")
        data = read_scenario(inputs[0])
        tracks, plane, skipped = scenario_tracks(data, min_plots)
        return (tracks, {t.key: plane for t in tracks}, scenario_truth(data, plane), dict(skipped), data.truth_biases,
                {r.id for r in data.radars})
    if any(p.is_dir() or p.suffix != ".new4" for p in inputs):
        raise ConfigurationError("give either one scenario folder or .new4 files")
    radars = read_radars(radars_csv) if radars_csv else []
    tracks, planes, skipped = new4_set_tracks(inputs, radars, sigma)
    keys = [t.key for t in tracks]
    if len(set(keys)) < len(keys):
        dup = sorted({k for k in keys if keys.count(k) > 1})
        raise ConfigurationError(f"two inputs map to the same aircraft key: {', '.join(dup)}")
    short = [t for t in tracks if len(t) < min_plots]
    if short:
        skipped[f"tracks with < {min_plots} points"] = len(short)
    tracks = [t for t in tracks if len(t) >= min_plots]
    return tracks, planes, {}, dict(skipped), None, ({r.id for r in radars} or None)


def _check_options(args: argparse.Namespace) -> None:
    """Every numeric option finite and within :data:`OPTION_BOUNDS` (a ConfigurationError naming it)."""
    for name, (lo, hi) in OPTION_BOUNDS.items():
        value = getattr(args, name)
        if value is not None and not lo <= value <= hi:  # also refuses NaN and ±inf
            raise ConfigurationError(f"--{name.replace('_', '-')}: {value!r} outside [{lo:g}, {hi:g}]")


def _check_grid(tracks, grid: float) -> None:
    """Refuse a --grid that would give a flight more than :data:`MAX_GRID_POINTS` geometric-track points."""
    longest = max(tracks, key=lambda t: t.t[-1] - t.t[0])
    points = (longest.t[-1] - longest.t[0]) / grid + 1
    if points > MAX_GRID_POINTS:
        raise ConfigurationError(f"--grid {grid:g}: flight {longest.key} ({longest.t[-1] - longest.t[0]:g} s) would "
                                 f"get {points:.3g} track points (at most {MAX_GRID_POINTS:,}); choose a larger grid")


def _components(args: argparse.Namespace) -> tuple[str, ...]:
    """The extra bias components ``--components`` names (a ConfigurationError for an unknown one, or where no
    joint estimate is made, or for .new4 input, whose plots carry no slant range)."""
    from radartracker.api import EXTRA_PRIOR_SD  # here: `reconstruct --help` imports no numerics

    names = tuple(n.strip() for n in args.components.split(",") if n.strip())
    if unknown := [n for n in names if n not in EXTRA_PRIOR_SD]:
        raise ConfigurationError(f"--components: unknown {unknown[0]!r}; known: {', '.join(EXTRA_PRIOR_SD)}")
    if names and not _scenario_input(args.inputs):
        raise ConfigurationError("--components: scenario input only (.new4 plots carry no slant range)")
    if names and not _estimate_biases(args):
        raise ConfigurationError("--components: only with the joint estimate of the biases (not with --truth-biases, "
                                 "--biases or --keep-biases)")
    return names


def _select(tracks, flights: str | None):
    """The tracks named by ``--flights ID,...`` (all when None); an unknown ID is an error."""
    if not flights:
        return tracks
    want = [f.strip() for f in flights.split(",") if f.strip()]
    have = {t.key for t in tracks}
    missing = [f for f in want if f not in have]
    if missing:
        raise ConfigurationError(f"--flights: no aircraft {', '.join(missing)} in the input "
                                 f"(have: {', '.join(sorted(have)[:20])}{' ...' if len(have) > 20 else ''})")
    return [t for t in tracks if t.key in set(want)]


def _estimate_biases(args: argparse.Namespace) -> bool:
    """Whether the radar biases are estimated jointly with the trajectories: on request, and by default for a
    scenario folder (radar plots with their geometry) unless known biases (``--truth-biases``, ``--biases``)
    are given or ``--keep-biases`` asks for the plots as they are. Biases left in the plots shift every
    flight (truth RMSE 116 m against 8 m on the ``demo`` scenario: docs/reconstruction.md), so a reference
    must remove them by default. ``.new4`` input keeps its plots unless asked: most such files are positions
    without radar geometry."""
    if args.estimate_biases:
        return True
    return _scenario_input(args.inputs) and not (args.truth_biases or args.biases or args.keep_biases)


def _scenario_input(inputs: list[Path]) -> bool:
    """Whether the input is one scenario folder (radar plots with their geometry), not ``.new4`` files."""
    return len(inputs) == 1 and inputs[0].is_dir()


def _results(tracks, cfg, ex, args: argparse.Namespace, summary: dict, notes: list[str]):
    """Every flight's reconstruction (or failure), as they finish: with the radar biases estimated jointly when
    :func:`_estimate_biases` says so — those of the radars that saw an aircraft together with another
    (:func:`.joint.shared_radars`); a radar seen alone keeps its plots as they are (its azimuth bias, a rotation
    of its tracks, is unobservable) — else of the plots as given. Records the bias mode in ``summary``."""
    from radartracker_plugins.reconstruction.engine import run_many
    from radartracker_plugins.reconstruction.joint import estimate_jointly, shared_radars

    if not _estimate_biases(args):
        return run_many(tracks, cfg, ex, args.batch_plots, not args.quiet)
    radars = shared_radars(tracks)
    if not radars:
        notes.append("reconstruct: warning: no aircraft was seen by two radars, so the radar biases cannot be "
                     "estimated; the plots are reconstructed as they are (give --biases to remove known ones)")
        summary["biases_removed"] = "none: no aircraft seen by two radars"
        return run_many(tracks, cfg, ex, args.batch_plots, not args.quiet)
    results, joint = estimate_jointly(tracks, cfg, ex, args.batch_plots, not args.quiet, radars, _components(args))
    summary["biases_removed"] = "estimated jointly"
    summary["joint_biases"] = joint
    return results


def _cmd_reconstruct(args: argparse.Namespace) -> int:
    from radartracker_plugins.reconstruction import ReconstructionConfig
    from radartracker_plugins.reconstruction.biases import debias, read_biases
    from radartracker_plugins.reconstruction.engine import Failure, executor
    from radartracker_plugins.reconstruction.output import write_reconstruction
    from radartracker_plugins.reconstruction.quality import assess, truth_error

    if args.out.exists() and any(args.out.iterdir()):
        raise ConfigurationError(f"{args.out} exists and is not empty; choose a new folder")
    _check_options(args)
    if sum(map(bool, (args.truth_biases, args.biases, args.estimate_biases, args.keep_biases))) > 1:
        raise ConfigurationError("give at most one of --truth-biases, --biases, --estimate-biases, --keep-biases")
    _components(args)  # refused before any work
    try:
        cfg = ReconstructionConfig(max_u=args.max_u, max_w=args.max_w, loss=args.loss, hypotheses=args.hypotheses,
                                   grid_dt=args.grid, shooting=not args.no_shooting,
                                   **({} if args.jump_sd is None else {"jump_sd": args.jump_sd}))
    except (ValueError, TypeError) as exc:
        raise ConfigurationError(str(exc)) from None
    if args.quiet:
        for name in ("distributed", "dask"):
            logging.getLogger(name).setLevel(logging.ERROR)
    tracks, planes, truth, skipped, truth_biases, radar_ids = _load(args.inputs, args.sigma, args.min_plots, args.radars)
    tracks = _select(tracks, args.flights)
    if args.truth_biases and not truth_biases:
        raise ConfigurationError("--truth-biases: the input has no truth biases")
    biases = truth_biases if args.truth_biases else read_biases(args.biases, radar_ids) if args.biases else None
    if not tracks:
        raise ConfigurationError("no aircraft with enough plots to reconstruct")
    _check_grid(tracks, args.grid)
    engine = "dask" if args.scheduler else args.engine
    args.out.mkdir(parents=True, exist_ok=True)
    summary = {"flights": len(tracks), "skipped_plots": skipped, "reconstructed": [], "failed": {}}
    if biases:
        tracks = [debias(t, biases) for t in tracks]
        summary["biases_removed"] = "truth_biases.csv" if args.truth_biases else str(args.biases)
    notes: list[str] = []  # failures and warnings, printed unless nothing was reconstructed
    with executor(engine, args.workers, args.scheduler, quiet=args.quiet) as ex:
        for res in _results(tracks, cfg, ex, args, summary, notes):
            if isinstance(res, Failure):
                summary["failed"][res.key] = res.reason
                notes.append(f"reconstruct: {res.key}: {res.reason}")
                continue
            write_reconstruction(res, planes[res.key], args.out, truth.get(res.key), not args.no_figures, cfg)
            q = assess(res, cfg)
            warnings = q.pop("warnings")
            notes += [f"reconstruct: warning: {w}" for w in warnings]
            row = {"key": res.key, "plots": len(res.plots), "segments": len(res.control), "weight": res.best.weight,
                   "score": res.best.score, "quality": q, "warnings": warnings}
            if res.key in truth:
                row["truth_error"] = truth_error(res, truth[res.key])
            summary["reconstructed"].append(row)
    summary["reconstructed"].sort(key=lambda r: r["key"])
    bad = [r["key"] for r in summary["reconstructed"] if not r["quality"]["plausible"]]
    summary["implausible"] = bad
    with atomic_open(args.out / "summary.json", "w", encoding="utf-8") as f:  # flushed, then renamed
        f.write(json.dumps(summary, indent=1))
    n_ok = len(summary["reconstructed"]) - len(bad)
    if not n_ok:  # refused work: exit 2 with one line (summary.json holds every flight's reason)
        why = (f"{len(summary['failed'])} failed (first: {next(iter(summary['failed'].items()))})"
               if summary["failed"] else f"{len(bad)} implausible")
        raise InputError(f"no flight reconstructed plausibly: {why}; see {args.out / 'summary.json'}")
    for line in notes:
        print(line, file=sys.stderr)
    print(f"reconstructed {len(summary['reconstructed'])} of {len(tracks)} aircraft into {args.out}"
          + (f"; {len(summary['failed'])} failed" if summary["failed"] else "")
          + (f"; {len(bad)} implausible ({', '.join(bad)}): see summary.json" if bad else ""))
    return 0

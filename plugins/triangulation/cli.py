"""``radartracker triangulate``: positions or trajectories from direction-finder bearings.

Static mode gives one ML fix per target (seed 001 §2–3); dynamic mode one polynomial trajectory
per target (seed 001 eq. 1.1), both with covariances. A target whose geometry is degenerate or
too poor is skipped, counted and named on stderr and in ``summary.json``; file formats are in
``docs/formats.md`` ("Triangulation files"). The output folder is checked before the computation;
the files are written beside their final names and renamed into place together, ``summary.json``
last, so a failure or a kill keeps an earlier run's files (``--overwrite``) intact. Exit codes: 0
when a target was located, 2 when none was (one line; ``summary.json`` names each refusal).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import defaultdict
from pathlib import Path
from typing import TYPE_CHECKING

from radartracker.api import (ConfigurationError, prepare_output_folder, removed_if_failed, replace_outputs,
                              write_text)

if TYPE_CHECKING:
    import numpy as np


def register_triangulate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("triangulate", help="locate targets from passive direction-finder bearings")
    p.add_argument("bearings", type=Path, help="bearings CSV (see docs/formats.md)")
    p.add_argument("--stations", type=Path, required=True, help="stations CSV (see docs/formats.md)")
    p.add_argument("--out", type=Path, required=True, help="output folder (new or empty; see --overwrite)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an earlier run's outputs in --out (otherwise a non-empty folder is refused)")
    p.add_argument("--mode", choices=("static", "dynamic"), default="static",
                   help="static: one position per target; dynamic: a polynomial trajectory (default static)")
    p.add_argument("--order", type=int, default=1, help="polynomial degree of the dynamic model (default 1)")
    p.add_argument("--step", type=float, default=None,
                   help="dynamic: output every STEP seconds (default: at each bearing time)")
    p.add_argument("--reference", default=None, metavar="LAT,LON[,H]",
                   help="origin of the east/north/up output columns (default: the stations' mean site)")
    p.add_argument("--warn-gdop", type=float, default=10.0, help="flag fixes with GDOP above this (default 10)")
    p.add_argument("--max-gdop", type=float, default=None,
                   help="refuse fixes with GDOP above this (default 0.5/σ: error above half the range)")
    p.add_argument("--estimator", choices=("ml", "lsq"), default="ml",
                   help="ml: Gaussian maximum likelihood (W = K⁻¹); lsq: least squares with the weights of "
                        "--weights (seed 001 eq. 3.1; default ml)")
    p.add_argument("--weights", default=None, metavar="identity|FILE",
                   help="lsq weight matrix: identity (W = I, needs no error model; the default) or a CSV of "
                        "per-station 2×2 blocks (docs/formats.md)")
    p.add_argument("--skip-bad", action="store_true", help="skip (and count) malformed bearing rows")
    p.set_defaults(func=_cmd_triangulate)


OUTPUT_FILES = ("fixes.csv", "tracks.csv", "summary.json")  # what --overwrite may replace
MAX_ORDER = 10  # a polynomial trajectory of higher degree is fitted noise, and slow to set up
MAX_OUTPUT_TIMES = 1_000_000  # per target: --step finer than span/10⁶ is a typo (1e-9 s asked for 411 GiB)


def _reference(text: str | None) -> tuple[float, ...] | None:
    if text is None:
        return None
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise ConfigurationError(f"--reference: expected LAT,LON[,H] in degrees and metres, got {text!r}") from None
    if len(values) not in (2, 3):
        raise ConfigurationError(f"--reference: expected LAT,LON[,H], got {text!r}")
    for name, v, lo, hi in zip(("LAT", "LON", "H"), values, (-90.0, -180.0, -1e5), (90.0, 180.0, 1e5)):
        if not lo <= v <= hi:  # also refuses NaN and ±inf
            raise ConfigurationError(f"--reference: {name} = {v!r} outside [{lo:g}, {hi:g}]")
    return values


def _check_options(args: argparse.Namespace) -> None:
    if not 0 <= args.order <= MAX_ORDER:
        raise ConfigurationError(f"--order: must be 0..{MAX_ORDER}, got {args.order}")
    if args.step is not None and not (math.isfinite(args.step) and args.step > 0):
        raise ConfigurationError(f"--step: must be a finite number > 0, got {args.step}")
    for option, value in (("--warn-gdop", args.warn_gdop), ("--max-gdop", args.max_gdop)):
        if value is not None and not value > 0:  # +inf is allowed: no limit
            raise ConfigurationError(f"{option}: must be > 0, got {value}")


def _output_times(target: str, t_min: float, t_max: float, step: float) -> np.ndarray:
    import numpy as np  # here, not at the top: registering the command needs none of it

    n = (t_max - t_min) / step + 1  # a float: a denormal step makes it infinite
    if not n <= MAX_OUTPUT_TIMES:
        raise ConfigurationError(f"--step {step:g}: target {target} would get {n:.3g} output times over "
                                 f"{t_max - t_min:g} s (at most {MAX_OUTPUT_TIMES:,}); choose a larger step")
    return np.arange(t_min, t_max + 1e-9, step)


def _cmd_triangulate(args: argparse.Namespace) -> int:
    _check_options(args)
    with removed_if_failed(args.out):  # a run that fails leaves no empty --out of its own making
        return _triangulate(args)


def _triangulate(args: argparse.Namespace) -> int:
    import numpy as np

    from radartracker_plugins.triangulation import (GeometryError, StationWeights, TriangulationFrame, io, locate,
                                                    read_weights, track)

    # before the computation; an earlier run's files stay until this run's replace them
    out = prepare_output_folder(args.out, OUTPUT_FILES, overwrite=args.overwrite, keep_earlier=True)
    if args.estimator == "ml" and args.weights is not None:
        raise ConfigurationError("--weights: only with --estimator lsq (ML weighs by the stations' σ)")
    weights = None
    if args.estimator == "lsq":
        weights = (StationWeights.identity() if args.weights in (None, "identity")
                   else read_weights(Path(args.weights)))
    frame = TriangulationFrame(io.read_stations(args.stations), _reference(args.reference))
    bearings, skipped = io.read_bearings(args.bearings, skip_bad=args.skip_bad)
    unknown = sorted({b.station for b in bearings} - set(frame.stations))
    if unknown and not args.skip_bad:
        raise ConfigurationError(f"{args.bearings.name}, field 'station': station id(s) {unknown} are not in "
                       f"{args.stations.name} (use --skip-bad to skip and count them)")
    known = [b for b in bearings if b.station in frame.stations]
    skipped["unknown_station"] = len(bearings) - len(known)
    bearings = known
    by_target = defaultdict(list)
    for b in bearings:
        by_target[b.target].append(b)
    done, refused = [], {}
    for target, bs in by_target.items():
        try:
            if args.mode == "static":
                done.append((target, locate(frame, bs, warn_gdop=args.warn_gdop, max_gdop=args.max_gdop,
                                            weights=weights)))
            else:
                tr = track(frame, bs, order=args.order, warn_gdop=args.warn_gdop, max_gdop=args.max_gdop,
                           weights=weights)
                times = (np.unique([b.time for b in bs]) if args.step is None
                         else _output_times(target, tr.t_min, tr.t_max, args.step))
                done.append((target, tr, times))
        except GeometryError as exc:
            refused[target] = str(exc)
    if done:  # else the one error line below says it
        for target, why in refused.items():
            print(f"radartracker triangulate: target {target}: refused: {why}", file=sys.stderr)
    name = "fixes.csv" if args.mode == "static" else "tracks.csv"
    summary = {
        "mode": args.mode, "estimator": args.estimator, "weights": args.weights if weights is not None else None,
        "reference": dict(zip(("lat_deg", "lon_deg", "height_m"), frame.reference)),
        "order": args.order if args.mode == "dynamic" else None,
        "bearings": len(bearings), "skipped_rows": skipped, "targets": len(by_target),
        "solved": [t[0] for t in done], "refused": refused,
        "poor_geometry": [t[0] for t in done if t[1].poor_geometry],
    }
    with replace_outputs(out, OUTPUT_FILES, last="summary.json") as stage:
        (io.write_fixes if args.mode == "static" else io.write_tracks)(stage(name), frame, done)
        write_text(stage("summary.json"), json.dumps(summary, indent=2) + "\n")  # renamed last: a finished run
    if not done:  # refused work: exit 2 with one line (the summary lists every target's reason)
        target, why = next(iter(refused.items()))
        raise GeometryError(f"no target located: {len(refused)} of {len(by_target)} refused (target {target}: "
                            f"{why}); reasons in {out / 'summary.json'}", math.inf)
    print(f"triangulated {len(done)} of {len(by_target)} targets from {len(bearings)} bearings "
          f"({sum(skipped.values())} rows skipped, {len(refused)} refused, "
          f"{len(summary['poor_geometry'])} in poor geometry); wrote {out / name}")
    return 0

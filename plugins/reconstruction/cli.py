"""``radartracker reconstruct``: multi-hypothesis trajectory reconstruction of every flight.

Input: one scenario folder (radar plots grouped per aircraft by truth label or Mode S address) or
``.new4`` files (one aircraft track each, isotropic noise ``--sigma``). Output per aircraft in
``OUT/<key>/``: ``track.csv``, ``track.plt``, ``segments.csv``, ``hypotheses.csv``, ``figure.png``
(see :mod:`radartracker_plugins.reconstruction.output`), plus ``OUT/summary.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from radartracker.api import ConfigurationError


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
    p.add_argument("--max-u", type=float, default=4.0, help="lateral acceleration bound m/s² (default 4)")
    p.add_argument("--max-w", type=float, default=2.0, help="longitudinal acceleration bound m/s² (default 2)")
    p.add_argument("--loss", choices=("gauss", "huber", "cauchy"), default="gauss",
                   help="track weight: Gaussian NLL or a robust loss (default gauss)")
    p.add_argument("--hypotheses", type=int, default=10, help="most hypotheses fitted per flight (default 10)")
    p.add_argument("--grid", type=float, default=1.0, help="geometric track spacing in seconds (default 1)")
    p.add_argument("--no-shooting", action="store_true",
                   help="skip the multiple-shooting refinement (about 3x faster, less accurate on long flights)")
    p.add_argument("--truth-biases", action="store_true",
                   help="scenario input: remove the radar biases of truth_biases.csv from the plots")
    p.add_argument("--no-figures", action="store_true", help="skip the per-aircraft figures")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_reconstruct)


def _load(inputs: list[Path], sigma: float, min_plots: int):
    """(tracks, plane per key, truth per key, skipped counts, truth biases or None)."""
    from radartracker.api import read_scenario
    from radartracker_plugins.reconstruction.tracks import new4_track, scenario_tracks, scenario_truth

    for p in inputs:
        if not p.exists():
            raise ConfigurationError(f"{p}: no such file or folder")
    if len(inputs) == 1 and inputs[0].is_dir():
        data = read_scenario(inputs[0])
        tracks, plane, skipped = scenario_tracks(data, min_plots)
        return tracks, {t.key: plane for t in tracks}, scenario_truth(data, plane), dict(skipped), data.truth_biases
    if any(p.is_dir() or p.suffix != ".new4" for p in inputs):
        raise ConfigurationError("give either one scenario folder or .new4 files")
    tracks, planes, skipped = [], {}, {}
    for p in inputs:
        pt, plane = new4_track(p, sigma)
        if len(pt) < min_plots:
            skipped[f"tracks with < {min_plots} points"] = skipped.get(f"tracks with < {min_plots} points", 0) + 1
            continue
        if pt.key in planes:
            raise ConfigurationError(f"{p}: two inputs map to the same aircraft key {pt.key!r}")
        tracks.append(pt)
        planes[pt.key] = plane
    return tracks, planes, {}, skipped, None


def _cmd_reconstruct(args: argparse.Namespace) -> int:
    from radartracker_plugins.reconstruction import ReconstructionConfig
    from radartracker_plugins.reconstruction.engine import Failure, executor, run_many
    from radartracker_plugins.reconstruction.output import write_reconstruction

    if args.out.exists() and any(args.out.iterdir()):
        raise ConfigurationError(f"{args.out} exists and is not empty; choose a new folder")
    if args.sigma <= 0:
        raise ConfigurationError(f"--sigma: must be > 0, got {args.sigma}")
    try:
        cfg = ReconstructionConfig(max_u=args.max_u, max_w=args.max_w, loss=args.loss,
                                   hypotheses=args.hypotheses, grid_dt=args.grid, shooting=not args.no_shooting)
    except (ValueError, TypeError) as exc:
        raise ConfigurationError(str(exc)) from None
    tracks, planes, truth, skipped, truth_biases = _load(args.inputs, args.sigma, args.min_plots)
    if args.truth_biases and not truth_biases:
        raise ConfigurationError("--truth-biases: the input has no truth biases")
    biases = truth_biases if args.truth_biases else None
    if not tracks:
        raise ConfigurationError("no aircraft with enough plots to reconstruct")
    engine = "dask" if args.scheduler else args.engine
    args.out.mkdir(parents=True, exist_ok=True)
    summary = {"flights": len(tracks), "skipped_plots": skipped, "reconstructed": [], "failed": {}}
    with executor(engine, args.workers, args.scheduler) as ex:
        for res in run_many(tracks, cfg, ex, args.batch_plots, not args.quiet, biases):
            if isinstance(res, Failure):
                summary["failed"][res.key] = res.reason
                print(f"reconstruct: {res.key}: {res.reason}", file=sys.stderr)
                continue
            write_reconstruction(res, planes[res.key], args.out, truth.get(res.key), not args.no_figures)
            summary["reconstructed"].append({"key": res.key, "plots": len(res.plots),
                                             "segments": len(res.control), "weight": res.best.weight,
                                             "score": res.best.score})
    summary["reconstructed"].sort(key=lambda r: r["key"])
    (args.out / "summary.json").write_text(json.dumps(summary, indent=1))
    print(f"reconstructed {len(summary['reconstructed'])} of {len(tracks)} aircraft into {args.out}"
          + (f"; {len(summary['failed'])} failed" if summary["failed"] else ""))
    return 0

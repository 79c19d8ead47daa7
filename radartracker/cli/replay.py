"""``radartracker replay`` and ``radartracker demo``: one run of the pipeline (radartracker.pipeline.run).

Every option of ``replay`` is either honoured on both associations or refused with a
ConfigurationError naming it; the effective settings go to ``OUT/config.json``, and
``replay SCENARIO --config OUT/config.json --out OUT2`` runs the same again (options given on the
command line override the file's).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from radartracker.errors import ConfigurationError
from radartracker.settings import ARCHITECTURES, ASSOCIATIONS, DEFAULT_Q, check_number

if TYPE_CHECKING:  # imported by the commands when they run: registering them must stay light
    from radartracker.pipeline.config import RunConfig
    from radartracker.pipeline.result import RunResult


def add_run_options(p: argparse.ArgumentParser, *, estimator_options: bool = True) -> None:
    """The options shared by ``replay`` and ``compare`` (``None`` defaults: the config file's or the default)."""
    p.add_argument("--q", type=str, default=None,
                   help=f"aircraft process noise density q (m²/s³) for the estimator and the track filter's q "
                        f"setting (default {DEFAULT_Q:g}; 0 is the seed's noiseless model)")
    p.add_argument("--association", choices=ASSOCIATIONS, default=None,
                   help="labels: the TrackManager associating by truth label / Mode S address (evaluation); "
                        "manager: the TrackManager with --associator (default gnn); auto (default): labels "
                        "when every plot carries one")
    p.add_argument("--manager", action="store_true", help="same as --association manager")
    p.add_argument("--architecture", choices=ARCHITECTURES, default=None,
                   help="central (default): every plot to one tracker and estimator; distributed: one tracker "
                        "per radar and a fusion centre over their tracks (seed 004, docs/fusion.md)")
    p.add_argument("--motion-model", default=None,
                   help="track filter plugin (cv, imm, adaptive, fading; default: ManagerConfig's)")
    p.add_argument("--associator", default=None,
                   help="association plugin of the TrackManager (gnn, labels, or an installed third party's; "
                        "default gnn)")
    p.add_argument("--motion-option", action="append", default=[], metavar="KEY=VALUE",
                   help="a setting of the motion model (repeatable; see `radartracker estimators`)")
    if estimator_options:
        p.add_argument("--estimator-option", action="append", default=[], metavar="KEY=VALUE",
                       help="an option of the estimator plugin (repeatable; see `radartracker estimators`)")
    p.add_argument("--skip-bad", action="store_true", default=None,
                   help="skip (and count) malformed input rows instead of stopping")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an earlier run's outputs in --out (otherwise a non-empty folder is refused)")
    p.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS,
                   help="no progress bars, no library logs; errors only")


def run_config(args: argparse.Namespace, base: RunConfig | None = None) -> RunConfig:
    """The RunConfig of the parsed options on top of ``base`` (a config file's, or the defaults)."""
    import attrs

    from radartracker.pipeline.config import RunConfig
    from radartracker.registry import parse_key_values

    base = base or RunConfig()
    changes: dict = {}
    if args.q is not None:
        changes["q"] = check_number("--q", args.q, lo=0.0)
    association = "manager" if args.manager else args.association
    if args.manager and args.association not in (None, "manager"):
        raise ConfigurationError(f"--manager contradicts --association {args.association}")
    if association is not None:
        changes["association"] = association
    if args.architecture is not None:
        changes["architecture"] = args.architecture
        if args.architecture == "central":
            changes["fusion"] = {}
    if args.motion_model is not None:
        changes["motion_model"] = args.motion_model
    if getattr(args, "associator", None) is not None:
        changes["associator"] = args.associator
    if args.motion_option:
        changes["motion_options"] = base.motion_options | parse_key_values(args.motion_option, "--motion-option")
    if getattr(args, "estimator_option", None):
        changes["estimator_options"] = base.estimator_options | parse_key_values(args.estimator_option,
                                                                                 "--estimator-option")
    if getattr(args, "estimator", None) is not None:
        if args.estimator != base.estimator and "estimator_options" not in changes:
            changes["estimator_options"] = {}  # another plugin: the file's options were the other one's
        changes["estimator"] = args.estimator
    if args.skip_bad:
        changes["skip_bad"] = True
    if changes.get("association", base.association) == "labels" and "associator" not in changes:
        changes["associator"] = None  # the labelled association names its own
    return attrs.evolve(base, **changes)


def register_replay(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="replay a scenario folder or ASTERIX recording through the pipeline")
    p.add_argument("scenario", type=Path, help="scenario folder or ASTERIX recording (see docs/formats.md)")
    p.add_argument("--out", type=Path, required=True, help="output folder (new or empty; see --overwrite)")
    p.add_argument("--config", type=Path, default=None,
                   help="settings from an earlier run's config.json (options given here override them)")
    p.add_argument("--estimator", default=None, help="estimator plugin (default: the best installed, coupled-sparse)")
    add_run_options(p)
    p.add_argument("--plots", action="store_true", help="also write figures (biases.png, tracks.png)")
    p.add_argument("--format", choices=("csv", "parquet"), default="csv",
                   help="the tables tracks, events and biases as CSV (default) or Parquet files (docs/formats.md)")
    p.set_defaults(func=_cmd_replay)


def _cmd_replay(args: argparse.Namespace) -> int:
    from radartracker.io.atomic import removed_if_failed
    from radartracker.io.scenario import check_regular_files
    from radartracker.pipeline.config import read_config
    from radartracker.pipeline.writer import prepare

    config = run_config(args, read_config(args.config) if args.config is not None else None)
    if args.scenario.is_dir():  # a device or pipe in the folder has no end: refused before any reading
        check_regular_files(args.scenario)
    with removed_if_failed(args.out):  # a run that fails leaves no empty --out of its own making
        out = prepare(args.out, overwrite=args.overwrite)  # before the computation: fail early, not after it
        result = _replay(args, config, out)
    print(f"{result.config.association} association, estimator {result.config.estimator}"
          + (f", motion model {result.config.motion_model}" if result.config.motion_model else ""))
    print(result.summary_table())
    print(f"outputs in {out}")
    return 0


def _replay(args: argparse.Namespace, config: RunConfig, out: Path) -> RunResult:
    """The run of ``replay`` into the prepared folder ``out``, its files written."""
    from radartracker.io.sources import ASTERIX_SUFFIXES, read_source
    from radartracker.pipeline.run import replay_folder, run, streamable
    from radartracker.pipeline.warmup import before_progress_bar, warm_up
    from radartracker.pipeline.writer import write_outputs

    local = None
    tracks_in = args.scenario.suffix.lower() in ASTERIX_SUFFIXES and args.scenario.is_file()
    if tracks_in:  # imported only for a recording: a folder needs none of libasterix's large generated tables
        from radartracker.fusion.cat048 import has_track_reports, local_tracks_from_asterix
        tracks_in = has_track_reports(args.scenario)
    if tracks_in and config.architecture == "distributed":
        # CAT048 track reports (I161): what a radar head that tracks sends; fused without local trackers
        data, local = local_tracks_from_asterix(args.scenario, skip_bad=config.skip_bad)
    else:
        if tracks_in:
            print(f"warning: {args.scenario} holds CAT048 track reports (I161); the central architecture reads "
                  "their positions as plots; --architecture distributed fuses them as tracks", file=sys.stderr)
        data = None if args.scenario.is_dir() and not args.plots else read_source(args.scenario, skip_bad=config.skip_bad)
    progress = not getattr(args, "quiet", False)
    if progress and before_progress_bar():  # compile (first run) or load the kernels before the bar starts
        warm_up(config, labelled=data.plots.has_truth_labels if data is not None
                else not streamable(args.scenario, config) and config.association != "manager")
    if data is None:  # a scenario folder: streamed when it can be (pipeline.run.replay_folder)
        return replay_folder(args.scenario, config, out, progress=progress, table_format=args.format)
    result = run(data, config, progress=progress, local_tracks=local)
    write_outputs(result, out, figures=args.plots, table_format=args.format)
    return result


def register_demo(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="simulate and replay a built-in scenario; print true vs estimated biases")
    p.add_argument("--estimator", default=None, help="estimator plugin (default: the best installed)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", type=Path, default=None, help="also keep the scenario and outputs here (new or empty)")
    p.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS, help="no progress bars, no library logs")
    p.set_defaults(func=_cmd_demo)


def _cmd_demo(args: argparse.Namespace) -> int:
    import tempfile

    from radartracker.io.atomic import removed_if_failed
    from radartracker.io.scenario import write_scenario
    from radartracker.io.sources import read_source
    from radartracker.pipeline.config import RunConfig
    from radartracker.pipeline.run import run
    from radartracker.pipeline.warmup import before_progress_bar, warm_up
    from radartracker.pipeline.writer import prepare, write_outputs
    from radartracker.simulation.scenarios import build_scenario

    check_number("--seed", args.seed, lo=0, integer=True)
    with tempfile.TemporaryDirectory() as tmp, removed_if_failed((args.out or Path(tmp)) / "replay"):
        root = args.out or Path(tmp)
        out = prepare(root / "replay")
        scen_dir = root / "scenario"
        data = build_scenario("demo", seed=args.seed).run()
        write_scenario(scen_dir, data)
        data = read_source(scen_dir)  # through the public file format, as a user would
        config, progress = RunConfig(estimator=args.estimator), not getattr(args, "quiet", False)
        if progress and before_progress_bar():  # compile (first run) or load the kernels before the bar starts
            warm_up(config, labelled=data.plots.has_truth_labels)
        result = run(data, config, progress=progress)
        print(f"demo: scenario 'demo' ({len(data.radars)} radars, {len(data.plots)} plots, "
              f"{len(data.adsb)} ADS-B reports), estimator '{result.estimator_name}'")
        write_outputs(result, out, figures=args.out is not None)
        print(result.summary_table())
    return 0

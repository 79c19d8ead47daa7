"""``radartracker assess``: a per-radar surveillance assessment of a scenario (radartracker.assessment)."""

from __future__ import annotations

import argparse
from pathlib import Path


def register_assess(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("assess", help="assess each radar (biases, errors, Pd, codes, time stamps) and the system "
                                      "tracks against the truth, else ADS-B and reconstructed flights; writes report.html "
                                      "(docs/assessment.md)")
    p.add_argument("scenario", type=Path, help="scenario folder or ASTERIX recording (see docs/formats.md)")
    p.add_argument("--out", type=Path, required=True, help="output folder (new or empty; see --overwrite)")
    p.add_argument("--profile", type=Path, default=None,
                   help="thresholds and standards, a TOML or JSON file (default: the 1997 EUROCONTROL radar "
                        "standard and ESASSP 5 NM, radartracker/data/assessment-eurocontrol-1997.toml)")
    p.add_argument("--system-tracks", type=Path, default=None, metavar="FILE",
                   help="score the system tracks of this CAT062 recording (raw, FINAL or pcap) instead of the "
                        "replay's own; the radars' figures still come from the replay (docs/assessment.md)")
    p.add_argument("--track-gap-s", type=float, default=60.0, metavar="SECONDS",
                   help="with --system-tracks: a CAT062 track number's updates further apart than this are two "
                        "tracks, the number reused (default 60)")
    p.add_argument("--no-reconstruct", dest="reconstruct", action="store_false",
                   help="without truth, judge against the validated ADS-B alone; by default the other aircraft are "
                        "reconstructed from their plots, the replay's bias estimates removed (docs/assessment.md)")
    p.add_argument("--reconstructor", default="multi-hypothesis", metavar="NAME",
                   help="the reconstructor plugin of the reference without truth (default multi-hypothesis)")
    p.add_argument("--estimator", default=None, help="the joint bias estimator (default: the best installed)")
    p.add_argument("--skip-bad", action="store_true", help="skip (and count) malformed input rows instead of stopping")
    p.add_argument("--overwrite", action="store_true", help="replace an earlier assessment's files in --out")
    p.add_argument("--slice-s", type=float, default=3600.0, metavar="SECONDS",
                   help="assess the recording in time slices of this length, each radar's slice one task "
                        "(default 3600: up to an hour stays one slice)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="run the slices on a Dask LocalCluster of N processes on 127.0.0.1 (default: this process)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the slices on an existing Dask scheduler (tcp://host:8786) instead")
    p.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS, help="no progress bars, no library logs")
    p.set_defaults(func=_cmd_assess)


def _slices(args: argparse.Namespace):
    """The slicing options as a SliceConfig; a bad value is a ConfigurationError naming the option."""
    from radartracker.assessment.slices import SliceConfig
    from radartracker.errors import ConfigurationError

    if not args.slice_s > 0:
        raise ConfigurationError(f"--slice-s: expected a positive number of seconds, got {args.slice_s}")
    if args.workers is not None and args.workers < 1:
        raise ConfigurationError(f"--workers: expected 1 or more, got {args.workers}")
    return SliceConfig(args.slice_s, args.workers, args.scheduler)


def _system(args: argparse.Namespace):
    """The CAT062 track options as a SystemTrackConfig; a bad value is a ConfigurationError naming the option."""
    from radartracker.assessment.systracks import SystemTrackConfig
    from radartracker.errors import ConfigurationError

    if not args.track_gap_s > 0:
        raise ConfigurationError(f"--track-gap-s: expected a positive number of seconds, got {args.track_gap_s}")
    return SystemTrackConfig(max_gap_s=args.track_gap_s)


def _cmd_assess(args: argparse.Namespace) -> int:
    from radartracker.assessment.assess import AssessmentConfig, assess
    from radartracker.assessment.profile import load_profile
    from radartracker.assessment.reference import ReferenceConfig
    from radartracker.assessment.writer import ASSESSMENT_FILES, write_assessment
    from radartracker.io.atomic import prepare_output_folder, removed_if_failed
    from radartracker.io.sources import read_source
    from radartracker.pipeline.config import RunConfig

    profile = load_profile(args.profile)  # a bad profile is refused before the work
    slices = _slices(args)
    system = _system(args)
    progress = not getattr(args, "quiet", False)
    with removed_if_failed(args.out):
        out = prepare_output_folder(args.out, ASSESSMENT_FILES, overwrite=args.overwrite, keep_earlier=True)
        data = read_source(args.scenario, skip_bad=args.skip_bad)
        config = AssessmentConfig(run=RunConfig(estimator=args.estimator, skip_bad=args.skip_bad),
                                  reference=ReferenceConfig(reconstruct=args.reconstruct,
                                                            reconstructor=args.reconstructor),
                                  slices=slices, system=system)
        a = assess(data, profile, config, progress=progress, system_tracks=args.system_tracks)
        write_assessment(a, out, progress=progress)
    counts = a.summary()["verdict_counts"]
    left = f" ({len(a.reference_left_out)} aircraft without a reference)" if a.reference_left_out else ""
    print(f"assessed {len(a.radars)} radars of {data.name or args.scenario} against the {a.reference}{left}; "
          f"profile {profile.name!r}: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())))
    print(f"system tracks: {a.system_source}")
    print(f"outputs in {out} (report.html)")
    return 0

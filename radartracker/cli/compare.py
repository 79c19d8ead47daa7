"""``radartracker compare``: the same scenario through several estimators, one table and two figures."""

from __future__ import annotations

import argparse
from pathlib import Path

from radartracker.errors import ConfigurationError


def register_compare(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("compare", help="run several estimators on the same scenario and compare them")
    p.add_argument("scenario", type=Path, help="scenario folder (see docs/formats.md)")
    p.add_argument("--estimators", default="decoupled,blom,coupled",
                   help="comma-separated estimator plugins (default: decoupled,blom,coupled)")
    p.add_argument("--out", type=Path, required=True, help="output folder for comparison.md, scores.json, figures")
    p.add_argument("--q", type=float, default=None, help="process noise density q (m²/s³); default 0")
    p.add_argument("--skip-bad", action="store_true", help="skip (and count) malformed input rows")
    p.set_defaults(func=_cmd_compare)


def _cmd_compare(args: argparse.Namespace) -> int:
    from radartracker.pipeline.compare import run_comparison, write_comparison
    from radartracker.io.sources import read_source
    from radartracker.registry import available_estimators
    from radartracker.pipeline.replay import ReplayOptions

    names = [n.strip() for n in args.estimators.split(",") if n.strip()]
    unknown = [n for n in names if n not in available_estimators()]
    if not names or unknown:
        raise ConfigurationError(f"--estimators: unknown {', '.join(unknown) or '(none given)'}; "
                       f"installed: {', '.join(available_estimators())}")
    data = read_source(args.scenario, skip_bad=args.skip_bad)
    results = run_comparison(data, names, ReplayOptions.for_scenario(data, q=args.q))
    write_comparison(results, args.out)
    print((args.out / "comparison.md").read_text(), end="")
    print(f"outputs in {args.out}")
    return 0

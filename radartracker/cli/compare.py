"""``radartracker compare``: the same scenario through several estimators, one table and two figures."""

from __future__ import annotations

import argparse
from pathlib import Path

from radartracker.cli.replay import add_run_options, run_config
from radartracker.errors import ConfigurationError


def register_compare(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("compare", help="run several estimators on the same scenario and compare them")
    p.add_argument("scenario", type=Path, help="scenario folder (see docs/formats.md)")
    p.add_argument("--estimators", default="decoupled,blom,coupled",
                   help="comma-separated estimator plugins (default: decoupled,blom,coupled)")
    p.add_argument("--out", type=Path, required=True, help="output folder for comparison.md, scores.json, figures")
    add_run_options(p, estimator_options=False)  # one plugin's options would be unknown to the others
    p.set_defaults(func=_cmd_compare)


def _cmd_compare(args: argparse.Namespace) -> int:
    from radartracker.io.atomic import prepare_output_folder, removed_if_failed, replace_outputs
    from radartracker.io.sources import read_source
    from radartracker.pipeline.compare import COMPARISON_FILES, run_comparison, write_comparison
    from radartracker.registry import available_estimators

    names = [n.strip() for n in args.estimators.split(",") if n.strip()]
    unknown = [n for n in names if n not in available_estimators()]
    if not names or unknown:
        raise ConfigurationError(f"--estimators: unknown {', '.join(unknown) or '(none given)'}; "
                                 f"installed: {', '.join(available_estimators())}")
    config = run_config(args)
    with removed_if_failed(args.out):  # a comparison that fails leaves no empty --out of its own making
        # an earlier comparison stays until this one's files are all written (replace_outputs)
        out = prepare_output_folder(args.out, COMPARISON_FILES, overwrite=args.overwrite, keep_earlier=True)
        data = read_source(args.scenario, skip_bad=config.skip_bad)
        results = run_comparison(data, names, config, progress=not getattr(args, "quiet", False))
        with replace_outputs(out, COMPARISON_FILES, last="comparison.md") as stage:
            write_comparison(results, out, stage=stage)
    print((out / "comparison.md").read_text(), end="")
    print(f"outputs in {out}")
    return 0

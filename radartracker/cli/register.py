"""``radartracker register``: every radar's bias components on a labelled scenario, each beside its Cramér–Rao
bound and its observability (:mod:`radartracker.pipeline.registration`; docs/estimators.md)."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from radartracker.errors import ConfigurationError

#: each component beyond the two offsets: its prior σ's command-line option, that option's attribute, its default
EXTRA = {"range_gain": ("--range-gain-sd", "range_gain_sd"), "time_offset": ("--time-offset-sd-s", "time_offset_sd_s")}
UNITS = {"range_offset": (1.0, "m"), "azimuth_offset": (math.degrees(1.0), "deg"), "range_gain": (1e6, "ppm"),
         "time_offset": (1e3, "ms")}


def register_register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("register", help="estimate every radar's bias components (range and azimuth offsets, range "
                                        "gain, time offset) on a labelled scenario, beside their Cramér–Rao bound")
    p.add_argument("scenario", type=Path, help="scenario folder whose plots carry truth labels (docs/formats.md)")
    p.add_argument("--components", default="range_gain,time_offset",
                   help="components beyond the range and azimuth offsets, comma-separated, or 'none' "
                        "(default: range_gain,time_offset)")
    p.add_argument("--range-gain-sd", type=float, dest=EXTRA["range_gain"][1],
                   help="prior σ of every radar's range gain (default 1e-3)")
    p.add_argument("--time-offset-sd-s", type=float, dest=EXTRA["time_offset"][1],
                   help="prior σ of every radar's time-stamp offset, s (default 0.5)")
    p.add_argument("--q", type=float, default=0.0, help="aircraft white-acceleration density, m²/s³ (default 0)")
    p.add_argument("--json", type=Path, help="also write the report to this JSON file")
    p.set_defaults(func=_cmd_register)


def _config(args: argparse.Namespace, radar_ids: list[str]):
    import attrs

    from radartracker.estimation.base import EstimatorConfig
    from radartracker.estimation.motion import MotionModel
    from radartracker.estimation.sensor import EXTRA_PRIOR_SD, BiasComponent
    from radartracker.settings import check_number

    names = [] if args.components.strip() == "none" else [n.strip() for n in args.components.split(",") if n.strip()]
    if unknown := [n for n in names if n not in EXTRA]:
        raise ConfigurationError(f"--components: unknown {unknown[0]!r}; known: {', '.join(EXTRA)} or none")
    given = {n: getattr(args, EXTRA[n][1]) for n in names}
    extra = tuple(BiasComponent(n, EXTRA_PRIOR_SD[n] if v is None else
                                check_number(EXTRA[n][0], v, lo=0.0, lo_open=True)) for n, v in given.items())
    base = EstimatorConfig(motion=MotionModel(check_number("--q", args.q, lo=0.0)))
    return attrs.evolve(base, sensors={r: base.sensor(r).with_components(*extra) for r in radar_ids})


def _cmd_register(args: argparse.Namespace) -> int:
    from radartracker.io.atomic import write_text
    from radartracker.io.sources import read_source
    from radartracker.pipeline.registration import register

    data = read_source(args.scenario)
    if not data.plots.has_truth_labels:
        raise ConfigurationError(f"{args.scenario}: register needs every plot labelled with its aircraft (the "
                                 "'target' column of a simulated scenario)")
    result = register(data, _config(args, [r.id for r in data.radars]))
    print("radar  component        estimate      σ             √CRLB         z       observability")
    for c in result.components:
        k, unit = UNITS[c.component]
        print(f"{c.radar:6s} {c.component:16s} {_num(c.estimate * k, unit)} {_num(c.sd * k, unit)} "
              f"{_num(c.crlb_sd * k, unit)} {c.z:+7.2f} {c.status}")
    print(f"position RMSE {result.position_rmse_m:.1f} m")
    if args.json is not None:
        rows = [{"radar": c.radar, "component": c.component, "estimate": c.estimate, "sd": c.sd, "crlb_sd": c.crlb_sd,
                 "status": c.status, "truth": _finite(c.truth), "z": _finite(c.z)} for c in result.components]
        write_text(args.json, json.dumps({"components": rows, "position_rmse_m": _finite(result.position_rmse_m)},
                                         indent=1))
    return 0


def _num(value: float, unit: str) -> str:
    return f"{value:9.4g} {unit:4s}"


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None

"""The same scenario judged against its truth and against its ADS-B alone (docs/assessment.md, "The
reference"): what the ADS-B reference costs a radar's figures. Prints one Markdown row per radar.

    python scripts/assessment_reference.py [--scenario paris] [--duration 1800] [--seed 1]
"""

from __future__ import annotations

import argparse
import math

import attrs

from radartracker.assessment.assess import assess
from radartracker.assessment.profile import load_profile
from radartracker.assessment.stats import Estimate
from radartracker.simulation.scenarios import build_scenario


def _f(e: Estimate) -> str:
    return f"{e.value:.4g} [{e.low:.4g}, {e.high:.4g}]"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="paris")
    p.add_argument("--duration", type=float, default=1800.0)
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args()
    sim = build_scenario(args.scenario, seed=args.seed, duration=args.duration)
    data = sim.run()
    truth = assess(data, load_profile(), progress=False)
    adsb = assess(attrs.evolve(data, truth=None), load_profile(), progress=False)
    print(f"{args.scenario}, {args.duration:g} s, seed {args.seed}: {len(data.plots)} plots; "
          f"intervals at 95 %")
    print("| radar | σ_r true (m) | σ_r vs truth | σ_r vs ADS-B | σ_θ true (deg) | σ_θ vs truth | σ_θ vs ADS-B "
          "| Pd vs truth | Pd vs ADS-B |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for sr, a, b in zip(sim.radars, truth.radars, adsb.radars):
        r = sr.radar
        print(f"| {r.id} | {r.sigma_range_m:g} | {_f(a.figures['range_sigma_m'])} | {_f(b.figures['range_sigma_m'])} "
              f"| {math.degrees(r.sigma_azimuth_rad):g} | {_f(a.figures['azimuth_sigma_deg'])} "
              f"| {_f(b.figures['azimuth_sigma_deg'])} | {_f(a.figures['pd'])} | {_f(b.figures['pd'])} |")


if __name__ == "__main__":
    main()

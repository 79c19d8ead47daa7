"""The same scenario judged against its truth, against its ADS-B alone and against its ADS-B with the other
aircraft reconstructed (the default without truth; docs/assessment.md, "The reference"): what each reference costs a
radar's figures. Prints one Markdown row per radar, and the CPU seconds of each assessment.

    python scripts/assessment_reference.py [--scenario paris] [--duration 1800] [--seed 1]
"""

from __future__ import annotations

import argparse
import math
import time

import attrs

from radartracker.assessment.assess import AssessmentConfig, assess
from radartracker.assessment.profile import load_profile
from radartracker.assessment.reference import ReferenceConfig
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
    hidden = attrs.evolve(data, truth=None)
    cpu = {}
    runs = {}
    adsb_only = AssessmentConfig(reference=ReferenceConfig(reconstruct=False))
    for name, scenario, config in (("truth", data, None), ("ADS-B", hidden, adsb_only),
                                   ("ADS-B + rec.", hidden, AssessmentConfig(reference=ReferenceConfig(reconstruct=True)))):
        started = time.process_time()
        runs[name] = assess(scenario, load_profile(), config, progress=False)
        cpu[name] = time.process_time() - started
    print(f"{args.scenario}, {args.duration:g} s, seed {args.seed}: {len(data.plots)} plots; "
          f"intervals at 95 %; CPU s per assessment: " + ", ".join(f"{k} {v:.1f}" for k, v in cpu.items()))
    for what, unit, true in (("range_sigma_m", "σ_r (m)", lambda sr: sr.radar.sigma_range_m),
                             ("azimuth_sigma_deg", "σ_θ (deg)", lambda sr: math.degrees(sr.radar.sigma_azimuth_rad)),
                             ("pd", "Pd", lambda sr: sr.pd)):
        print(f"\n| radar | {unit} true | " + " | ".join(f"vs {k}" for k in runs) + " |")
        print("| --- | --- | " + " | ".join("---" for _ in runs) + " |")
        for k, sr in enumerate(sim.radars):
            cells = [_f(a.radars[k].figures[what]) for a in runs.values()]
            print(f"| {sr.radar.id} | {true(sr):g} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()

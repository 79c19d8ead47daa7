"""Monte Carlo of the assessment against known truth (docs/assessment.md, "Checked against known truth").

Each run simulates the ``tracking`` scenario (two radars with known range and azimuth biases, σ, Pd 0.9 and
two false plots per revolution; radar A also with a range gain of 3·10⁻⁴ and a time-stamp offset of 100 ms,
:data:`SENSOR_ERRORS`) with its own seed, plants wrong Mode 3/A, Mode C and Mode S codes, split plots and
disordered time stamps at known rates (radartracker.simulation.faults), assesses it against the truth and
checks, per radar and figure, whether the 95 % interval holds the true value (a figure not assessed, e.g. a
component found unobservable, does not). Prints one row per
figure: the runs × radars, how often the interval held the truth (coverage; 95 % expected), the mean
estimate against the truth and the mean interval width.

    python scripts/assessment_montecarlo.py [--runs 40] [--duration 600] [--biases-only]
"""

from __future__ import annotations

import argparse
from collections import defaultdict

import numpy as np
from scipy import stats

from radartracker.assessment.assess import assess
from radartracker.simulation.faults import Faults, known_figures, plant
from radartracker.assessment.profile import INDICATORS, load_profile
from radartracker.progress import progress_bar
from radartracker.simulation.scenarios import build_scenario, with_sensor_errors

FAULTS = Faults(wrong_mode_3a=0.03, wrong_mode_c=0.02, wrong_mode_s=0.03, split=0.02, out_of_order=0.01,
                reflection=0.02)
SENSOR_ERRORS = {"A": {"range_gain": 3e-4, "time_offset_s": 0.1}}


def monte_carlo(runs: int, duration: float, first_seed: int = 1,
                sensor_errors: dict[str, dict[str, float]] | None = None) -> dict[str, list[tuple]]:
    """Per figure: (radar, truth, estimate, low, high) of every radar of every run with a true value, the
    radars given ``sensor_errors`` (:data:`SENSOR_ERRORS` by default; ``{}``: range and azimuth biases only)."""
    sensor_errors = SENSOR_ERRORS if sensor_errors is None else sensor_errors
    rows: dict[str, list] = defaultdict(list)
    profile = load_profile()
    for seed in progress_bar(range(first_seed, first_seed + runs), desc="runs", total=runs):
        sim = with_sensor_errors(build_scenario("tracking", seed=seed, duration=duration), sensor_errors)
        data = plant(sim.run(), FAULTS, seed=seed)
        a = assess(data, profile, progress=False)
        truth = known_figures(sim.radars, data.truth_biases, FAULTS)
        for r in a.radars:
            for name, value in truth[r.radar].items():
                e = r.figures.get(name)
                rows[name].append((r.radar, value, *((e.value, e.low, e.high) if e else (np.nan,) * 3)))
    return rows


def table(rows: dict[str, list], runs: int, duration: float) -> str:
    """The Markdown table of the module docstring; the coverage's own 95 % band is that of a binomial."""
    lines = [f"{runs} runs, {duration:g} s each; each figure's coverage with its binomial 95 % band for a 95 % "
             "interval", "",
             "| figure | truth (radar A; B) | mean estimate − truth | mean 95 % width | coverage | band |",
             "| --- | --- | --- | --- | --- | --- |"]
    for name, r in rows.items():
        x = np.array([v[1:] for v in r], float)
        inside = (x[:, 2] <= x[:, 0]) & (x[:, 0] <= x[:, 3])
        first = {}
        for radar, value, *_ in r:
            first.setdefault(radar, value)
        truths = "; ".join(f"{first[k]:.4g}" if k in first else "—" for k in ("A", "B"))
        lo, hi = stats.binom.ppf([0.025, 0.975], len(x), 0.95) / len(x)
        label, unit = INDICATORS[name]
        lines.append(f"| {label}{f' ({unit})' if unit else ''} | {truths} | "
                     f"{np.nanmean(x[:, 1] - x[:, 0]):+.3g} | {np.nanmean(x[:, 3] - x[:, 2]):.3g} | "
                     f"{100 * inside.mean():.1f} % of {len(x)} | {100 * lo:.1f}–{100 * hi:.1f} % |")
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=40)
    p.add_argument("--duration", type=float, default=600.0)
    p.add_argument("--biases-only", action="store_true", help="no range gain or time offset on radar A")
    args = p.parse_args()
    rows = monte_carlo(args.runs, args.duration, sensor_errors={} if args.biases_only else SENSOR_ERRORS)
    print(table(rows, args.runs, args.duration))


if __name__ == "__main__":
    main()

"""Monte Carlo of the assessment against known truth (docs/assessment.md, "Checked against known truth").

Each run simulates the ``tracking`` scenario (two radars with known range and azimuth biases, σ, Pd 0.9 and
two false plots per revolution) with its own seed, plants wrong Mode 3/A, Mode C and Mode S codes, split
plots and disordered time stamps at known rates (radartracker.simulation.faults), assesses it against the
truth and checks, per radar and figure, whether the 95 % interval holds the true value. Prints one row per
figure: the runs × radars, how often the interval held the truth (coverage; 95 % expected), the mean
estimate against the truth and the mean interval width.

    python scripts/assessment_montecarlo.py [--runs 40] [--duration 600]
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
from radartracker.simulation.scenarios import build_scenario

FAULTS = Faults(wrong_mode_3a=0.03, wrong_mode_c=0.02, wrong_mode_s=0.03, split=0.02, out_of_order=0.01)


def monte_carlo(runs: int, duration: float, first_seed: int = 1) -> dict[str, list[tuple[float, float, float, float]]]:
    """Per figure: (truth, estimate, low, high) of every radar of every run."""
    rows: dict[str, list] = defaultdict(list)
    profile = load_profile()
    for seed in progress_bar(range(first_seed, first_seed + runs), desc="runs", total=runs):
        sim = build_scenario("tracking", seed=seed, duration=duration)
        data = plant(sim.run(), FAULTS, seed=seed)
        a = assess(data, profile, progress=False)
        truth = known_figures(sim.radars, data.truth_biases, FAULTS)
        for r in a.radars:
            for name, value in truth[r.radar].items():
                e = r.figures[name]
                rows[name].append((value, e.value, e.low, e.high))
    return rows


def table(rows: dict[str, list], runs: int, duration: float) -> str:
    """The Markdown table of the module docstring; the coverage's own 95 % band is that of a binomial."""
    n = len(next(iter(rows.values())))
    lo, hi = stats.binom.ppf([0.025, 0.975], n, 0.95) / n
    lines = [f"{runs} runs × 2 radars = {n} intervals per figure, {duration:g} s each; a coverage of 95 % "
             f"gives {100 * lo:.1f}–{100 * hi:.1f} % in {n} intervals (binomial 95 %)", "",
             "| figure | truth (radar A; B) | mean estimate − truth | mean 95 % width | coverage |",
             "| --- | --- | --- | --- | --- |"]
    for name, r in rows.items():
        x = np.array(r)
        inside = (x[:, 2] <= x[:, 0]) & (x[:, 0] <= x[:, 3])
        truths = "; ".join(f"{v:.4g}" for v in x[:2, 0])
        label, unit = INDICATORS[name]
        lines.append(f"| {label}{f' ({unit})' if unit else ''} | {truths} | "
                     f"{np.mean(x[:, 1] - x[:, 0]):+.3g} | {np.mean(x[:, 3] - x[:, 2]):.3g} | "
                     f"{100 * inside.mean():.1f} % |")
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=40)
    p.add_argument("--duration", type=float, default=600.0)
    args = p.parse_args()
    rows = monte_carlo(args.runs, args.duration)
    print(table(rows, args.runs, args.duration))


if __name__ == "__main__":
    main()

"""Known faults planted in a scenario, so that the assessment can be checked against a known truth
(tests/assessment, scripts/assessment_montecarlo.py). The simulator (:mod:`radartracker.simulation.simulator`) makes
biases, noise, Pd < 1 and false plots but no wrong codes, split plots or disordered time stamps; these are
planted here, each plot independently with its stated probability:

* a wrong Mode 3/A code (the last octal digit changed), a wrong Mode C altitude (+1000 ft) or a wrong Mode S
  address (the last hex digit changed), among the plots that carry one;
* a split plot: a second plot of the same sweep, 1 ms later and ``split_offset_m`` farther in range;
* a plot out of time order: of two consecutive plots of a radar (pairs taken without overlap) the two rows
  exchanged, with probability 2 × ``out_of_order`` per pair, so that this share of the plots is stamped
  earlier than the plot before it in the file;
* a reflection: the aircraft's reply, with its codes, seen a second time off a reflector, 20°–160° away in
  azimuth (either side) and up to ``reflection_extra_m`` farther, stamped when the antenna pointed there (in
  the same revolution, T·Δθ/2π later); it carries no truth label (it is not where an aircraft is). Drawn
  from a generator of its own, so that planting none leaves the other faults' draws as they were.
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from radartracker.io.tables import ScenarioData, concat_tables
from radartracker.simulation.simulator import SimRadar

_FT = 0.3048


@attrs.frozen
class Faults:
    """The probabilities of the module docstring (each in [0, 0.5])."""

    wrong_mode_3a: float = 0.0
    wrong_mode_c: float = 0.0
    wrong_mode_s: float = 0.0
    split: float = 0.0
    out_of_order: float = 0.0
    reflection: float = 0.0
    split_offset_m: float = 300.0
    reflection_extra_m: float = 2000.0


def plant(data: ScenarioData, faults: Faults, seed: int = 0) -> ScenarioData:
    """``data`` with ``faults`` planted in its plots (module docstring); the rest unchanged."""
    rng = np.random.default_rng([seed, 31])
    p = data.plots.take(np.arange(len(data.plots)))  # a copy: the columns are changed in place
    hit = rng.random((3, len(p)))
    for draw, col, rate, change in ((hit[0], p.mode_3a, faults.wrong_mode_3a, lambda c: c[:3] + str((int(c[3]) + 1) % 8)),
                                    (hit[2], p.mode_s, faults.wrong_mode_s, lambda c: c[:5] + f"{(int(c[5], 16) + 1) % 16:x}")):
        rows = np.flatnonzero((draw < rate) & np.array([c is not None for c in col]))
        col[rows] = [change(c) for c in col[rows]]
    alt = np.isfinite(p.altitude_m) & (hit[1] < faults.wrong_mode_c)
    p.altitude_m[alt] += 1000 * _FT
    labelled = np.array([t is not None for t in p.target], bool)
    split = np.flatnonzero(labelled & (rng.random(len(p)) < faults.split))
    extra = p.take(split)
    extra.time = extra.time + 1e-3
    extra.range_m = extra.range_m + faults.split_offset_m
    reflections = _reflections(data.plots, labelled, faults, data.radars, np.random.default_rng([seed, 37]))
    merged = concat_tables([p, extra, reflections])
    order = np.argsort(merged.time, kind="stable")
    plots = merged.take(_disorder(merged.radar[order], order, faults.out_of_order, rng))
    return attrs.evolve(data, plots=plots)


def _reflections(p, labelled: np.ndarray, faults: Faults, radars: list, rng: np.random.Generator):
    """The reflections of the module docstring of the labelled plots of ``p`` (the plot table as simulated,
    before any code was made wrong: a reflection repeats the reply the aircraft sent)."""
    rows = np.flatnonzero(labelled & (rng.random(len(p)) < faults.reflection))
    out = p.take(rows)
    turn = rng.choice([-1.0, 1.0], len(rows)) * rng.uniform(math.radians(20.0), math.radians(160.0), len(rows))
    period = {r.id: r.period_s for r in radars}
    out.azimuth_rad = np.mod(out.azimuth_rad + turn, 2 * math.pi)
    out.time = out.time + np.mod(turn, 2 * math.pi) / (2 * math.pi) * np.array([period[r] for r in out.radar.tolist()])
    out.range_m = out.range_m + rng.uniform(0.0, faults.reflection_extra_m, len(rows))
    out.target = np.full(len(rows), None, dtype=object)
    return out


def _disorder(radar: np.ndarray, order: np.ndarray, share: float, rng: np.random.Generator) -> np.ndarray:
    """``order`` (row indices in time order) with, per radar, pairs of consecutive plots (0-1, 2-3, …) swapped
    with probability 2 × ``share``."""
    out = order.copy()
    for rid in np.unique(radar.astype(str)).tolist():
        pos = np.flatnonzero(radar == rid)
        pairs = pos[: len(pos) // 2 * 2].reshape(-1, 2)
        swap = pairs[rng.random(len(pairs)) < 2 * share]
        out[swap[:, 0]], out[swap[:, 1]] = order[swap[:, 1]], order[swap[:, 0]]
    return out


def known_figures(radars: list[SimRadar], truth_biases: dict[str, tuple[float, float]], faults: Faults
                  ) -> dict[str, dict[str, float]]:
    """The true value of each figure a simulation with ``faults`` planted should give, per radar id: the
    simulated biases (``truth_biases``: Δr m, Δθ rad), range gain and time-stamp offset, noise, Pd and false
    plot rate (``radars``), the planted rates, and the time-stamp jitter σ_θ T/2π of an exact clock. A radar with
    a range gain or a time-stamp offset has no true value for the joint estimator's two-component biases (that
    model has no term for them): those two figures are left out for it."""
    out = {}
    for sr in radars:
        r = sr.radar
        bias_r, bias_a = truth_biases[r.id]
        two = {} if sr.range_gain or sr.time_offset_s else {"range_bias_m": bias_r,
                                                             "azimuth_bias_deg": math.degrees(bias_a)}
        out[r.id] = {**two, "range_bias_vs_reference_m": bias_r, "azimuth_bias_vs_reference_deg": math.degrees(bias_a),
                     "range_gain_ppm": 1e6 * sr.range_gain, "time_offset_ms": 1e3 * sr.time_offset_s,
                     "range_sigma_m": r.sigma_range_m, "azimuth_sigma_deg": math.degrees(r.sigma_azimuth_rad),
                     "pd": sr.pd, "false_plots_per_scan": sr.false_per_scan, "split_plot_share": faults.split,
                     "mode_3a_validity": 1.0, "mode_3a_correctness": 1.0 - faults.wrong_mode_3a,
                     "mode_c_validity": 1.0, "mode_c_correctness": 1.0 - faults.wrong_mode_c,
                     "mode_s_correctness": 1.0 - faults.wrong_mode_s, "out_of_order_share": faults.out_of_order,
                     "reflection_share": faults.reflection,
                     "timestamp_jitter_s": r.sigma_azimuth_rad * r.period_s / (2 * math.pi)}
    return out

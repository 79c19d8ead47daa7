"""The Monte Carlo of ``scripts/assessment_montecarlo.py`` (the tables of docs/assessment.md): over 40 runs of
the ``tracking`` scenario with planted faults, each figure's 95 % interval must hold the true value as often
as a 95 % interval does — within the binomial band of its intervals, widened to its 99.9 % quantile since
18 figures are checked at once. Twice: with range and azimuth biases only, and with radar A also given a range
gain of 3·10⁻⁴ and a 100 ms time-stamp offset. In the second the joint estimator's two-component biases are
not checked, for either radar: that model has no term for A's gain and offset, which pull B's estimate too
(docs/assessment.md shows by how much; issue 30 is the estimator carrying them)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binom

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "assessment_montecarlo.py"
JOINT = ("range_bias_m", "azimuth_bias_deg")


def _script():
    spec = importlib.util.spec_from_file_location("assessment_montecarlo", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
@pytest.mark.parametrize("sensor_errors", [{}, None], ids=["biases-only", "gain-and-time-offset"])
def test_every_figure_covers_its_truth_95_percent_of_the_time(sensor_errors):
    mc = _script()
    rows = mc.monte_carlo(runs=40, duration=600.0, sensor_errors=sensor_errors)
    print(mc.table(rows, 40, 600.0))
    for name, r in rows.items():
        if sensor_errors is None and name in JOINT:
            continue
        x = np.array([v[1:] for v in r], float)
        inside = int(((x[:, 2] <= x[:, 0]) & (x[:, 0] <= x[:, 3])).sum())
        assert inside >= binom.ppf(0.001, len(x), 0.95), f"{name}: {inside} of {len(x)} intervals hold the truth"

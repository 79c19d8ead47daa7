"""The Monte Carlo of ``scripts/assessment_montecarlo.py`` (the table of docs/assessment.md): over 40 runs of
the ``tracking`` scenario with planted faults, each figure's 95 % interval must hold the true value as often
as a 95 % interval does — within the binomial band of 80 intervals, widened to its 99.9 % quantile since
16 figures are checked at once."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binom

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "assessment_montecarlo.py"


def _script():
    spec = importlib.util.spec_from_file_location("assessment_montecarlo", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_every_figure_covers_its_truth_95_percent_of_the_time():
    mc = _script()
    rows = mc.monte_carlo(runs=40, duration=600.0)
    print(mc.table(rows, 40, 600.0))
    for name, r in rows.items():
        x = np.array(r)
        inside = int(((x[:, 2] <= x[:, 0]) & (x[:, 0] <= x[:, 3])).sum())
        assert inside >= binom.ppf(0.001, len(x), 0.95), f"{name}: {inside} of {len(x)} intervals hold the truth"

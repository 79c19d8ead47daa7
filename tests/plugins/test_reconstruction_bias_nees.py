"""Consistency of the joint bias estimate's covariance: a Monte Carlo NEES against χ².

Oracle: over M independent simulated runs (the project's radar simulator, two biased radars, four
flights of the seed's model, :func:`~radartracker_plugins.reconstruction.sim.biased_scenario`), the
normalised estimation error squared of each radar's jointly estimated bias,
ε = (ς̂ − ς)ᵀ P⁻¹ (ς̂ − ς), is χ²(2) when P is right, so the sum over M runs and 2 radars is
χ²(4M) (Bar-Shalom, Li & Kirubarajan 2001, §5.4; the two radars' errors are correlated, which
widens the sum's spread a little); it is held to the two-sided 99 % interval of
``scipy.stats.chi2``. The quick version starts every flight's fit from its true segment structure
(what the covariance is conditional on) and runs the joint rounds; the slow one runs the
hypothesis search first, on more runs (``scripts/reconstruction_bias_nees.py`` prints both, and the
two-step way's).
"""

import numpy as np
import pytest
from scipy.stats import chi2

from radartracker_plugins.reconstruction import ReconstructionConfig
from radartracker_plugins.reconstruction.engine import run_many
from radartracker_plugins.reconstruction.hypotheses import Reconstruction, refit
from radartracker_plugins.reconstruction.integrate import geo_track
from radartracker_plugins.reconstruction.joint import joint_rounds
from radartracker_plugins.reconstruction.sim import BIASES, biased_scenario, true_control
from radartracker_plugins.reconstruction.tracks import scenario_tracks

CFG = ReconstructionConfig(max_u=6.0, max_w=2.0, shooting=False, hypotheses=3)


def _nees(biases) -> list[float]:
    out = []
    for radar, true in BIASES.items():
        e = biases[radar].value - np.array(true)
        out.append(float(e @ np.linalg.solve(biases[radar].cov, e)))
    return out


def _chi2_interval(n_terms: int, level: float = 0.99) -> tuple[float, float]:
    return tuple(chi2.ppf([(1 - level) / 2, (1 + level) / 2], 2 * n_terms))


def test_joint_bias_nees_is_chi2_from_the_true_segment_structure():
    nees = []
    for seed in range(10):
        data, flights = biased_scenario(seed, 200.0)
        tracks, _, _ = scenario_tracks(data)
        recs = {}
        for pt in tracks:  # each flight fitted at zero biases, from its true segment structure
            ct = true_control(flights[pt.key], float(pt.t[0]), float(pt.t[-1]))
            recs[pt.key] = refit(Reconstruction(pt.key, pt, (), geo_track(ct, CFG.grid_dt), 0.0), pt, CFG)
        _, biases, _, change = joint_rounds(tracks, recs, CFG)
        assert change <= 1.0  # converged
        nees += _nees(biases)
    lo, hi = _chi2_interval(len(nees))
    assert lo < sum(nees) < hi, (sum(nees), lo, hi, nees)


@pytest.mark.slow
def test_joint_bias_nees_is_chi2_with_the_full_search():
    nees = []
    for seed in range(100, 130):
        data, _ = biased_scenario(seed, 200.0)
        tracks, _, _ = scenario_tracks(data)
        recs = {r.key: r for r in run_many(tracks, CFG, None, progress=False)}
        _, biases, _, _ = joint_rounds(tracks, recs, CFG)
        nees += _nees(biases)
    lo, hi = _chi2_interval(len(nees))
    assert lo < sum(nees) < hi, (sum(nees), lo, hi, nees)

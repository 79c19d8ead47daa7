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


SENSOR = {"R0": {"range_gain": 3e-4, "time_offset_s": 0.1}}  # 3·10⁻⁴: 15 m at 50 km; 0.1 s: 18 m at 180 m/s


def test_a_range_gain_and_time_offset_are_estimated_with_honest_sd():
    """R0 also has a range gain and a time-stamp offset. Over 20 runs (each flight fitted from its true segment
    structure), each component's Σ z² = Σ ((ς̂ − ς)/σ)² of the joint mode with those components stays under
    χ²₂₀'s 99.5 % quantile (its σ is not optimistic; with two radars and no ADS-B a time offset common to both is
    held by its prior, so those z are small), while the two offsets alone misplace R0's range offset beyond it
    (the gain and the offset it cannot model go into it)."""
    truth = {"R0": [*BIASES["R0"], 3e-4, 0.1], "R1": [*BIASES["R1"], 0.0, 0.0]}
    z2: dict[tuple, float] = {}
    for seed in range(20):
        data, flights = biased_scenario(seed, 200.0, SENSOR)
        tracks, _, _ = scenario_tracks(data)
        recs = {}
        for pt in tracks:
            ct = true_control(flights[pt.key], float(pt.t[0]), float(pt.t[-1]))
            recs[pt.key] = refit(Reconstruction(pt.key, pt, (), geo_track(ct, CFG.grid_dt), 0.0), pt, CFG)
        for components in ((), ("range_gain", "time_offset")):
            _, biases, _, change = joint_rounds(tracks, recs, CFG, components=components)
            assert change <= 1.0
            for radar, b in biases.items():
                assert b.model.names == ("range_offset", "azimuth_offset", *components)
                e = b.value - np.array(truth[radar][:len(b.value)])
                for k, name in enumerate(b.model.names):
                    z2[components, radar, name] = z2.get((components, radar, name), 0.0) + e[k] ** 2 / b.cov[k, k]
    limit = chi2.ppf(0.995, 20)
    full = {k: v for k, v in z2.items() if k[0]}
    assert len(full) == 8 and all(v < limit for v in full.values()), (full, limit)
    assert z2[(), "R0", "range_offset"] > limit, z2

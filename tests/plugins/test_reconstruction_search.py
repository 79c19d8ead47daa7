"""The hypothesis search: simple answers are always tried, merges as well as splits, a noise-aware start.

Oracles: the synthetic recording's flights are straight lines by construction (one segment is the
truth); signals built piecewise constant with known change points plus noise of known correlation;
the merge criterion recomputed by brute force over every neighbouring pair.
"""

import csv

import numpy as np
import pytest

from radartracker.cli import main
from radartracker.io.convert import ConvertOptions, convert
from radartracker.io.recording import write_synthetic_recording
from radartracker_plugins.reconstruction.hypotheses import merge, noise_aware_count
from radartracker_plugins.reconstruction.integrate import sample
from radartracker_plugins.reconstruction.objects import ControlSegment, ControlTrack, GeoPoint


@pytest.fixture(scope="module")
def new4_set(tmp_path_factory):
    base = tmp_path_factory.mktemp("straight")
    write_synthetic_recording(base / "rec", batches=1, aircraft_per_batch=2, flight_s=900.0)
    convert(base / "rec", base / "new", ConvertOptions())
    return base / "new"


def test_straight_flight_from_new4_chooses_one_segment(new4_set, tmp_path):
    out = tmp_path / "out"
    src = sorted(new4_set.glob("*/240_mr.new4"))[0]  # the multi-radar track of a straight synthetic flight
    assert main(["reconstruct", str(src), "--out", str(out), "--engine", "serial", "--quiet", "--no-figures"]) == 0
    folder = out / f"{src.parent.name}_240_mr"
    assert len(list(csv.DictReader(open(folder / "segments.csv")))) == 1
    hyps = list(csv.DictReader(open(folder / "hypotheses.csv")))
    assert {1, 2, 3} <= {int(h["segments"]) for h in hyps}  # the simple answers are always tried
    scores = [float(h["score"]) for h in hyps]
    assert scores == sorted(scores) and int(hyps[0]["segments"]) == 1


def _signal(rng, levels, lengths, noise, corr):
    """Piecewise-constant (N, 2) signal plus noise moving-averaged over ``corr`` samples."""
    clean = np.repeat(np.asarray(levels, float), lengths, axis=0)
    e = rng.normal(0, noise, (len(clean) + corr - 1, 2))
    e = np.column_stack([np.convolve(e[:, j], np.ones(corr) / np.sqrt(corr), mode="valid") for j in range(2)])
    return clean + e


def test_noise_aware_count_finds_the_pieces_and_ignores_correlated_noise():
    rng = np.random.default_rng(3)
    counts_noise, counts_steps = [], []
    for _ in range(5):
        noise_only = _signal(rng, [[0.0, 0.0]], [300], 1.0, 8)
        counts_noise.append(noise_aware_count(noise_only, 1.0, 8.0, 6, 20)[0])
        steps = _signal(rng, [[0.0, 0.0], [4.0, 0.0], [4.0, -3.0], [0.0, 0.0]], [80, 60, 70, 90], 1.0, 8)
        counts_steps.append(noise_aware_count(steps, 1.0, 8.0, 6, 20)[0])
    assert counts_noise == [1] * 5
    assert counts_steps == [4] * 5


def test_merge_joins_the_most_alike_neighbours_with_weighted_means():
    segs = [ControlSegment(0.0, 0.0, 0, 60), ControlSegment(3.0, 0.2, 60, 150),
            ControlSegment(2.8, 0.25, 150, 200), ControlSegment(-2.0, -0.4, 200, 300)]
    ct = ControlTrack(GeoPoint(0, 0.0, 0.0, 1.0, 150.0), segs)
    ward = [s.duration * n.duration / (s.duration + n.duration) * ((s.u - n.u) ** 2 + (s.w - n.w) ** 2)
            for s, n in zip(segs, segs[1:])]
    i = int(np.argmin(ward))
    got = merge(ct, 3)
    assert len(got) == 3 and got[i].t_start == segs[i].t_start and got[i].t_end == segs[i + 1].t_end
    d = segs[i].duration + segs[i + 1].duration
    assert got[i].u == pytest.approx((segs[i].u * segs[i].duration + segs[i + 1].u * segs[i + 1].duration) / d)
    # merging equal controls leaves the track unchanged
    same = ControlTrack(ct.initial, [ControlSegment(1.0, 0.1, 0, 100), ControlSegment(1.0, 0.1, 100, 300)])
    t = np.linspace(0, 300, 31)
    np.testing.assert_allclose(sample(merge(same, 1), t), sample(same, t), atol=1e-6)

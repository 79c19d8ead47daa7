"""The antenna-phase recurrence of the TrackManager (radartracker.tracking.coverage.smooth_phases)."""

import math

import numpy as np

from radartracker.tracking.coverage import smooth_phases


def test_compiled_phase_recurrence_is_the_python_loop_bit_for_bit():
    """smooth_phases equals ``p = p * 0.98 + e`` in Python, radar by radar (oracle: that loop), on phases
    and terms of all sizes, radars without plots among them, and zeros of either sign (the terms radar by
    radar, each with its radar's row)."""
    rng = np.random.default_rng(3)
    counts = rng.integers(0, 60, 40)
    counts[[0, 3, 17]] = 0
    counts[1] = 2
    terms = np.exp(1j * rng.uniform(-50, 50, counts.sum())) * rng.choice([1.0, 1e-300, 1e12], counts.sum())
    terms[:2] = complex(-0.0, -0.0)  # the second radar's: (−0 − 0i)(0.98 + 0i) is +0 − 0i
    start = [0j, complex(-0.0, -0.0)] + list(rng.normal(0, 30, 38) + 1j * rng.normal(0, 30, 38))
    want, k = [], 0
    for p, c in zip(start, counts):
        for e in terms[k:k + c].tolist():
            p = p * 0.98 + e
        want.append(p)
        k += c
    got = np.array(start, complex)
    smooth_phases(got, terms, np.repeat(np.arange(len(counts)), counts).astype(np.int64))
    assert [(z.real, z.imag, math.copysign(1, z.real), math.copysign(1, z.imag)) for z in got.tolist()] == \
        [(z.real, z.imag, math.copysign(1, z.real), math.copysign(1, z.imag)) for z in want]

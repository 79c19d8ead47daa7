"""Radar biases for reconstruction: read a replay's ``biases.csv``, correct plots with them.

A plot of radar j is z_i = p(t_i) + C_i ς_j + e_i, e_i ~ N(0, R_i) (seed 000 eq. 1.11). With a bias
estimate ς̂_j of covariance Σ_j (from a replay), the corrected plot and its covariance are::

    z̃_i = z_i − C_i ς̂_j,      R̃_i = R_i + C_i Σ_j C_iᵀ

The inflation is per plot: the error of ς̂_j is common to every plot of radar j, which this treats
as independent — so it understates how far a whole flight may be shifted, but keeps a poorly
known bias from being trusted as exact.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from pathlib import Path

import attrs
import numpy as np

from radartracker.api import FormatError
from radartracker_plugins.reconstruction.objects import PlotTrack

COLUMNS = ("time", "radar", "range_bias_m", "azimuth_bias_deg", "sd_range_m", "sd_azimuth_deg")


@attrs.frozen
class BiasEstimate:
    """One radar's bias ς = [Δr (m), Δθ (rad)] and its covariance (2×2, m and rad)."""

    value: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, float))
    cov: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, float), factory=lambda: np.zeros((2, 2)))


def read_biases(path: Path | str, radar_ids: set[str] | None = None) -> dict[str, BiasEstimate]:
    """The final bias per radar (its last row) of a replay's ``biases.csv`` (docs/formats.md).

    A bad row raises :class:`FormatError` naming the file, line and field; a radar not in
    ``radar_ids`` (when given) is one too.
    """
    path = Path(path)
    out: dict[str, BiasEstimate] = {}
    with open(path, newline="", encoding="utf-8") as f:
        rows = csv.reader(f)
        header = next(rows, None)
        if header is None or [h.strip() for h in header[:len(COLUMNS)]] != list(COLUMNS):
            raise FormatError(str(path), 1, None, f"expected the header {','.join(COLUMNS)}")
        for line, row in enumerate(rows, start=2):
            if not row:
                continue
            if len(row) < len(COLUMNS):
                raise FormatError(str(path), line, None, f"expected {len(COLUMNS)} fields, got {len(row)}")
            vals = {}
            for name, text in zip(COLUMNS[2:], row[2:len(COLUMNS)]):
                try:
                    vals[name] = float(text)
                except ValueError:
                    raise FormatError(str(path), line, name, f"not a number: {text!r}") from None
                if not math.isfinite(vals[name]) or (name.startswith("sd_") and vals[name] < 0):
                    raise FormatError(str(path), line, name, f"expected a finite{' non-negative' if name.startswith('sd_') else ''} number, got {text!r}")
            radar = row[1].strip()
            if radar_ids is not None and radar not in radar_ids:
                raise FormatError(str(path), line, "radar", f"unknown radar {radar!r}")
            sd = np.array([vals["sd_range_m"], math.radians(vals["sd_azimuth_deg"])])
            out[radar] = BiasEstimate([vals["range_bias_m"], math.radians(vals["azimuth_bias_deg"])], np.diag(sd**2))
    if not out:
        raise FormatError(str(path), 1, None, "no bias rows")
    return out


def debias(pt: PlotTrack, biases: Mapping[str, BiasEstimate | np.ndarray]) -> PlotTrack:
    """``pt`` with z̃ = z − C ς̂ and R̃ = R + C Σ Cᵀ for every radar with a bias (an array: Σ = 0)."""
    z, R = pt.z.copy(), pt.R.copy()
    for radar, b in biases.items():
        est = b if isinstance(b, BiasEstimate) else BiasEstimate(b)
        sel = pt.radar == radar
        if not sel.any():
            continue
        C = pt.C[sel]
        z[sel] -= C @ est.value
        R[sel] += C @ est.cov @ C.transpose(0, 2, 1)
    return attrs.evolve(pt, z=z, R=R)

"""Radar biases for reconstruction: read a replay's ``biases.csv``, correct plots with them.

A plot of radar j is z_i = p(t_i) + B_i ς_j + e_i, e_i ~ N(0, R_i) (seed 000 eq. 1.11, generalised to the
sensor model's components: B_i = C_i for the range and azimuth offsets; a range gain's column ρ_i c_ρ and a
time offset's −v(t_i), :meth:`radartracker.api.SensorModel.jacobians`). With a bias estimate ς̂_j of
covariance Σ_j (from a replay, or the joint estimate), the corrected plot and its covariance are::

    z̃_i = z_i − B_i ς̂_j,      R̃_i = R_i + B_i Σ_j B_iᵀ

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

from radartracker.api import FormatError, SensorModel
from radartracker_plugins.reconstruction.objects import PlotTrack

COLUMNS = ("time", "radar", "range_bias_m", "azimuth_bias_deg", "sd_range_m", "sd_azimuth_deg")


#: the components of a bias given as [Δr, Δθ] (their priors do not enter a correction)
OFFSETS = SensorModel.default(1.0, 1.0)


@attrs.frozen
class BiasEstimate:
    """One radar's bias ς and its covariance (m × m) in the components of ``model`` (default the range and
    azimuth offsets [Δr (m), Δθ (rad)]; SI units, :class:`radartracker.api.SensorModel`)."""

    value: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, float))
    cov: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, float),
                                  default=attrs.Factory(lambda self: np.zeros((len(self.value),) * 2), takes_self=True))
    model: SensorModel = OFFSETS


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


def debias(pt: PlotTrack, biases: Mapping[str, BiasEstimate | np.ndarray],
           velocity: np.ndarray | None = None) -> PlotTrack:
    """``pt`` with z̃ = z − B ς̂ and R̃ = R + B Σ Bᵀ for every radar with a bias (module docstring; an array: the
    offsets [Δr, Δθ], Σ = 0); ``velocity`` (n × 2, m/s): the aircraft's plane velocity at each plot, which a
    time offset's column needs (a reconstruction of the flight gives it)."""
    z, R = pt.z.copy(), pt.R.copy()
    for radar, b in biases.items():
        est = b if isinstance(b, BiasEstimate) else BiasEstimate(b)
        sel = pt.radar == radar
        if not sel.any():
            continue
        B = est.model.jacobians(pt.C[sel], pt.rho[sel], None if velocity is None else velocity[sel])
        z[sel] -= B @ est.value
        R[sel] += B @ est.cov @ B.transpose(0, 2, 1)
    return attrs.evolve(pt, z=z, R=R)

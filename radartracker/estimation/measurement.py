"""Radar plots and ADS-B reports converted to system-plane measurements, in bulk.

A plot (ρ, θ, altitude) of radar j becomes z = plane position of the exact 3-D point
(:meth:`RadarFrame.to_plane`), with the linearised model of DESIGN §4 / seed 000 eq. 1.11::

    z ≈ p + C_s ς_j + D w,   C_s = D = ∂p/∂(ρ, θ),   R = D W_j Dᵀ,   W_j = diag(σ_r², σ_θ²)

C_s and D are evaluated at the plot itself (a converted-measurement filter): the difference from
evaluating them at the estimate is of relative order σ/ρ ≈ 1e-3 of a bias-sized term, well below the
noise, and it makes the model linear in the estimated quantities, so every estimator sees exactly the
same C and R. An ADS-B report is z = plane position with C = 0 and R = σ²(NACp)·I.

Plots without an altitude take the altitude of the same aircraft's nearest plot in time (by Mode S
address or truth label); where none exists, ``default_altitude_m`` is assumed and counted.
"""

from __future__ import annotations

from collections import defaultdict

import attrs
import numpy as np

from radartracker.domain import NACP_EPU_M, Radar
from radartracker.io.tables import AdsbTable, PlotTable
from radartracker.geometry.plane import RadarFrame, SystemPlane


@attrs.frozen
class Measurements:
    """Plane measurements as columns: ``radar`` is None for unbiased sources; ``key`` the aircraft."""

    time: np.ndarray
    radar: np.ndarray
    key: np.ndarray
    z: np.ndarray
    C: np.ndarray
    R: np.ndarray
    valid: np.ndarray

    def __len__(self) -> int:
        return len(self.time)


def plot_keys(plots: PlotTable, use_truth: bool) -> np.ndarray:
    """Aircraft key of each plot: the truth label if asked and present, else the Mode S address."""
    if use_truth:
        return plots.target.copy()
    return plots.mode_s.copy()


def fill_altitudes(plots: PlotTable, keys: np.ndarray, default_altitude_m: float) -> tuple[np.ndarray, int]:
    """Altitudes with gaps filled from the same aircraft's nearest plot in time; count of defaults."""
    alt = plots.altitude_m.copy()
    missing = np.isnan(alt)
    if not missing.any():
        return alt, 0
    groups: dict[object, list[int]] = defaultdict(list)
    for i, k in enumerate(keys):
        if k is not None:
            groups[k].append(i)
    for idx in groups.values():
        idx = np.asarray(idx)
        have = idx[~missing[idx]]
        need = idx[missing[idx]]
        if len(have) and len(need):
            t_have = plots.time[have]
            order = np.argsort(t_have)
            pos = np.clip(np.searchsorted(t_have[order], plots.time[need]), 0, len(have) - 1)
            prev = np.clip(pos - 1, 0, len(have) - 1)
            th = t_have[order]
            nearest = np.where(np.abs(th[prev] - plots.time[need]) < np.abs(th[pos] - plots.time[need]), prev, pos)
            alt[need] = plots.altitude_m[have[order][nearest]]
    still = np.isnan(alt)
    alt[still] = default_altitude_m
    return alt, int(still.sum())


def convert_plots(plots: PlotTable, radars: list[Radar], plane: SystemPlane, keys: np.ndarray,
                  altitude_m: np.ndarray) -> Measurements:
    """Exact conversion of every plot to the plane, with C_s and R per plot."""
    n = len(plots)
    z = np.full((n, 2), np.nan)
    C = np.zeros((n, 2, 2))
    R = np.zeros((n, 2, 2))
    valid = np.zeros(n, bool)
    for radar in radars:
        idx = np.flatnonzero(plots.radar == radar.id)
        if len(idx) == 0:
            continue
        frame = RadarFrame(radar.lat, radar.lon, radar.height_m, plane)
        p, ok = frame.to_plane(plots.range_m[idx], plots.azimuth_rad[idx], altitude_m[idx])
        J = frame.bias_jacobian(p, plots.range_m[idx], altitude_m[idx])
        z[idx], C[idx], valid[idx] = p, J, ok
        R[idx] = J @ radar.W @ np.swapaxes(J, -1, -2)
    return Measurements(plots.time, plots.radar.copy(), keys, z, C, R, valid)


def convert_adsb(adsb: AdsbTable, plane: SystemPlane) -> Measurements:
    """ADS-B reports as unbiased plane positions with R = σ²(NACp)·I."""
    n = len(adsb)
    if n == 0:
        return Measurements(np.empty(0), np.empty(0, object), np.empty(0, object), np.empty((0, 2)),
                            np.empty((0, 2, 2)), np.empty((0, 2, 2)), np.empty(0, bool))
    x, y = plane.to_plane(adsb.lat, adsb.lon)
    sd = np.array([NACP_EPU_M[int(k)] / 2.448 for k in adsb.nacp])
    R = np.zeros((n, 2, 2))
    R[:, 0, 0] = R[:, 1, 1] = sd**2
    return Measurements(adsb.time, np.full(n, None, object), adsb.icao24.copy(), np.stack([x, y], axis=-1),
                        np.zeros((n, 2, 2)), R, np.ones(n, bool))


def merge(*parts: Measurements) -> Measurements:
    """All measurements in one table, sorted by time (stable: earlier parts first at equal times)."""
    cat = {f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in attrs.fields(Measurements)}
    order = np.argsort(cat["time"], kind="stable")
    return Measurements(**{k: v[order] for k, v in cat.items()})

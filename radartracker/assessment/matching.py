"""One radar's plots against the reference: antenna revolutions, plot-to-aircraft association and the
detections the radar should have made.

* **Antenna revolution (scan).** The antenna turns clockwise once per period T: a plot at azimuth θ was
  stamped t = t_N + (n + θ/2π) T in revolution n, t_N being the time the antenna points north in
  revolution 0. t_N is the circular mean of (t_i − θ_i T/2π) mod T over the radar's plots, so
  n_i = round((t_i − t_N)/T − θ_i/2π), and t_i − (t_N + (n_i + θ_i/2π) T) is the plot's time-stamp offset
  from its antenna position (:func:`antenna_offsets`).
* **Association.** Each plot, its range and azimuth corrected by the radar's estimated bias, is compared at
  its own time with the exact slant range and azimuth of every reference aircraft
  (:meth:`radartracker.geometry.plane.RadarFrame.polar`); it goes to the one of least
  d² = (Δρ/G_ρ)² + (Δθ/G_θ)², if d² ≤ 1 (the gate: :class:`MatchConfig`).
* **Expected detections.** In each revolution the antenna crosses a reference aircraft at the t solving
  t = t_N + (n + θ_ref(t)/2π) T (three fixed-point steps; crossings two revolutions' iterations meet near
  north counted once). The radar should detect it there when the reference is inside its coverage: slant
  range ≤ its ``max_range_m``, elevation above the geometric radar horizon −arccos(R/(R + h)) and below
  the cone of silence (:attr:`MatchConfig.cone_of_silence_deg`). It did when a plot matched to that
  aircraft lies within T/2 of the crossing (by time, not by revolution label: near north a plot's
  azimuth noise can move its label by one).
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from radartracker.assessment.reference import Reference
from radartracker.domain import TWO_PI, Radar
from radartracker.geometry.plane import RadarFrame

_EARTH_RADIUS_M = 6_371_008.8


@attrs.frozen
class MatchConfig:
    """The association gate (half-widths in slant range and azimuth) and the cone of silence."""

    gate_range_m: float = attrs.field(default=1000.0, validator=attrs.validators.gt(0.0))
    gate_azimuth_deg: float = attrs.field(default=1.0, validator=attrs.validators.gt(0.0))
    cone_of_silence_deg: float = attrs.field(default=45.0, validator=attrs.validators.gt(0.0))


@attrs.frozen
class RadarMatch:
    """One radar's plots (by row of its plot table) matched to the reference.

    ``aircraft``: the reference key of each plot ('' when none is in the gate), ``d2`` its gate distance
    d² (inf when unmatched); ``ref_range``,
    ``ref_azimuth``, ``ref_altitude``: the reference's exact polar position and height at the plot's time
    (NaN when unmatched); ``scan``: each plot's antenna revolution. ``expected``: one row per reference
    crossing inside the coverage, as columns ``aircraft``, ``scan``, ``time``, ``range_m``, ``azimuth_deg``,
    ``altitude_m``, ``x``, ``y`` (plane, m), ``detected``."""

    aircraft: np.ndarray
    d2: np.ndarray
    ref_range: np.ndarray
    ref_azimuth: np.ndarray
    ref_altitude: np.ndarray
    scan: np.ndarray
    north_time: float
    expected: dict[str, np.ndarray]


def north_time(t: np.ndarray, theta: np.ndarray, period_s: float) -> float:
    """t_N (module docstring): the circular mean of the plots' north-crossing phases, in [0, T)."""
    phase = TWO_PI * np.mod(t - theta * period_s / TWO_PI, period_s) / period_s
    mean = math.atan2(float(np.mean(np.sin(phase))), float(np.mean(np.cos(phase))))
    return (mean % TWO_PI) * period_s / TWO_PI


def antenna_offsets(t: np.ndarray, theta: np.ndarray, period_s: float, t_north: float) -> tuple[np.ndarray, np.ndarray]:
    """Each plot's revolution n and its time-stamp offset t − (t_N + (n + θ/2π) T) (s)."""
    turns = (t - t_north) / period_s - theta / TWO_PI
    n = np.round(turns)
    return n.astype(np.int64), (turns - n) * period_s


def match_radar(radar: Radar, frame: RadarFrame, t: np.ndarray, rho: np.ndarray, theta: np.ndarray,
                bias: tuple[float, float], reference: Reference, config: MatchConfig, *,
                antenna: tuple[float, tuple[float, float]] | None = None,
                keep: tuple[float, float] = (-math.inf, math.inf)) -> RadarMatch:
    """The plots (times, slant ranges, azimuths) of ``radar`` matched to ``reference`` (module docstring),
    its estimated ``bias`` (Δr m, Δθ rad) removed before the gate.

    A time slice of a longer recording (:mod:`radartracker.assessment.slices`) gives ``antenna``: t_N and the
    span (first, last plot time) of *all* the radar's plots, and ``keep``: the slice [t₀, t₁); its plots and
    reference then cover the slice and a margin either side, and only the crossings inside the slice are
    expected of it (computed from the same revolutions as over the whole recording: the same figures)."""
    n = len(t)
    best = np.full(n, np.inf)
    key = np.full(n, "", dtype=object)
    ref = np.full((3, n), np.nan)
    rho_c, theta_c = rho - bias[0], theta - bias[1]
    g_r, g_a = config.gate_range_m, math.radians(config.gate_azimuth_deg)
    for name, track in reference.tracks.items():
        idx = np.flatnonzero(track.covered(t))
        if not len(idx):
            continue
        lat, lon, h = reference.geodetic(name, t[idx])
        r_ref, a_ref, _ = frame.polar(lat, lon, h)
        d2 = ((rho_c[idx] - r_ref) / g_r) ** 2 + (wrap_angle(theta_c[idx] - a_ref) / g_a) ** 2
        win = (d2 <= 1.0) & (d2 < best[idx])
        w = idx[win]
        best[w], key[w] = d2[win], name
        ref[0, w], ref[1, w] = r_ref[win], a_ref[win]
        ref[2, w] = h[win]
    if antenna is None:
        antenna = (north_time(t, theta, radar.period_s) if n else 0.0,
                   (float(t.min()), float(t.max())) if n else (0.0, 0.0))
    t_n, span = antenna
    scan, _ = antenna_offsets(t, theta, radar.period_s, t_n)
    expected = _expected(radar, frame, reference, config, t_n, (span, keep))
    expected["detected"] = _detected(expected, key, t, radar.period_s)
    return RadarMatch(key, best, ref[0], ref[1], ref[2], scan, t_n, expected)


def _expected(radar: Radar, frame: RadarFrame, reference: Reference, config: MatchConfig, t_north: float,
              spans: tuple[tuple[float, float], tuple[float, float]]) -> dict[str, np.ndarray]:
    """The crossings of every reference aircraft inside the radar's coverage during the plots' span that fall
    in the slice ``keep`` (``spans``: both, :func:`match_radar`). The crossing of revolution n lies in
    [t_N + nT, t_N + (n+1)T], so the revolutions from 2T before the slice to 2T after it hold them all."""
    T = radar.period_s
    span, keep = spans
    dip = math.acos(_EARTH_RADIUS_M / (_EARTH_RADIUS_M + max(radar.height_m, 0.0)))
    cone = math.radians(config.cone_of_silence_deg)
    cols: dict[str, list] = {k: [] for k in ("aircraft", "time", "range_m", "azimuth_deg", "altitude_m", "x", "y")}
    for name, track in reference.tracks.items():
        lo, hi = max(track.times[0], span[0]), min(track.times[-1], span[1])
        a, b = max(lo, keep[0] - 2 * T), min(hi, keep[1] + 2 * T)
        if b <= a:
            continue
        scans = np.arange(math.floor((a - t_north) / T), math.ceil((b - t_north) / T) + 1)
        tc = t_north + scans * T
        for _ in range(3):
            _, theta, _ = frame.polar(*reference.geodetic(name, np.clip(tc, lo, hi)))
            tc = t_north + (scans + theta / TWO_PI) * T
        tc = tc[(tc >= lo) & (tc <= hi) & track.covered(tc)]
        lat, lon, h = reference.geodetic(name, tc)
        rho, theta, elev = frame.polar(lat, lon, h)
        # labelled as a plot there would be: near north two revolutions' iterations can meet one crossing
        _, first = np.unique(antenna_offsets(tc, theta, T, t_north)[0], return_index=True)
        lat, lon, h, rho, theta, elev, tc = (v[first] for v in (lat, lon, h, rho, theta, elev, tc))
        inside = (rho <= radar.max_range_m) & (elev >= -dip) & (elev <= cone) & (tc >= keep[0]) & (tc < keep[1])
        x, y = reference.plane.to_plane(lat[inside], lon[inside])
        for k, v in (("aircraft", np.full(int(inside.sum()), name, dtype=object)), ("time", tc[inside]),
                     ("range_m", rho[inside]), ("azimuth_deg", np.degrees(theta[inside])), ("altitude_m", h[inside]),
                     ("x", x), ("y", y)):
            cols[k].append(np.asarray(v))
    return {k: np.concatenate(v) if v else np.empty(0, object if k == "aircraft" else float) for k, v in cols.items()}


def _detected(expected: dict[str, np.ndarray], key: np.ndarray, t: np.ndarray, period_s: float) -> np.ndarray:
    """Whether a plot matched to the aircraft of each expected crossing lies within T/2 of its time (by
    time, not by revolution label: near north a plot's noise can move its label by one)."""
    out = np.zeros(len(expected["time"]), bool)
    for name in np.unique(expected["aircraft"]).tolist():
        rows = np.flatnonzero(expected["aircraft"] == name)
        mine = np.sort(t[key == name])
        if not len(mine):
            continue
        te = expected["time"][rows]
        i = np.searchsorted(mine, te)
        before, after = mine[np.clip(i - 1, 0, len(mine) - 1)], mine[np.clip(i, 0, len(mine) - 1)]
        near = np.minimum(np.abs(before - te), np.abs(after - te))
        out[rows] = near <= period_s / 2
    return out


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles folded into [−π, π)."""
    return np.mod(a + math.pi, TWO_PI) - math.pi

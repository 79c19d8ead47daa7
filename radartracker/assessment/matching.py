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
  d² = (Δρ/G_ρ)² + (Δθ/G_θ)², if d² ≤ 1 (the gate: :class:`MatchConfig`). An aircraft that cannot come
  within the radar's reach (:meth:`Reference.near`), or whose slant range at a plot's time cannot lie
  within G_ρ of the plot's (:meth:`Reference.slant_range_bounds`), cannot fill that gate and is not
  projected there: the same matches at a cost that grows with the traffic, not with its square.
* **Expected detections.** In each revolution the antenna crosses a reference aircraft at the t solving
  t = t_N + (n + θ_ref(t)/2π) T (three fixed-point steps; crossings two revolutions' iterations meet near
  north counted once). The radar should detect it there when the reference is inside its coverage: slant
  range ≤ its ``max_range_m``, elevation above the geometric radar horizon −arccos(R/(R + h)) and below
  the assumed cone of silence (:attr:`MatchConfig.cone_of_silence_deg`). It did when a plot matched to that
  aircraft lies within T/2 of the crossing (by time, not by revolution label: near north a plot's
  azimuth noise can move its label by one). The crossings above the assumed cone are kept too, flagged
  ``above_cone``: Pd leaves them out, the measured cone of silence
  (:mod:`radartracker.assessment.coverage`) needs them.
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from radartracker.assessment.reference import Reference
from radartracker.domain import TWO_PI, Radar
from radartracker.geometry.plane import RadarFrame, in_coverage


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
    (NaN when unmatched); ``ref_rate``: its slant-range and azimuth rates there, ρ̇ (m/s) and θ̇ (rad/s), 2 × n
    (NaN when unmatched); ``scan``: each plot's antenna revolution. ``expected``: one row per reference
    crossing inside the coverage or above the assumed cone, as columns ``aircraft``, ``time``, ``range_m``,
    ``azimuth_deg``, ``elevation_deg``, ``altitude_m``, ``x``, ``y`` (plane, m), ``above_cone``, ``detected``."""

    aircraft: np.ndarray
    d2: np.ndarray
    ref_range: np.ndarray
    ref_azimuth: np.ndarray
    ref_altitude: np.ndarray
    ref_rate: np.ndarray
    scan: np.ndarray
    north_time: float
    expected: dict[str, np.ndarray]


RATE_STEP_S = 0.5  # the half-step of the reference's polar rates (s): its positions are exact, its turns slow


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
    expected of it (computed from the same revolutions as over the whole recording: the same figures).

    Only the aircraft that may come within max(``max_range_m``, max ρ + G_ρ) of the radar are looked at
    (:meth:`Reference.near`): one farther is outside its coverage and every plot's gate."""
    n = len(t)
    rho_c, theta_c = rho - bias[0], theta - bias[1]
    reach = max(radar.max_range_m, float(rho_c.max()) + config.gate_range_m if n else 0.0)
    near = reference.near(frame.xy, reach)
    key, best, ref = associate(frame, t, (rho_c, theta_c), near, config)
    if antenna is None:
        antenna = (north_time(t, theta, radar.period_s) if n else 0.0,
                   (float(t.min()), float(t.max())) if n else (0.0, 0.0))
    t_n, span = antenna
    scan, _ = antenna_offsets(t, theta, radar.period_s, t_n)
    expected = _expected(radar, frame, near, config, t_n, (span, keep))
    expected["detected"] = _detected(expected, key, t, radar.period_s)
    return RadarMatch(key, best, ref[0], ref[1], ref[2], _reference_rates(frame, t, key, near), scan, t_n, expected)


def _reference_rates(frame: RadarFrame, t: np.ndarray, key: np.ndarray, reference: Reference,
                     step_s: float = RATE_STEP_S) -> np.ndarray:
    """ρ̇ (m/s) and θ̇ (rad/s) of each matched plot's reference at its time (2 × n, NaN unmatched): central
    differences of the reference's exact polar position over ±``step_s``, one-sided at the ends of its span."""
    out = np.full((2, len(t)), np.nan)
    names = sorted(set(key[key != ""].tolist()))
    if not names:
        return out
    rows = [np.flatnonzero(key == k) for k in names]
    ends = [reference.tracks[k].times[[0, -1]] for k in names]
    lo = [np.maximum(t[r] - step_s, e[0]) for r, e in zip(rows, ends)]
    hi = [np.minimum(t[r] + step_s, e[1]) for r, e in zip(rows, ends)]
    r0, a0, _ = frame.polar(*reference.geodetic(names, lo))
    r1, a1, _ = frame.polar(*reference.geodetic(names, hi))
    idx, dt = np.concatenate(rows), np.concatenate(hi) - np.concatenate(lo)
    with np.errstate(invalid="ignore", divide="ignore"):
        out[0, idx], out[1, idx] = (r1 - r0) / dt, wrap_angle(a1 - a0) / dt
    return out


def associate(frame: RadarFrame, t: np.ndarray, polar: tuple[np.ndarray, np.ndarray], reference: Reference,
               config: MatchConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each plot's aircraft ('' none), d² (inf none) and the reference's (ρ, θ, h) there (NaN none): of every
    (aircraft, plot) pair whose time the aircraft's reference covers, in one projection, the plot's pair of
    least d² ≤ 1, the first aircraft of ``reference`` on a tie. ``polar``: the plots' bias-corrected ρ, θ."""
    n = len(t)
    key, best, ref = np.full(n, "", dtype=object), np.full(n, np.inf), np.full((3, n), np.nan)
    names = list(reference.tracks)
    rows = [np.flatnonzero(track.covered(t)) for track in reference.tracks.values()]
    g = config.gate_range_m  # a pair whose slant range cannot be within G_ρ of the plot's is not projected
    rows = [r[(polar[0][r] >= lo - g) & (polar[0][r] <= hi + g)]
            for r, (lo, hi) in zip(rows, reference.slant_range_bounds(frame, [t[r] for r in rows]))]
    lat, lon, h = reference.geodetic(names, [t[r] for r in rows])
    if not len(h):
        return key, best, ref
    r_ref, a_ref, _ = frame.polar(lat, lon, h)
    plot = np.concatenate(rows)
    owner = np.repeat(np.arange(len(names)), [len(r) for r in rows])
    d2 = ((polar[0][plot] - r_ref) / g) ** 2 \
        + (wrap_angle(polar[1][plot] - a_ref) / math.radians(config.gate_azimuth_deg)) ** 2
    gated = np.flatnonzero(d2 <= 1.0)
    order = gated[np.lexsort((owner[gated], d2[gated], plot[gated]))]  # by plot, then d², then aircraft
    win = order[np.concatenate([[True], np.diff(plot[order]) != 0])] if len(order) else order
    w = plot[win]
    key[w], best[w] = np.array(names, dtype=object)[owner[win]], d2[win]
    ref[0, w], ref[1, w], ref[2, w] = r_ref[win], a_ref[win], h[win]
    return key, best, ref


def _expected(radar: Radar, frame: RadarFrame, reference: Reference, config: MatchConfig, t_north: float,
              spans: tuple[tuple[float, float], tuple[float, float]]) -> dict[str, np.ndarray]:
    """The crossings of every reference aircraft inside the radar's coverage, or above its assumed cone of
    silence (flagged ``above_cone``), during the plots' span that fall in the slice ``keep`` (``spans``:
    both, :func:`match_radar`), every aircraft's in one projection per step; in the order of ``reference``'s
    aircraft, then of revolution."""
    T = radar.period_s
    names, owner, tc = _crossing_times(frame, reference, t_north, T, spans)
    lat, lon, h = reference.geodetic(names, np.split(tc, np.cumsum(np.bincount(owner, minlength=len(names)))[:-1]))
    rho, theta, elev = frame.polar(lat, lon, h)
    # labelled as a plot there would be: near north two revolutions' iterations can meet one crossing
    label = antenna_offsets(tc, theta, T, t_north)[0]
    order = np.lexsort((label, owner))
    first = order[np.concatenate([[True], (np.diff(owner[order]) != 0) | (np.diff(label[order]) != 0)])] \
        if len(order) else order
    lat, lon, h, rho, theta, elev, tc, owner = (v[first] for v in (lat, lon, h, rho, theta, elev, tc, owner))
    keep = spans[1]
    inside = in_coverage(rho, elev, radar.max_range_m, radar.height_m, math.pi / 2)  # the cone's crossings too
    inside &= (tc >= keep[0]) & (tc < keep[1])
    x, y = reference.plane.to_plane(lat[inside], lon[inside])
    return {"aircraft": np.array(names, dtype=object)[owner[inside]], "time": tc[inside],
            "range_m": rho[inside], "azimuth_deg": np.degrees(theta[inside]),
            "elevation_deg": np.degrees(elev[inside]), "altitude_m": h[inside],
            "x": np.asarray(x, float), "y": np.asarray(y, float),
            "above_cone": elev[inside] > math.radians(config.cone_of_silence_deg)}


def _crossing_times(frame: RadarFrame, reference: Reference, t_north: float, T: float,
                    spans: tuple[tuple[float, float], tuple[float, float]]) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The aircraft with a crossing to look at, and per crossing its aircraft (index into them) and time, in
    order: the t solving t = t_N + (n + θ_ref(t)/2π) T by three fixed-point steps, for the revolutions n from
    2T before the slice to 2T after it (the crossing of revolution n lies in [t_N + nT, t_N + (n+1)T]), kept
    where the aircraft's reference covers it and the radar's plots span it."""
    span, keep = spans
    names, lo, hi, scans = [], [], [], []
    for name, track in reference.tracks.items():
        l, u = max(track.times[0], span[0]), min(track.times[-1], span[1])
        a, b = max(l, keep[0] - 2 * T), min(u, keep[1] + 2 * T)
        if b > a:
            names.append(name)
            lo.append(l)
            hi.append(u)
            scans.append(np.arange(math.floor((a - t_north) / T), math.ceil((b - t_north) / T) + 1))
    if not names:
        return names, np.zeros(0, np.int64), np.empty(0)
    counts = [len(s) for s in scans]
    owner = np.repeat(np.arange(len(names)), counts)
    scan = np.concatenate(scans)
    lo_c, hi_c = np.repeat(lo, counts), np.repeat(hi, counts)
    cuts = np.cumsum(counts)[:-1]
    tc = t_north + scan * T
    for _ in range(3):
        _, theta, _ = frame.polar(*reference.geodetic(names, np.split(np.clip(tc, lo_c, hi_c), cuts)))
        tc = t_north + (scan + theta / TWO_PI) * T
    covered = np.concatenate([reference.tracks[k].covered(part) for k, part in zip(names, np.split(tc, cuts))])
    ok = (tc >= lo_c) & (tc <= hi_c) & covered
    return names, owner[ok], tc[ok]


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

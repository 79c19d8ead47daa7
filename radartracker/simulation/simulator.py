"""Scenario simulator: aircraft trajectories seen by rotating radars with biases, and ADS-B.

* Trajectories in the system plane: :class:`KinematicTrajectory` (seed 000 eq. 2.1 with
  piecewise-constant controls; constant-velocity legs are u = w = 0) or
  :class:`RecordedTrajectory` (real flights, interpolated).
* Each radar's antenna turns clockwise, azimuth α(t) = α₀ + 2π (t − t₀)/T. A plot is produced
  when the antenna sweeps the aircraft: the crossing time solves θ(t) = α(t) (fixed-point
  iteration on the exact azimuth), so plot times are asynchronous across aircraft and radars.
* Visibility: slant range ≤ max range, elevation above the geometric radar horizon (−arccos(R/(R+h)))
  and below the radar's cone of silence (:attr:`SimRadar.cone_of_silence_deg`, 45° by default), and within
  its true detection range where a sector is screened (:attr:`SimRadar.screening`). Detection with
  probability Pd.
* Measured ρ = ρ_true (1 + g(t)) + Δr(t) + σ_r n, θ = θ_true + Δθ(t) + σ_θ n (exact 3-D geometry with
  pyproj), stamped t + τ(t) for a plot measured at t: range offset Δr, azimuth offset Δθ, range gain g
  and time-stamp offset τ (docs/design-notes.md, the sensor error model), each constant or drifting as
  a random walk. Altitude reported as Mode C (25 ft steps).
* False plots: Poisson per antenna revolution, uniform over the coverage disc, no codes.
* ADS-B: equipped aircraft report every ``adsb_period_s`` with per-axis σ from NACp.

Everything is driven by ``numpy.random.default_rng`` seeded per radar and per aircraft, so a run
is deterministic for a given seed.
"""

from __future__ import annotations

import math
from typing import Protocol

import attrs
import numpy as np
from scipy.interpolate import make_smoothing_spline

from radartracker.domain import Aircraft, Radar, nacp_sigma_m
from radartracker.io.tables import AdsbTable, PlotTable, ScenarioData, TruthTable
from radartracker.geometry.plane import RadarFrame, SystemPlane, in_coverage
from radartracker.geometry.kinematics import propagate

_MODE_C_STEP_M = 25 * 0.3048
MIN_SPLINE_POINTS = 5  # make_smoothing_spline's least: fewer recorded points are joined by straight lines
SMOOTHING_S3 = 100.0  # λ = σ²/q of a recorded flight's smoothing spline: (20 m)² / (4 m²/s³), in s³
OUTLIER_FLOOR_M, OUTLIER_FLOOR_ALT_M = 150.0, 100.0  # residuals this small are never outliers


class Trajectory(Protocol):
    """Anything that gives plane positions (x, y, altitude) at times within [t_start, t_end]."""

    t_start: float
    t_end: float

    def position(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


@attrs.frozen
class Leg:
    """Constant controls for ``duration`` s: lateral ``u`` and longitudinal ``w`` (m/s²), climb (m/s)."""

    duration: float = attrs.field(validator=attrs.validators.gt(0.0))
    u: float = 0.0
    w: float = 0.0
    climb_mps: float = 0.0

    @classmethod
    def turn(cls, duration: float, rate_deg_s: float, speed_mps: float, climb_mps: float = 0.0) -> Leg:
        """A level-speed turn at ``rate_deg_s`` (positive = clockwise/right): u = v·ω."""
        return cls(duration, u=speed_mps * math.radians(rate_deg_s), climb_mps=climb_mps)


class KinematicTrajectory:
    """Seed 000 eq. 2.1 flown leg after leg from (x0, y0, h0, heading, speed) at ``t0``."""

    def __init__(self, t0: float, x0: float, y0: float, h0: float, heading_rad: float, speed_mps: float,
                 legs: list[Leg]) -> None:
        if not legs:
            raise ValueError("legs: at least one leg is needed")
        self.legs = tuple(legs)
        self.t_start = float(t0)
        starts = [(float(t0), x0, y0, h0, heading_rad, speed_mps)]
        for leg in self.legs[:-1]:
            t, x, y, h, phi, v = starts[-1]
            xs, ys, ps, vs = propagate(x, y, phi, v, leg.u, leg.w, np.array([leg.duration]))
            starts.append((t + leg.duration, xs[0], ys[0], h + leg.climb_mps * leg.duration, ps[0], vs[0]))
        self._starts = starts
        self.t_end = starts[-1][0] + self.legs[-1].duration

    def state(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """(x, y, h, φ, v) at times ``t`` (clamped to the trajectory's span)."""
        t = np.clip(np.asarray(t, float), self.t_start, self.t_end)
        out = [np.empty_like(t) for _ in range(5)]
        bounds = [s[0] for s in self._starts[1:]]
        seg = np.searchsorted(bounds, t, side="right")
        for k in np.unique(seg):
            mask = seg == k
            t0, x0, y0, h0, phi0, v0 = self._starts[k]
            leg = self.legs[k]
            tau = t[mask] - t0
            x, y, phi, v = propagate(x0, y0, phi0, v0, leg.u, leg.w, tau)
            for o, val in zip(out, (x, y, h0 + leg.climb_mps * tau, phi, v)):
                o[mask] = val
        return tuple(out)

    def position(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x, y, h, _, _ = self.state(t)
        return x, y, h


class RecordedTrajectory:
    """A recorded flight (times strictly increasing) as the aircraft flew it: by default a cubic smoothing
    spline through its plane positions and altitudes (``scipy.interpolate.make_smoothing_spline``, which
    minimises Σᵢ (yᵢ − f(tᵢ))² + λ ∫ f''(t)² dt) with λ = σ²/q = :data:`SMOOTHING_S3`: the posterior mean
    of a path whose acceleration is white noise of density q = 4 m²/s³ (an airliner's manoeuvres) seen
    with σ = 20 m noise (ADS-B at NACp 8, stale positions); ``smooth=False``, or fewer than
    :data:`MIN_SPLINE_POINTS` points: straight lines between the points.

    Recorded positions carry noise (ADS-B's NACp, Mode C's 25 ft steps) and, in OpenSky state vectors,
    positions older than their time stamps. Joined by straight lines, the path's velocity jumps at every
    point: on the ``paris`` flights the tracks' velocity errors against such a truth were 18 m/s RMS and
    the mean NEES 19 (position part 2.3, velocity part 10), against a smoothed one 7.7 m/s and 2.6 — the
    jumps were in the truth, not in the filters (docs/design-notes.md). (λ chosen per flight by generalised
    cross-validation gave the same figures within 10 % at 30 times the cost.) Recorded outliers are left out
    of the fit (:func:`_robust_spline`).
    """

    def __init__(self, t: np.ndarray, x: np.ndarray, y: np.ndarray, h: np.ndarray, smooth: bool = True) -> None:
        self.t, self.x, self.y, self.h = (np.asarray(a, float) for a in (t, x, y, h))
        if len(self.t) < 2 or np.any(np.diff(self.t) <= 0):
            raise ValueError("recorded trajectory needs ≥ 2 points with strictly increasing times")
        self.t_start, self.t_end = float(self.t[0]), float(self.t[-1])
        self._splines = ([_robust_spline(self.t, v, floor) for v, floor in
                          ((self.x, OUTLIER_FLOOR_M), (self.y, OUTLIER_FLOOR_M), (self.h, OUTLIER_FLOOR_ALT_M))]
                         if smooth and len(self.t) >= MIN_SPLINE_POINTS else None)

    @property
    def smoothed(self) -> bool:
        """Whether a smoothing spline (not straight lines) joins the points."""
        return self._splines is not None

    @classmethod
    def from_geodetic(cls, plane: SystemPlane, t, lat, lon, alt_m, smooth: bool = True) -> RecordedTrajectory:
        x, y = plane.to_plane(lat, lon)
        return cls(t, x, y, alt_m, smooth)

    def position(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, float)
        if self._splines is None:
            return np.interp(t, self.t, self.x), np.interp(t, self.t, self.y), np.interp(t, self.t, self.h)
        t = np.clip(t, self.t_start, self.t_end)  # as np.interp: the end points before and after
        return tuple(s(t) for s in self._splines)


def _robust_spline(t: np.ndarray, v: np.ndarray, floor: float):
    """The smoothing spline of ``v(t)`` (λ = :data:`SMOOTHING_S3`) fitted again without the points more than
    max(5 σ̂, ``floor``) off it, σ̂ = 1.4826 · the median absolute residual, up to three times. A recorded
    outlier (OpenSky's altitude spikes to 10 668 m on an approach at 3 400 m) would otherwise pull the
    spline over ±20 s, and the Mode C of the plots with it; joined by straight lines it lasted a second."""
    keep = np.ones(len(t), bool)
    for _ in range(3):
        spline = make_smoothing_spline(t[keep], v[keep], lam=SMOOTHING_S3)
        r = np.abs(v - spline(t))
        kept = r <= max(5.0 * 1.4826 * float(np.median(r[keep])), floor)
        if (kept == keep).all() or kept.sum() < MIN_SPLINE_POINTS:
            break
        keep = kept
    return spline


@attrs.frozen
class SimRadar:
    """A simulated radar: its public description plus what only the simulator knows.

    Biases are [Δr (m), Δθ (rad)], the range gain g (dimensionless: ρ_meas = ρ (1 + g) + …) and the
    time-stamp offset τ (s: a plot measured at t is stamped t + τ); drifts are random-walk densities
    (m²/s, rad²/s, 1/s, s); ``false_per_scan`` is the mean number of false plots per antenna revolution.
    ``cone_of_silence_deg``: the true elevation ε_c above which the radar detects nothing; ``screening``: the
    azimuth sectors (from°, to°, clockwise from north, and the range R m) where its true detection range is
    R, shorter than the configured ``max_range_m`` (terrain, a weak receiver): what the assessment's measured
    cone and achieved coverage are checked against.
    """

    radar: Radar
    range_bias_m: float = 0.0
    azimuth_bias_rad: float = 0.0
    drift_range: float = attrs.field(default=0.0, validator=attrs.validators.ge(0.0))
    drift_azimuth: float = attrs.field(default=0.0, validator=attrs.validators.ge(0.0))
    range_gain: float = attrs.field(default=0.0, kw_only=True)
    time_offset_s: float = attrs.field(default=0.0, kw_only=True)
    drift_gain: float = attrs.field(default=0.0, validator=attrs.validators.ge(0.0), kw_only=True)
    drift_time: float = attrs.field(default=0.0, validator=attrs.validators.ge(0.0), kw_only=True)
    pd: float = attrs.field(default=1.0, validator=[attrs.validators.ge(0.0), attrs.validators.le(1.0)])
    false_per_scan: float = attrs.field(default=0.0, validator=attrs.validators.ge(0.0))
    phase_rad: float = 0.0
    cone_of_silence_deg: float = attrs.field(default=45.0, kw_only=True,
                                             validator=[attrs.validators.gt(0.0), attrs.validators.le(90.0)])
    screening: tuple[tuple[float, float, float], ...] = attrs.field(default=(), kw_only=True, converter=tuple)

    def visible(self, rho: np.ndarray, theta: np.ndarray, elev: np.ndarray) -> np.ndarray:
        """Where the radar can see a target at slant range ρ (m), azimuth θ and elevation ε (rad): ρ within the
        configured range and, in a screened sector, within that sector's R; ε above the radar horizon and below
        the cone of silence."""
        seen = in_coverage(rho, elev, self.radar.max_range_m, self.radar.height_m,
                           math.radians(self.cone_of_silence_deg))
        az = np.mod(np.degrees(theta), 360.0)
        for lo, hi, reach in self.screening:  # a sector from lo to hi clockwise; lo = hi (mod 360): all azimuths
            width = np.mod(hi - lo, 360.0) or 360.0
            seen &= (np.mod(az - lo, 360.0) >= width) | (rho <= reach)
        return seen

    @property
    def has_gain_or_time(self) -> bool:
        """Whether this radar has a range gain or a time-stamp offset (constant or drifting)."""
        return any(v != 0.0 for v in (self.range_gain, self.time_offset_s, self.drift_gain, self.drift_time))


def random_walks(rng: np.random.Generator, t0: float, t: np.ndarray, starts: tuple[float, ...],
                 densities: tuple[float, ...]) -> list[np.ndarray]:
    """Random walks x(t) = x₀ + Σ wᵢ √(q Δtᵢ), wᵢ ~ N(0, 1), from each start x₀ with its density q
    (variance per second), at the sorted times ``t`` after ``t0``; the walks drawn from ``rng`` one after
    the other."""
    dt = np.diff(np.concatenate([[t0], t]))
    return [x0 + np.cumsum(rng.normal(0.0, 1.0, len(t)) * np.sqrt(q * dt)) for x0, q in zip(starts, densities)]


def walks_at(rng: np.random.Generator, t0: float, t1: float, t: np.ndarray, starts: tuple[float, ...],
             densities: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`random_walks` at the times ``t`` (any order; the walks run through them sorted) and at ``t1`` after
    them: (walks × len(t), walks)."""
    order = np.argsort(t, kind="stable")
    w = np.array(random_walks(rng, t0, np.append(t[order], t1), starts, densities))
    at = np.empty((len(starts), len(t)))
    at[:, order] = w[:, :-1]
    return at, w[:, -1]


def apply_sensor_errors(cols: dict[str, np.ndarray], sr: SimRadar, seed: int, j: int, t0: float,
                        t1: float) -> dict[str, float]:
    """Add radar ``j``'s range gain and time-stamp offset to its plot columns in place (ρ += g ρ, time += τ),
    each a random walk from its initial value sampled at the sorted plot times (generator ``[seed, 4, j]``);
    their values at ``t1`` (the truth file's). Without either, the columns are left as they are."""
    if not sr.has_gain_or_time:
        return {"range_gain": 0.0, "time_offset": 0.0}
    (gain, shift), (g1, tau1) = walks_at(np.random.default_rng([seed, 4, j]), t0, t1, cols["time"],
                                         (sr.range_gain, sr.time_offset_s), (sr.drift_gain, sr.drift_time))
    cols["range_m"] = cols["range_m"] + gain * cols["range_m"]
    cols["time"] = cols["time"] + shift
    return {"range_gain": float(g1), "time_offset": float(tau1)}


@attrs.frozen
class SimAircraft:
    """An aircraft's identity and the trajectory it flies."""

    aircraft: Aircraft
    trajectory: Trajectory


def time_ordered(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The plot columns of every radar, concatenated and in time order (stable at equal times)."""
    cols = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    order = np.argsort(cols["time"], kind="stable")
    return {k: v[order] for k, v in cols.items()}


@attrs.define
class Simulator:
    """Simulates radar plots, ADS-B reports and truth over [t0, t1] (see module docstring)."""

    reference: tuple[float, float]
    radars: list[SimRadar]
    aircraft: list[SimAircraft]
    t0: float
    t1: float
    seed: int = 0
    adsb_period_s: float = 1.0
    truth_step_s: float = 1.0
    name: str = "simulated"
    plane: SystemPlane = attrs.field(init=False)

    def __attrs_post_init__(self) -> None:
        self.plane = SystemPlane(*self.reference)
        if not self.t1 > self.t0:
            raise ValueError(f"t1 ({self.t1}) must be after t0 ({self.t0})")

    def run(self) -> ScenarioData:
        plots, truth_biases, truth_sensor = [], {}, {}
        for j, sr in enumerate(self.radars):
            cols, truth_biases[sr.radar.id], truth_sensor[sr.radar.id] = self._radar_plots(j, sr)
            plots.append(cols)
        table = PlotTable.from_columns(**time_ordered(plots))
        return ScenarioData(
            reference=self.reference, radars=[sr.radar for sr in self.radars], plots=table,
            adsb=self._adsb(), truth=self._truth(), truth_biases=truth_biases,
            truth_sensor=truth_sensor if any(sr.has_gain_or_time for sr in self.radars) else None,
            aircraft=[sa.aircraft for sa in self.aircraft], name=self.name,
        )

    # --- radar plots -------------------------------------------------------------------------
    def _span(self, traj: Trajectory) -> tuple[float, float]:
        return max(traj.t_start, self.t0), min(traj.t_end, self.t1)

    def _geo(self, traj: Trajectory, t: np.ndarray):
        x, y, h = traj.position(t)
        lat, lon = self.plane.to_geodetic(x, y)
        return lat, lon, h

    def _crossings(self, frame: RadarFrame, sr: SimRadar, traj: Trajectory) -> np.ndarray:
        """Times within the trajectory's span at which the antenna points at the aircraft."""
        ta, tb = self._span(traj)
        if tb <= ta:
            return np.empty(0)
        T = sr.radar.period_s
        ks = np.arange(math.floor((ta - self.t0) / T) - 1, math.ceil((tb - self.t0) / T) + 1)
        scan_start = self.t0 + ks * T
        _, theta, _ = frame.polar(*self._geo(traj, np.clip(scan_start, ta, tb)))
        t = scan_start + T * np.mod(theta - sr.phase_rad, 2 * np.pi) / (2 * np.pi)
        for _ in range(3):
            _, theta, _ = frame.polar(*self._geo(traj, np.clip(t, ta, tb)))
            antenna = sr.phase_rad + 2 * np.pi * (t - self.t0) / T
            t = t + T * (np.mod(theta - antenna + np.pi, 2 * np.pi) - np.pi) / (2 * np.pi)
        t = np.sort(t[(t >= ta) & (t <= tb)])
        # adjacent scans can converge to the same crossing near the antenna's start azimuth
        return t[np.concatenate([[True], np.diff(t) > 0.5 * T])] if len(t) else t

    def _radar_plots(self, j: int, sr: SimRadar) -> tuple[dict[str, np.ndarray], tuple[float, float], dict[str, float]]:
        """One radar's plots as columns, its true bias at t1 and its true range gain and time offset at t1."""
        rng = np.random.default_rng([self.seed, 1, j])
        radar = sr.radar
        frame = RadarFrame(radar.lat, radar.lon, radar.height_m, self.plane)
        out: dict[str, list] = {k: [] for k in ("time", "radar", "range_m", "azimuth_rad", "altitude_m",
                                                "mode_s", "mode_3a", "target")}
        for sa in self.aircraft:
            t = self._crossings(frame, sr, sa.trajectory)
            if len(t) == 0:
                continue
            lat, lon, h = self._geo(sa.trajectory, t)
            rho, theta, elev = frame.polar(lat, lon, h)
            seen = sr.visible(rho, theta, elev)
            seen &= rng.random(len(t)) < sr.pd
            n = int(seen.sum())
            if n == 0:
                continue
            out["time"].append(t[seen])
            out["range_m"].append(rho[seen] + rng.normal(0.0, radar.sigma_range_m, n))
            out["azimuth_rad"].append(theta[seen] + rng.normal(0.0, radar.sigma_azimuth_rad, n))
            ac = sa.aircraft
            mode_c = np.round(h[seen] / _MODE_C_STEP_M) * _MODE_C_STEP_M
            out["altitude_m"].append(mode_c if ac.transponder != "none" else np.full(n, np.nan))
            mode_s = ac.icao24 if ac.transponder == "mode_s" else None
            mode_3a = ac.mode_3a if ac.transponder != "none" else None
            for key, value in (("mode_s", mode_s), ("mode_3a", mode_3a), ("target", ac.icao24)):
                out[key].append(np.full(n, value, dtype=object))
        self._false_plots(sr, rng, out)
        cols = {k: (np.concatenate(v) if v else np.empty(0, dtype=object if k in ("mode_s", "mode_3a", "target") else float))
                for k, v in out.items() if k != "radar"}
        # the bias random walk is sampled at the sorted plot times, then at t1 for the truth file
        t = cols["time"]
        order = np.argsort(t, kind="stable")
        br, ba = self._bias_walk(j, sr, np.append(t[order], self.t1))
        bias_r, bias_a = np.empty_like(t), np.empty_like(t)
        bias_r[order], bias_a[order] = br[:-1], ba[:-1]
        extra = apply_sensor_errors(cols, sr, self.seed, j, self.t0, self.t1)
        cols["range_m"] = np.maximum(cols["range_m"] + bias_r, 0.0)
        cols["azimuth_rad"] = np.mod(cols["azimuth_rad"] + bias_a, 2 * np.pi)
        cols["radar"] = np.full(len(t), radar.id, dtype=object)
        return cols, (float(br[-1]), float(ba[-1])), extra

    def _false_plots(self, sr: SimRadar, rng: np.random.Generator, out: dict[str, list]) -> None:
        if sr.false_per_scan <= 0:
            return
        T = sr.radar.period_s
        n_scans = int(math.ceil((self.t1 - self.t0) / T))
        counts = rng.poisson(sr.false_per_scan, n_scans)
        n = int(counts.sum())
        if n == 0:
            return
        scan = np.repeat(np.arange(n_scans), counts)
        theta = rng.uniform(0, 2 * np.pi, n)
        t = self.t0 + T * (scan + np.mod(theta - sr.phase_rad, 2 * np.pi) / (2 * np.pi))
        keep = t <= self.t1
        m = int(keep.sum())
        out["time"].append(t[keep])
        out["range_m"].append(sr.radar.max_range_m * np.sqrt(rng.uniform(0.0025, 1.0, n))[keep])
        out["azimuth_rad"].append(theta[keep])
        out["altitude_m"].append(np.full(m, np.nan))
        for key in ("mode_s", "mode_3a", "target"):
            out[key].append(np.full(m, None, dtype=object))

    def _bias_walk(self, j: int, sr: SimRadar, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bias (Δr, Δθ) at sorted times ``t``, random walk from the initial values."""
        dr, da = random_walks(np.random.default_rng([self.seed, 2, j]), self.t0, t,
                              (sr.range_bias_m, sr.azimuth_bias_rad), (sr.drift_range, sr.drift_azimuth))
        return dr, da

    # --- ADS-B and truth -----------------------------------------------------------------------
    def _adsb(self) -> AdsbTable:
        cols: dict[str, list] = {k: [] for k in ("time", "icao24", "lat", "lon", "altitude_m", "nacp")}
        for i, sa in enumerate(self.aircraft):
            ac = sa.aircraft
            ta, tb = self._span(sa.trajectory)
            if not ac.adsb or tb <= ta:
                continue
            rng = np.random.default_rng([self.seed, 3, i])
            t = np.arange(ta + rng.uniform(0, self.adsb_period_s), tb, self.adsb_period_s)
            x, y, h = sa.trajectory.position(t)
            sd = nacp_sigma_m(ac.nacp)
            lat, lon = self.plane.to_geodetic(x + rng.normal(0, sd, len(t)), y + rng.normal(0, sd, len(t)))
            for k, v in (("time", t), ("icao24", [ac.icao24] * len(t)), ("lat", lat), ("lon", lon),
                         ("altitude_m", h), ("nacp", [ac.nacp] * len(t))):
                cols[k].append(np.asarray(v))
        merged = {k: np.concatenate(v) if v else [] for k, v in cols.items()}
        table = AdsbTable.from_columns(**merged)
        order = np.argsort(table.time, kind="stable")
        return AdsbTable(**{f.name: getattr(table, f.name)[order] for f in attrs.fields(AdsbTable)})

    def _truth(self) -> TruthTable:
        cols: dict[str, list] = {k: [] for k in ("time", "target", "lat", "lon", "altitude_m")}
        for sa in self.aircraft:
            ta, tb = self._span(sa.trajectory)
            if tb <= ta:
                continue
            t = np.append(np.arange(ta, tb, self.truth_step_s), tb)
            lat, lon, h = self._geo(sa.trajectory, t)
            for k, v in (("time", t), ("target", [sa.aircraft.icao24] * len(t)), ("lat", lat), ("lon", lon),
                         ("altitude_m", h)):
                cols[k].append(np.asarray(v))
        return TruthTable.from_columns(**{k: np.concatenate(v) if v else [] for k, v in cols.items()})

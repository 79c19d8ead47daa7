"""National-scale synthetic traffic, vectorised over aircraft and antenna scans.

The model is :class:`radartracker.simulation.simulator.Simulator`'s, computed for all aircraft
of a radar at once instead of one aircraft at a time:

* Flights follow seed 000 eq. 2.1 at constant speed (w = 0): straight legs of 5–15 min between
  level turns of 1–3 °/s lasting 20–60 s (u = v·ω), at a constant altitude. Flights last 20–90 min
  and start uniformly over [−90 min, duration], so about ``aircraft`` are airborne at any time.
* Radars on a jittered grid ``spacing_km`` apart, periods 4–12 s, Pd, constant biases.
* Antenna timing as in the simulator: for each scan k the crossing time solves θ(t) = α(t),
  α(t) = φ + 2π(t − t₀)/T, by the same fixed-point iteration on the exact azimuth (pyproj,
  :class:`RadarFrame` and :class:`SystemPlane` called once per iteration on every aircraft-scan
  pair of the radar); visibility (range, radar horizon, 45° cone of silence), Mode C rounding,
  range/azimuth noise, bias random walk, false plots and ADS-B as in the simulator.

:meth:`TrafficSimulator.simulator` builds the equivalent per-aircraft :class:`Simulator`; the
tests hold both to the same noiseless plots.
"""

from __future__ import annotations

import math

import attrs
import numpy as np
from tqdm import tqdm

from radartracker.domain import Aircraft, Radar, nacp_sigma_m
from radartracker.errors import ConfigurationError
from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.io.tables import AdsbTable, PlotTable, ScenarioData, TruthTable
from radartracker.simulation.memory import check_fits, traffic_bytes
from radartracker.simulation.simulator import (_MODE_C_STEP_M,
                                               KinematicTrajectory, Leg, SimAircraft, SimRadar, Simulator,
                                               apply_sensor_errors, time_ordered, walks_at)

_U_EPS = 1e-9  # as radartracker.geometry.kinematics: below this |u| a leg is straight
_N_LEGS = 36  # enough alternating straight/turn legs for the longest flight (90 min)


def _share(inst, attr, value) -> None:
    if not 0.0 <= value <= 1.0:
        raise ConfigurationError(f"{attr.name}: must be in [0, 1], got {value!r}")


def _at_least(low: float, strict: bool = False):
    def check(inst, attr, value) -> None:
        if not (value > low if strict else value >= low) or not math.isfinite(value):
            raise ConfigurationError(f"{attr.name}: must be {'>' if strict else '>='} {low:g}, got {value!r}")
    return check


def _span(low: float):
    """A (low, high) pair of numbers with ``low`` ≤ the first ≤ the second (a uniform draw's bounds)."""
    def check(inst, attr, value) -> None:
        try:
            lo, hi = (float(v) for v in value)
        except (TypeError, ValueError):
            raise ConfigurationError(f"{attr.name}: expected two numbers (low, high), got {value!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and low <= lo <= hi):
            raise ConfigurationError(f"{attr.name}: expected {low:g} <= low <= high, got {value!r}")
    return check


def _one_of(names: tuple[str, ...]):
    def check(inst, attr, value) -> None:
        if value not in names:
            raise ConfigurationError(f"{attr.name}: one of {', '.join(names)}, got {value!r}")
    return check


TRANSPONDERS = ("mode_s", "mode_c", "none")


@attrs.frozen
class TrafficConfig:
    """Size and mix of the synthetic traffic: mean airborne ``aircraft``, ``radars``, ``duration_s``.

    The airspace: radars on a grid ``spacing_km`` apart with coverage ``max_range_km`` and rotation
    periods drawn uniformly from ``period_s``, constant biases drawn from N(0, ``range_bias_sd_m``²) and
    N(0, ``azimuth_bias_sd_deg``²); flights at constant altitudes and speeds drawn uniformly from
    ``altitude_m`` and ``speed_mps``. What the plots of an aircraft with a transponder carry is
    ``transponder``: ``mode_s`` (Mode S address, Mode 3/A code and Mode C altitude), ``mode_c`` (Mode C
    altitude alone: no identity, as old transponders or stripped recordings) or ``none`` (no transponder
    at all: primary plots without altitude); ``primary_share`` of the aircraft have no transponder
    whatever ``transponder`` says. The defaults are the national traffic; an en-route cruise set under
    dense overlapping coverage is e.g. ``radars=5, spacing_km=100, period_s=(8, 12),
    altitude_m=(9144, 12192), speed_mps=(170, 310), transponder="mode_c"``.
    """

    aircraft: int = attrs.field(default=200, validator=_at_least(1))
    radars: int = attrs.field(default=28, validator=_at_least(1))
    duration_s: float = attrs.field(default=180.0, validator=_at_least(0.0, strict=True))
    adsb_share: float = attrs.field(default=0.3, validator=_share)
    primary_share: float = attrs.field(default=0.0, validator=_share)
    pd: float = attrs.field(default=0.9, validator=_share)
    false_per_scan: float = attrs.field(default=0.0, validator=_at_least(0.0))
    spacing_km: float = attrs.field(default=200.0, validator=_at_least(0.0, strict=True))
    max_range_km: float = attrs.field(default=250.0, validator=_at_least(0.0, strict=True))
    period_s: tuple[float, float] = attrs.field(default=(4.0, 12.0), converter=tuple, validator=_span(0.5))
    range_bias_sd_m: float = attrs.field(default=100.0, validator=_at_least(0.0))
    azimuth_bias_sd_deg: float = attrs.field(default=0.1, validator=_at_least(0.0))
    altitude_m: tuple[float, float] = attrs.field(default=(7000.0, 12000.0), converter=tuple, validator=_span(0.0))
    speed_mps: tuple[float, float] = attrs.field(default=(200.0, 250.0), converter=tuple, validator=_span(1.0))
    transponder: str = attrs.field(default="mode_s", validator=_one_of(TRANSPONDERS))
    truth_step_s: float = attrs.field(default=2.0, validator=_at_least(0.0, strict=True))
    reference: tuple[float, float] = (46.5, 2.5)
    seed: int = 1

    def __attrs_post_init__(self) -> None:
        if self.adsb_share + self.primary_share > 1.0:
            raise ConfigurationError(f"adsb_share + primary_share must be <= 1 (primary-only aircraft have no ADS-B), "
                                     f"got {self.adsb_share} + {self.primary_share}")


@attrs.frozen
class Flights:
    """Legs of every flight as arrays (n, L): start time, position, heading at each leg start, and u."""

    t_start: np.ndarray
    t_end: np.ndarray
    leg_t: np.ndarray
    leg_x: np.ndarray
    leg_y: np.ndarray
    leg_phi: np.ndarray
    leg_u: np.ndarray
    speed: np.ndarray
    altitude: np.ndarray

    def __len__(self) -> int:
        return len(self.t_start)

    def position(self, ac: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Plane (x, y, h) of flights ``ac`` at times ``t`` (clamped to each flight's span)."""
        t = np.clip(t, self.t_start[ac], self.t_end[ac])
        n_legs = self.leg_t.shape[1]
        # leg index: number of leg starts ≤ t, minus one (legs sorted per flight, flights offset)
        span = float(np.ptp(self.leg_t)) + 1.0 if self.leg_t.size else 1.0
        offset = (np.arange(len(self)) * span)[:, None]
        flat = (self.leg_t - self.leg_t.min() + offset).ravel()
        seg = np.searchsorted(flat, t - self.leg_t.min() + ac * span, side="right") - 1 - ac * n_legs
        seg = np.clip(seg, 0, n_legs - 1)
        x, y, _ = _arc(self.leg_x[ac, seg], self.leg_y[ac, seg], self.leg_phi[ac, seg], self.speed[ac],
                       self.leg_u[ac, seg], t - self.leg_t[ac, seg])
        return x, y, self.altitude[ac]


def _arc(x0, y0, phi0, v, u, tau):
    """Seed eq. 2.1 with w = 0, element by element (the formulas of ``kinematics.propagate``)."""
    turning = np.abs(u) >= _U_EPS
    safe_u = np.where(turning, u, 1.0)
    phi = np.where(turning, phi0 + u / v * tau, phi0)
    r = v * v / safe_u
    x = np.where(turning, x0 - r * (np.cos(phi) - np.cos(phi0)), x0 + v * tau * np.sin(phi0))
    y = np.where(turning, y0 + r * (np.sin(phi) - np.sin(phi0)), y0 + v * tau * np.cos(phi0))
    return x, y, phi


def _grid(n: int, spacing: float, rng: np.random.Generator) -> np.ndarray:
    rows = max(1, round(math.sqrt(n / 1.75)))
    cols = math.ceil(n / rows)
    j = np.arange(n)
    xy = np.column_stack([(j % cols - (cols - 1) / 2) * spacing, (j // cols - (rows - 1) / 2) * 1.1 * spacing])
    return xy + rng.uniform(-0.15, 0.15, xy.shape) * spacing


class TrafficSimulator:
    """Radars, flights and identities of a :class:`TrafficConfig`; :meth:`run` gives the scenario."""

    def __init__(self, config: TrafficConfig) -> None:
        self.config = c = config
        check_fits(f"--scenario traffic with {c.aircraft:,} aircraft over {c.duration_s:g} s",
                   traffic_bytes(c.aircraft, c.duration_s))
        self.plane = SystemPlane(*c.reference)
        self.t0, self.t1 = 0.0, float(c.duration_s)
        rng = np.random.default_rng([c.seed, 10])
        rxy = _grid(c.radars, c.spacing_km * 1e3, rng)
        lat, lon = self.plane.to_geodetic(rxy[:, 0], rxy[:, 1])
        self.radars = [
            SimRadar(Radar(f"R{j:02d}", float(lat[j]), float(lon[j]), 100.0, 70.0, math.radians(0.08),
                           float(rng.uniform(*c.period_s)), c.max_range_km * 1e3),
                     float(rng.normal(0.0, c.range_bias_sd_m)), float(rng.normal(0.0, math.radians(c.azimuth_bias_sd_deg))),
                     pd=c.pd,
                     false_per_scan=c.false_per_scan, phase_rad=float(rng.uniform(0, 2 * np.pi)))
            for j in range(c.radars)]
        half = np.abs(rxy).max(axis=0) + c.max_range_km * 1e3 * 0.6
        self.flights = self._flights(rng, half)
        n = len(self.flights)
        kind = rng.random(n)
        primary = kind < c.primary_share
        adsb = ~primary & (rng.random(n) < c.adsb_share / max(1.0 - c.primary_share, 1e-9))
        # "mode_c": a Mode A/C transponder without a Mode 3/A code, so its plots carry the altitude alone
        fitted = {"mode_s": "mode_s", "mode_c": "mode_a_c", "none": "none"}[c.transponder]
        self.aircraft = [Aircraft(f"{0x400000 + i:06x}", f"TFC{i:05d}",
                                  f"{(1000 + 37 * i) % 4096:04o}" if c.transponder == "mode_s" else None,
                                  adsb=bool(adsb[i]), nacp=8, transponder="none" if primary[i] else fitted)
                         for i in range(n)]

    def _flights(self, rng: np.random.Generator, half: np.ndarray) -> Flights:
        c = self.config
        n = int(round(c.aircraft * (c.duration_s + 5400.0) / 3300.0))  # mean life (1200 + 5400)/2
        life = rng.uniform(1200.0, 5400.0, n)
        start = rng.uniform(-5400.0, c.duration_s, n)
        keep = (start + life > 0.0)
        n = int(keep.sum())
        life, start = life[keep], start[keep]
        speed = rng.uniform(*c.speed_mps, n)
        heading = rng.uniform(0.0, 2 * np.pi, n)
        altitude = rng.uniform(*c.altitude_m, n)
        # alternating straight legs (5–15 min) and turns of 1–3 °/s for 20–60 s
        dur = np.where(np.arange(_N_LEGS) % 2 == 0, rng.uniform(300.0, 900.0, (n, _N_LEGS)),
                       rng.uniform(20.0, 60.0, (n, _N_LEGS)))
        rate = np.radians(rng.uniform(1.0, 3.0, (n, _N_LEGS))) * rng.choice([-1.0, 1.0], (n, _N_LEGS))
        u = np.where(np.arange(_N_LEGS) % 2 == 1, speed[:, None] * rate, 0.0)
        # start so that mid-flight lies anywhere over the region
        mid = rng.uniform(-1.0, 1.0, (n, 2)) * half
        x = mid[:, 0] - 0.5 * life * speed * np.sin(heading)
        y = mid[:, 1] - 0.5 * life * speed * np.cos(heading)
        cols = {k: np.empty((n, _N_LEGS)) for k in ("t", "x", "y", "phi")}
        t, phi = start.copy(), heading.copy()
        for leg in range(_N_LEGS):
            cols["t"][:, leg], cols["x"][:, leg], cols["y"][:, leg], cols["phi"][:, leg] = t, x, y, phi
            x, y, phi = _arc(x, y, phi, speed, u[:, leg], dur[:, leg])
            t = t + dur[:, leg]
        return Flights(start, start + life, cols["t"], cols["x"], cols["y"], cols["phi"], u, speed, altitude)

    # --- the equivalent per-aircraft simulator ----------------------------------------------------
    def simulator(self) -> Simulator:
        """The same radars and flights as a :class:`Simulator` (slow; for checking this module)."""
        f = self.flights
        aircraft = []
        for i, ac in enumerate(self.aircraft):
            starts = f.leg_t[i]
            used = np.flatnonzero(starts < f.t_end[i])
            ends = np.append(starts[used[1:]], f.t_end[i])
            legs = [Leg(float(e - s), u=float(f.leg_u[i, k])) for k, s, e in zip(used, starts[used], ends)]
            traj = KinematicTrajectory(float(f.t_start[i]), float(f.leg_x[i, 0]), float(f.leg_y[i, 0]),
                                       float(f.altitude[i]), float(f.leg_phi[i, 0]), float(f.speed[i]), legs)
            aircraft.append(SimAircraft(ac, traj))
        c = self.config
        return Simulator(c.reference, self.radars, aircraft, self.t0, self.t1, seed=c.seed,
                         truth_step_s=c.truth_step_s, name="traffic")

    # --- simulation -------------------------------------------------------------------------------
    def run(self) -> ScenarioData:
        """The scenario, radar by radar (a progress bar on stderr after 2 s, off with TQDM_DISABLE / --quiet)."""
        parts, truth_biases, truth_sensor = [], {}, {}
        for j, sr in enumerate(tqdm(self.radars, desc="simulate", unit="radar", delay=2.0, mininterval=1.0)):
            cols, truth_biases[sr.radar.id], truth_sensor[sr.radar.id] = self._radar_plots(j, sr)
            parts.append(cols)
        plots = PlotTable(**time_ordered(parts))
        return ScenarioData(reference=self.config.reference, radars=[sr.radar for sr in self.radars], plots=plots,
                            adsb=self._adsb(), truth=self._truth(), truth_biases=truth_biases,
                            truth_sensor=truth_sensor if any(sr.has_gain_or_time for sr in self.radars) else None,
                            aircraft=self.aircraft, name="traffic")

    def _span(self) -> tuple[np.ndarray, np.ndarray]:
        return np.maximum(self.flights.t_start, self.t0), np.minimum(self.flights.t_end, self.t1)

    def _polar(self, frame: RadarFrame, ac: np.ndarray, t: np.ndarray):
        x, y, h = self.flights.position(ac, t)
        lat, lon = self.plane.to_geodetic(x, y)
        return frame.polar(lat, lon, h)

    def _crossings(self, frame: RadarFrame, sr: SimRadar) -> tuple[np.ndarray, np.ndarray]:
        """(flight, time) of every antenna crossing within each flight's span, as Simulator._crossings."""
        T = sr.radar.period_s
        ta, tb = self._span()
        alive = np.flatnonzero(tb > ta)
        k_lo = np.floor((ta[alive] - self.t0) / T).astype(int) - 1
        k_hi = np.ceil((tb[alive] - self.t0) / T).astype(int) + 1
        count = k_hi - k_lo
        ac = np.repeat(alive, count)
        k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count) + np.repeat(k_lo, count)
        scan_start = self.t0 + k * T
        # only pairs that can be in range: the aircraft moves < 300 m/s × T within a scan
        x, y, _ = self.flights.position(ac, scan_start)
        near = np.hypot(x - frame.xy[0], y - frame.xy[1]) < sr.radar.max_range_m + 300.0 * T + 10e3
        ac, scan_start = ac[near], scan_start[near]
        lo, hi = ta[ac], tb[ac]
        _, theta, _ = self._polar(frame, ac, np.clip(scan_start, lo, hi))
        t = scan_start + T * np.mod(theta - sr.phase_rad, 2 * np.pi) / (2 * np.pi)
        for _ in range(3):
            _, theta, _ = self._polar(frame, ac, np.clip(t, lo, hi))
            antenna = sr.phase_rad + 2 * np.pi * (t - self.t0) / T
            t = t + T * (np.mod(theta - antenna + np.pi, 2 * np.pi) - np.pi) / (2 * np.pi)
        inside = (t >= lo) & (t <= hi)
        ac, t = ac[inside], t[inside]
        order = np.lexsort((t, ac))
        ac, t = ac[order], t[order]
        # adjacent scans can converge to the same crossing near the antenna's start azimuth
        first = np.concatenate([[True], (ac[1:] != ac[:-1]) | (np.diff(t) > 0.5 * T)]) if len(t) else np.empty(0, bool)
        return ac[first], t[first]

    def _radar_plots(self, j: int, sr: SimRadar) -> tuple[dict[str, np.ndarray], tuple[float, float], dict[str, float]]:
        rng = np.random.default_rng([self.config.seed, 1, j])
        radar = sr.radar
        frame = RadarFrame(radar.lat, radar.lon, radar.height_m, self.plane)
        ac, t = self._crossings(frame, sr)
        rho, theta, elev = self._polar(frame, ac, t)
        seen = sr.visible(rho, theta, elev)
        seen &= rng.random(len(t)) < sr.pd
        ac, t, rho, theta = ac[seen], t[seen], rho[seen], theta[seen]
        n = len(t)
        rho = rho + rng.normal(0.0, radar.sigma_range_m, n)
        theta = theta + rng.normal(0.0, radar.sigma_azimuth_rad, n)
        icao = np.array([a.icao24 for a in self.aircraft], dtype=object)
        squawk = np.array([a.mode_3a for a in self.aircraft], dtype=object)
        primary = np.array([a.transponder == "none" for a in self.aircraft], bool)
        mode_s = np.array([a.transponder == "mode_s" for a in self.aircraft], bool)
        alt = np.round(self.flights.altitude[ac] / _MODE_C_STEP_M) * _MODE_C_STEP_M
        cols = {"time": t, "range_m": rho, "azimuth_rad": theta, "altitude_m": np.where(primary[ac], np.nan, alt),
                "mode_s": np.where(mode_s[ac], icao[ac], None), "mode_3a": np.where(primary[ac], None, squawk[ac]),
                "target": icao[ac]}
        false = self._false_plots(sr, rng)
        cols = {k: np.concatenate([v, false[k]]) for k, v in cols.items()}
        t = cols["time"]
        (bias_r, bias_a), (br, ba) = walks_at(np.random.default_rng([self.config.seed, 2, j]), self.t0, self.t1,
                                              t, (sr.range_bias_m, sr.azimuth_bias_rad),
                                              (sr.drift_range, sr.drift_azimuth))
        extra = apply_sensor_errors(cols, sr, self.config.seed, j, self.t0, self.t1)
        cols["range_m"] = np.maximum(cols["range_m"] + bias_r, 0.0)
        cols["azimuth_rad"] = np.mod(cols["azimuth_rad"] + bias_a, 2 * np.pi)
        cols["radar"] = np.full(len(t), radar.id, dtype=object)
        return cols, (float(br), float(ba)), extra

    def _false_plots(self, sr: SimRadar, rng: np.random.Generator) -> dict[str, np.ndarray]:
        T = sr.radar.period_s
        n_scans = int(math.ceil((self.t1 - self.t0) / T))
        counts = rng.poisson(sr.false_per_scan, n_scans) if sr.false_per_scan > 0 else np.zeros(n_scans, int)
        n = int(counts.sum())
        scan = np.repeat(np.arange(n_scans), counts)
        theta = rng.uniform(0, 2 * np.pi, n)
        t = self.t0 + T * (scan + np.mod(theta - sr.phase_rad, 2 * np.pi) / (2 * np.pi))
        rho = sr.radar.max_range_m * np.sqrt(rng.uniform(0.0025, 1.0, n))
        keep = t <= self.t1
        m = int(keep.sum())
        none = np.full(m, None, dtype=object)
        return {"time": t[keep], "range_m": rho[keep], "azimuth_rad": theta[keep], "altitude_m": np.full(m, np.nan),
                "mode_s": none, "mode_3a": none, "target": none}

    def _adsb(self) -> AdsbTable:
        """Reports every second from a random phase, per-axis noise from NACp (as the simulator)."""
        ta, tb = self._span()
        cols: dict[str, list] = {k: [] for k in ("time", "ac", "dx", "dy")}
        for i, ac in enumerate(self.aircraft):
            if not ac.adsb or tb[i] <= ta[i]:
                continue
            rng = np.random.default_rng([self.config.seed, 3, i])
            t = np.arange(ta[i] + rng.uniform(0, 1.0), tb[i], 1.0)
            sd = nacp_sigma_m(ac.nacp)
            cols["time"].append(t)
            cols["ac"].append(np.full(len(t), i))
            cols["dx"].append(rng.normal(0, sd, len(t)))
            cols["dy"].append(rng.normal(0, sd, len(t)))
        t, i, dx, dy = (np.concatenate(v) if v else np.empty(0) for v in cols.values())
        i = i.astype(int)
        x, y, h = self.flights.position(i, t)
        lat, lon = self.plane.to_geodetic(x + dx, y + dy)
        order = np.argsort(t, kind="stable")
        icao = np.array([a.icao24 for a in self.aircraft], dtype=object)
        nacp = np.array([a.nacp for a in self.aircraft], int)
        return AdsbTable(time=t[order], icao24=icao[i][order], lat=lat[order], lon=lon[order], altitude_m=h[order],
                         nacp=nacp[i][order])

    def _truth(self) -> TruthTable:
        """Positions every ``truth_step_s`` from each flight's first time in the run, and at its last."""
        ta, tb = self._span()
        alive = np.flatnonzero(tb > ta)
        step = self.config.truth_step_s
        count = np.ceil((tb[alive] - ta[alive]) / step).astype(int) + 1
        ac = np.repeat(alive, count)
        k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
        t = np.minimum(ta[ac] + k * step, tb[ac])
        last = np.cumsum(count) - 1
        t[last] = tb[alive]
        x, y, h = self.flights.position(ac, t)
        lat, lon = self.plane.to_geodetic(x, y)
        icao = np.array([a.icao24 for a in self.aircraft], dtype=object)
        order = np.lexsort((ac, t))
        return TruthTable(time=t[order], target=icao[ac][order], lat=lat[order], lon=lon[order], altitude_m=h[order])


def traffic_scenario(seed: int = 1, duration: float | None = None, **options) -> TrafficSimulator:
    """National traffic (see :class:`TrafficConfig` for ``options``); 3 minutes unless ``duration``."""
    return TrafficSimulator(TrafficConfig(seed=seed, duration_s=180.0 if duration is None else duration, **options))

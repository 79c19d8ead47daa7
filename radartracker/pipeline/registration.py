"""Registration with the sensor error model on a labelled scenario, with the Cramér–Rao bound beside each
estimate (issue 30; docs/estimators.md, "Sensor error model").

Every plot of a labelled aircraft (its truth label) and every ADS-B report goes, in time order, to the
estimator as a :class:`PlaneMeasurement` with its slant range (for a range gain's column ρ·∂z/∂ρ). An
aircraft starts at its first measurement from N([z, 0, 0], diag(σ_p², σ_p², σ_v², σ_v²)) and is
marginalised after its last. From its third measurement on, a plot's Jacobian C, noise R and slant range
are evaluated at the track's prediction rather than at the plot, whose own noise they would otherwise
carry (docs/design-notes.md). The TrackManager does not carry the new components yet (it refuses them), so
this is the path that estimates them end to end. The bound (:mod:`radartracker.estimation.bound`) is
evaluated on the same measurements at the truth's positions and velocities where the scenario has a
truth, else at the estimator's own estimates.
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from radartracker.domain import BiasState
from radartracker.estimation.base import Estimator, EstimatorConfig, PlaneMeasurement
from radartracker.estimation.bound import BoundInput, ComponentBound, bias_bound
from radartracker.estimation.measurement import convert_adsb, convert_plots, fill_altitudes, merge, plot_keys
from radartracker.estimation.sensor import SensorModel
from radartracker.geometry.plane import RadarFrame, SystemPlane, bias_jacobian
from radartracker.io.tables import ScenarioData
from radartracker.pipeline.evaluate import TruthPaths
from radartracker.registry import make_estimator

PREDICT_AFTER = 2  # measurements of an aircraft before its plots' Jacobians are taken at its prediction
SETTLE_S = 120.0  # position RMSE counts an aircraft's estimates after this much of its track (its start settles)


@attrs.frozen
class ComponentReport:
    """One bias component: estimate and σ of the estimator, √CRLB and observability, truth and z where known."""

    radar: str
    component: str
    estimate: float
    sd: float
    crlb_sd: float
    status: str
    truth: float = math.nan

    @property
    def z(self) -> float:
        """(estimate − truth)/σ; NaN without truth."""
        return (self.estimate - self.truth) / self.sd if self.sd > 0.0 else math.nan


@attrs.frozen
class Registration:
    """The final biases, the report per component and the tracks' position RMSE (m; NaN without truth)."""

    biases: dict[str, BiasState]
    components: list[ComponentReport]
    position_rmse_m: float


def true_components(data: ScenarioData) -> dict[str, dict[str, float]]:
    """Every radar's true components by name (``truth_biases.csv``), empty without a truth file."""
    out: dict[str, dict[str, float]] = {}
    for rid, (dr, da) in (data.truth_biases or {}).items():
        out[rid] = {"range_offset": dr, "azimuth_offset": da, **(data.truth_sensor or {}).get(rid, {})}
    return out


def _columns(data: ScenarioData, plane: SystemPlane) -> dict[str, np.ndarray]:
    """Valid labelled plots and ADS-B reports, in time order, as columns, with each one's slant range ``rho``
    and altitude ``alt`` (NaN for ADS-B)."""
    keys = plot_keys(data.plots, use_truth=True)
    alt, _ = fill_altitudes(data.plots, keys, 10_000.0)
    plots = convert_plots(data.plots, data.radars, plane, keys, alt)
    adsb = convert_adsb(data.adsb, plane)
    both = merge(plots, adsb)
    order = np.argsort(np.concatenate([plots.time, adsb.time]), kind="stable")
    keep = both.valid & np.array([k is not None for k in both.key], bool)
    cols = {f.name: getattr(both, f.name)[keep] for f in attrs.fields(type(both))}
    nan = np.full(len(adsb), np.nan)
    cols["rho"] = np.concatenate([data.plots.range_m, nan])[order][keep]
    cols["alt"] = np.concatenate([alt, nan])[order][keep]
    return cols


class _Geometry:
    """C = ∂p/∂(ρ, θ), R = C W Cᵀ and the slant range ρ of radar plots evaluated at given plane positions (the
    truth's, or a track's prediction) instead of at the noisy plot (docs/design-notes.md: why)."""

    def __init__(self, data: ScenarioData, plane: SystemPlane) -> None:
        self.plane = plane
        self.frames = {r.id: RadarFrame(r.lat, r.lon, r.height_m, plane) for r in data.radars}
        self.W = {r.id: r.W for r in data.radars}

    def at(self, radar: str, p: np.ndarray, alt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        frame = self.frames[radar]
        lat, lon = self.plane.to_geodetic(p[..., 0], p[..., 1])
        rho = frame.polar(lat, lon, alt)[0]
        C = frame.bias_jacobian(p, rho, alt)
        return C, C @ self.W[radar] @ np.swapaxes(C, -1, -2), rho

    def at_prediction(self, radar: str, p: np.ndarray, z: np.ndarray, rho: float, C: np.ndarray, alt: float
                      ) -> tuple[np.ndarray, np.ndarray, float]:
        """C, R, ρ at the predicted position ``p`` of a plot ``z`` (slant range ``rho``, Jacobian ``C``), without
        geodesy: ρ̄ = ρ + (d̄ − d)/|c_ρ| (d the plane distance from the radar, |c_ρ| = ∂d/∂ρ at the plot), exact
        to second order in p − z, then the spherical Jacobian of :meth:`RadarFrame.bias_jacobian` at (p, ρ̄)."""
        frame = self.frames[radar]
        d_bar, d = np.linalg.norm(p - frame.xy), np.linalg.norm(z - frame.xy)
        rho_bar = rho + (d_bar - d) / np.linalg.norm(C[:, 0])
        Cp = bias_jacobian(frame.xy, frame.height_m, p, np.asarray(rho_bar), np.asarray(alt))
        return Cp, Cp @ self.W[radar] @ Cp.T, float(rho_bar)

    def at_truth(self, cols: dict[str, np.ndarray], true_xy: np.ndarray) -> dict[str, np.ndarray]:
        """``cols`` with every radar plot's C, R and ρ at its true position where the truth has one."""
        out = {k: v.copy() for k, v in cols.items()}
        for radar in self.frames:
            idx = np.flatnonzero((cols["radar"] == radar) & np.isfinite(true_xy[:, 0]))
            if len(idx):
                out["C"][idx], out["R"][idx], out["rho"][idx] = self.at(radar, true_xy[idx], cols["alt"][idx])
        return out


def register(data: ScenarioData, config: EstimatorConfig, estimator: str = "coupled",
             aircraft_sd: tuple[float, float] = (1e5, 1e3)) -> Registration:
    """Feed ``data``'s labelled measurements to ``estimator`` built with ``config`` (its sensor models) and
    report each component beside its bound (module docstring). A range gain or time offset the bound calls
    unobservable is left out of the estimated model (held at its prior mean, reported with its prior σ)."""
    plane = SystemPlane(*data.reference)
    cols = _columns(data, plane)
    geometry = _Geometry(data, plane)
    radar_ids = [r.id for r in data.radars]
    P0 = np.diag([aircraft_sd[0] ** 2] * 2 + [aircraft_sd[1] ** 2] * 2)
    truth = true_components(data)
    true_states = (_truth_states(TruthPaths.from_table(data.truth, plane), cols["key"], cols["time"])
                   if data.truth is not None else np.full((len(cols["time"]), 4), np.nan))
    run = None
    if not np.isfinite(true_states).all():  # the bound needs states: the estimator's where there is no truth
        run = _feed(make_estimator(estimator, config, radar_ids), cols, geometry, P0)
    states = true_states if run is None else np.where(np.isfinite(true_states), true_states, run[1])
    at = geometry.at_truth(cols, states[:, :2])
    bound = bias_bound(BoundInput(at["time"], at["key"], at["radar"], at["C"], at["R"], at["rho"], states[:, 2:],
                                  {k: P0 for k in set(cols["key"].tolist())}),
                       config, radar_ids, {r: v.get("time_offset", 0.0) for r, v in truth.items()})
    reduced = _observable_only(config, bound, radar_ids)
    if run is None or reduced != config:
        run = _feed(make_estimator(estimator, reduced, radar_ids), cols, geometry, P0)
    est, estimates = run
    rmse = math.nan
    if data.truth is not None:
        _, first, which = np.unique(cols["key"], return_index=True, return_inverse=True)  # each key's first row
        late = (cols["time"] >= cols["time"][first][which] + SETTLE_S) & np.isfinite(true_states[:, 0])
        rmse = float(np.sqrt(np.mean(np.sum((estimates[late, :2] - true_states[late, :2]) ** 2, axis=1))))
    biases = {r: est.bias(r) for r in radar_ids}
    return Registration(biases, _report(biases, bound, truth), rmse)


def _feed(est: Estimator, cols: dict[str, np.ndarray], geometry: _Geometry, P0: np.ndarray
          ) -> tuple[Estimator, np.ndarray]:
    """Every measurement to ``est`` in turn (an aircraft added at its first, removed after its last); the
    estimator and its estimate [x, y, vx, vy] of the measured aircraft after each. From an aircraft's
    :data:`PREDICT_AFTER`-th measurement on, a plot's C, R and ρ are those of the track's prediction."""
    n = len(cols["time"])
    last = {k: i for i, k in enumerate(cols["key"])}
    seen: dict = {}
    states = np.zeros((n, 4))
    for i in range(n):
        t, key, radar = float(cols["time"][i]), cols["key"][i], cols["radar"][i]
        if key not in est.aircraft_keys:
            est.add_aircraft(key, t, np.concatenate([cols["z"][i], [0.0, 0.0]]), P0)
        C, R, rho = cols["C"][i], cols["R"][i], float(cols["rho"][i])
        if radar is not None and seen.get(key, 0) >= PREDICT_AFTER:
            C, R, rho = geometry.at_prediction(radar, est.predict(key, t).state[:2], cols["z"][i], rho, C,
                                               float(cols["alt"][i]))
        est.update(PlaneMeasurement(t, key, radar, cols["z"][i], C, R, float(rho)))
        seen[key] = seen.get(key, 0) + 1
        states[i] = est.aircraft(key).state
        if last[key] == i:
            est.remove_aircraft(key)
    return est, states


def _observable_only(config: EstimatorConfig, bound: dict[str, list[ComponentBound]],
                     radar_ids: list[str]) -> EstimatorConfig:
    """``config`` without the range gains and time offsets the bound calls unobservable: the plots carry no
    information on them, so estimated they would only absorb what the model leaves out."""
    sensors = {}
    for rid in radar_ids:
        model = config.sensor(rid)
        drop = {b.component for b in bound[rid] if b.status == "unobservable" and b.component in model.extra}
        sensors[rid] = SensorModel(tuple(c for c in model.components if c.name not in drop))
    return attrs.evolve(config, sensors=sensors) if any(
        sensors[r] != config.sensor(r) for r in radar_ids) else config


def _truth_states(paths: TruthPaths, keys: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Truth [x, y, vx, vy] at each measurement (NaN outside its truth)."""
    out = np.full((len(times), 4), np.nan)
    for key in set(keys.tolist()):
        idx = np.flatnonzero(keys == key)
        state, inside = paths.state_at(str(key), times[idx])
        out[idx[inside]] = state[inside]
    return out


def _report(biases: dict[str, BiasState], bound: dict[str, list[ComponentBound]],
            truth: dict[str, dict[str, float]]) -> list[ComponentReport]:
    rows = []
    for rid, state in biases.items():
        for cb in bound[rid]:  # a component left out: its prior, N(0, σ²)
            value, sd = state.component(cb.component) if cb.component in state.components else (0.0, cb.prior_sd)
            rows.append(ComponentReport(rid, cb.component, value, sd, cb.sd, cb.status,
                                        truth.get(rid, {}).get(cb.component, math.nan)))
    return rows


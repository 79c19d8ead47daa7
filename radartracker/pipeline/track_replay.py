"""Replay a scenario through the TrackManager (no truth association) and evaluate it.

Used by ``radartracker replay`` when the plots carry no truth label (or with ``--manager``).
Writes the same ``tracks.csv``, ``biases.csv`` and ``summary.json`` as the labelled replay plus
``events.csv``; with truth, ``summary.json`` gains continuity, swaps, breaks, false tracks, RMSE and
GOSPA (:func:`radartracker.evaluate.track_metrics`), and ``--plots`` draws tracks over truth.
"""

from __future__ import annotations

import json
import math
import time as _time
from pathlib import Path

import attrs
import numpy as np
from tqdm import tqdm

from radartracker.domain import AdsbReport, Plot
from radartracker.pipeline.evaluate import TrackHistory, TruthPaths, track_metrics
from radartracker.io.tables import ScenarioData
from radartracker.tracking.manager import ManagerConfig, TrackEvent, TrackManager


def scenario_items(data: ScenarioData) -> list[Plot | AdsbReport]:
    """The scenario's plots and ADS-B reports as domain objects, in time order (plots first at ties)."""
    p, a = data.plots, data.adsb
    items: list = [Plot(float(p.time[i]), p.radar[i], float(p.range_m[i]), float(p.azimuth_rad[i]),
                        None if math.isnan(p.altitude_m[i]) else float(p.altitude_m[i]), p.mode_s[i], p.mode_3a[i],
                        p.target[i]) for i in range(len(p))]
    items += [AdsbReport(float(a.time[i]), a.icao24[i], float(a.lat[i]), float(a.lon[i]),
                         None if math.isnan(a.altitude_m[i]) else float(a.altitude_m[i]), int(a.nacp[i]))
              for i in range(len(a))]
    items.sort(key=lambda x: x.time)
    return items


@attrs.define
class TrackReplayResult:
    """Events, bias history and counts of a TrackManager replay."""

    data: ScenarioData
    manager: TrackManager
    events: list[TrackEvent]
    bias_log: list[tuple[float, str, np.ndarray, np.ndarray]]
    seconds: float

    def histories(self) -> dict[int, TrackHistory]:
        """Each confirmed track's reported states from its events."""
        rows: dict[int, list[TrackEvent]] = {}
        for e in self.events:
            rows.setdefault(e.track, []).append(e)
        out = {}
        for tid, evs in rows.items():
            rep = [e for e in evs if e.kind in ("confirmed", "updated", "coasting")]
            if not rep:
                continue
            end = next((e.time for e in evs if e.kind == "deleted"), rep[-1].time)
            out[tid] = TrackHistory(np.array([e.time for e in rep]), np.array([e.state for e in rep]), rep[0].time, end)
        return out

    def evaluation(self, step_s: float = 2.0, grace_s: float = 20.0) -> dict | None:
        """Track metrics against the truth (``None`` without truth).

        A target counts as observed from ``grace_s`` after its first labelled plot (the time
        M-of-N confirmation needs) to its last labelled plot.
        """
        d = self.data
        if d.truth is None:
            return None
        labelled = np.array([t is not None for t in d.plots.target])
        observed = {}
        for tg in np.unique(d.plots.target[labelled].astype(str)):
            t = d.plots.time[d.plots.target == tg]
            if t.max() - t.min() > grace_s:
                observed[tg] = (float(t.min()) + grace_s, float(t.max()))
        paths = TruthPaths.from_table(d.truth, self.manager.plane)
        grid = np.arange(d.truth.time.min(), d.truth.time.max(), step_s)
        return track_metrics(self.histories(), paths, observed, grid)

    def summary(self) -> dict:
        est = self.manager.estimator
        out = {
            "scenario": self.data.name, "estimator": self.manager.config.estimator,
            "motion_model": self.manager.config.motion_model, "association": "track manager",
            "counts": self.manager.accounting(), "skipped_input_rows": dict(self.data.skipped),
            "seconds": self.seconds, "biases": {},
            "observability": self.manager.coupling.report(),
        }
        truth_b = self.data.truth_biases or {}
        for rid in est.radars:
            b = est.bias(rid)
            entry = {"range_bias_m": b.range_m, "azimuth_bias_deg": math.degrees(b.azimuth_rad),
                     "sd_range_m": b.sd_range_m, "sd_azimuth_deg": math.degrees(b.sd_azimuth_rad)}
            if rid in truth_b:
                entry.update({"true_range_bias_m": truth_b[rid][0], "true_azimuth_bias_deg": math.degrees(truth_b[rid][1])})
            out["biases"][rid] = entry
        ev = self.evaluation()
        if ev is not None:
            out["tracking"] = {k: v for k, v in ev.items() if k != "gospa"}
        return out


def track_replay(data: ScenarioData, config: ManagerConfig | None = None) -> TrackReplayResult:
    """Run the TrackManager over ``data``."""
    mgr = TrackManager(data.radars, data.reference, config)
    items = scenario_items(data)
    events: list[TrackEvent] = []
    bias_log, last_logged = [], {}
    started = _time.perf_counter()
    for item in tqdm(items, desc="track replay", unit="item", delay=2.0, mininterval=1.0):
        events.extend(mgr.process(item))
        rid = getattr(item, "radar", None)
        if rid is not None and item.time - last_logged.get(rid, -math.inf) >= 1.0:
            b = mgr.estimator.bias(rid)
            bias_log.append((item.time, rid, b.bias, b.cov))
            last_logged[rid] = item.time
    events.extend(mgr.flush())
    return TrackReplayResult(data, mgr, events, bias_log, _time.perf_counter() - started)


def write_track_outputs(result: TrackReplayResult, out: Path | str, *, figures: bool = False) -> None:
    """tracks.csv, events.csv, biases.csv, summary.json, coupling.graphml (and figures) in ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    plane = result.manager.plane
    ev = result.events
    xy = np.array([e.state[:2] for e in ev]).reshape(-1, 2)
    lat, lon = plane.to_geodetic(xy[:, 0], xy[:, 1]) if len(ev) else (np.empty(0), np.empty(0))
    with (out / "events.csv").open("w") as f:
        f.write("time,track,event,status,lat,lon,x_m,y_m,vx_mps,vy_mps\n")
        for e, la, lo in zip(ev, lat, lon):
            f.write(f"{e.time:.3f},{e.track},{e.kind},{e.status},{la:.8f},{lo:.8f},{e.state[0]:.2f},{e.state[1]:.2f},"
                    f"{e.state[2]:.3f},{e.state[3]:.3f}\n")
    with (out / "tracks.csv").open("w") as f:
        f.write("time,track,lat,lon,x_m,y_m,vx_mps,vy_mps,sd_x_m,sd_y_m\n")
        for e, la, lo in zip(ev, lat, lon):
            if e.kind in ("confirmed", "updated"):
                f.write(f"{e.time:.3f},{e.track},{la:.8f},{lo:.8f},{e.state[0]:.2f},{e.state[1]:.2f},"
                        f"{e.state[2]:.3f},{e.state[3]:.3f},,\n")
    with (out / "biases.csv").open("w") as f:
        f.write("time,radar,range_bias_m,azimuth_bias_deg,sd_range_m,sd_azimuth_deg\n")
        for t, rid, b, P in result.bias_log:
            f.write(f"{t:.3f},{rid},{b[0]:.3f},{math.degrees(b[1]):.6f},{math.sqrt(P[0, 0]):.3f},"
                    f"{math.degrees(math.sqrt(P[1, 1])):.6f}\n")
    (out / "summary.json").write_text(json.dumps(result.summary(), indent=1))
    result.manager.coupling.write_graphml(out / "coupling.graphml")
    if figures:
        from radartracker.pipeline.figures import plot_tracks_over_truth

        plot_tracks_over_truth(result, out / "tracks.png")

"""Gross errors injected into the built-in ``paris`` scenario, screening off and on (issue 12).

Faults, each at the given rate of its population (independently drawn): radar plots with +20 km
range; ADS-B reports moved 1° north; plots whose Mode S address is swapped for another aircraft's;
duplicated inputs (any kind, delivered twice in a row); and one plot whose time stamp is 10 years
ahead (kept at its place in the stream, as a bad clock delivers it). The stream goes through the
TrackManager; printed as JSON lines: every radar's final bias error and z-score, position RMSE,
breaks and false tracks (radartracker.pipeline.evaluate.track_metrics), and the input counts.
"Screening off" disables innovation screening, ADS-B plausibility and the robust clock.

``--measure-gates`` instead prints the normalised innovations d² of clean runs per scenario, motion
model and measurement kind (with how many the default gates reject), and those of the gross errors
— the table the default gates were chosen from (docs/reliability.md, "Gross errors").

Usage: python scripts/fault_injection.py [--duration 1200] [--rates 0.001 0.01 0.05] [--seed 1]
       python scripts/fault_injection.py --measure-gates [--duration 1200]
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import time

import attrs
import numpy as np

from radartracker.registry import make_manager
from radartracker.tracking.events import ENDS
from radartracker.domain import AdsbReport, Plot
from radartracker.estimation.screening import ScreeningConfig
from radartracker.io.tables import ScenarioData
from radartracker.pipeline.evaluate import TrackHistory, TruthPaths, track_metrics
from radartracker.simulation.scenarios import build_scenario
from radartracker.clock import ClockConfig
from radartracker.tracking.config import ManagerConfig
from radartracker.tracking.manager import TrackManager

YEARS_10 = 10 * 365.25 * 86400.0
OFF = dict(screening=ScreeningConfig(enabled=False), clock=ClockConfig(max_ahead_s=math.inf))


def clean_items(data: ScenarioData) -> list[Plot | AdsbReport]:
    """The scenario's plots and ADS-B reports as domain objects in time order (plots first at ties)."""
    p, a = data.plots, data.adsb
    items: list = [Plot(float(p.time[i]), p.radar[i], float(p.range_m[i]), float(p.azimuth_rad[i]),
                        None if math.isnan(p.altitude_m[i]) else float(p.altitude_m[i]), p.mode_s[i], p.mode_3a[i],
                        p.target[i]) for i in range(len(p))]
    items += [AdsbReport(float(a.time[i]), a.icao24[i], float(a.lat[i]), float(a.lon[i]),
                         None if math.isnan(a.altitude_m[i]) else float(a.altitude_m[i]), int(a.nacp[i]))
              for i in range(len(a))]
    items.sort(key=lambda x: (x.time, isinstance(x, AdsbReport)))
    return items


def inject(items: list, rate: float, rng: np.random.Generator) -> tuple[list, dict[str, int]]:
    """A copy of ``items`` with gross errors at ``rate`` per fault type, and how many of each."""
    out = list(items)
    plots = [i for i, x in enumerate(out) if isinstance(x, Plot)]
    adsb = [i for i, x in enumerate(out) if isinstance(x, AdsbReport)]
    codes = sorted({x.mode_s for x in out if isinstance(x, Plot) and x.mode_s})

    def pick(pop: list[int]) -> list[int]:
        return [pop[k] for k in np.flatnonzero(rng.random(len(pop)) < rate)]

    n = {}
    chosen = pick(plots)
    for i in chosen:
        out[i] = attrs.evolve(out[i], range_m=out[i].range_m + 20_000.0)
    n["range_20km"] = len(chosen)
    chosen = pick(adsb)
    for i in chosen:
        out[i] = attrs.evolve(out[i], lat=min(out[i].lat + 1.0, 90.0))
    n["adsb_1deg"] = len(chosen)
    chosen = [i for i in pick(plots) if out[i].mode_s]
    for i in chosen:
        out[i] = attrs.evolve(out[i], mode_s=str(rng.choice([c for c in codes if c != out[i].mode_s])))
    n["mode_s_swapped"] = len(chosen)
    k = plots[len(plots) // 3]
    out[k] = attrs.evolve(out[k], time=out[k].time + YEARS_10)
    n["time_10_years_ahead"] = 1
    dup = set(pick(list(range(len(out)))))
    n["duplicated"] = len(dup)
    return [x for i, item in enumerate(out) for x in ((item, item) if i in dup else (item,))], n


def run(data: ScenarioData, items: list, config: ManagerConfig) -> tuple[TrackManager, list]:
    mgr = make_manager(data.radars, data.reference, config)
    events = []
    for item in items:
        events.extend(mgr.process(item))
    events.extend(mgr.flush())
    return mgr, events


def tracking(data: ScenarioData, mgr: TrackManager, events: list, grace_s: float = 20.0) -> dict:
    """Track metrics against the truth (as the track replay evaluates them)."""
    rows: dict[int, list] = {}
    for e in events:
        rows.setdefault(e.track, []).append(e)
    hist = {}
    for tid, evs in rows.items():
        rep = [e for e in evs if e.kind in ("confirmed", "updated", "coasting")]
        if rep:
            end = next((e.time for e in evs if e.kind in ENDS), rep[-1].time)
            hist[tid] = TrackHistory(np.array([e.time for e in rep]), np.array([e.state for e in rep]),
                                     rep[0].time, end)
    observed = {}
    for tg in np.unique(data.plots.target[data.plots.target != None].astype(str)):  # noqa: E711
        t = data.plots.time[data.plots.target == tg]
        if t.max() - t.min() > grace_s:
            observed[tg] = (float(t.min()) + grace_s, float(t.max()))
    grid = np.arange(data.truth.time.min(), data.truth.time.max(), 2.0)
    return track_metrics(hist, TruthPaths.from_table(data.truth, mgr.plane), observed, grid)


def report(data: ScenarioData, mgr: TrackManager, events: list) -> dict:
    out: dict = {"biases": {}}
    for rid, (tr, ta) in data.truth_biases.items():
        b = mgr.estimator.bias(rid)
        er, ea = b.bias[0] - tr, b.bias[1] - ta
        out["biases"][rid] = {"err_range_m": round(float(er), 2),
                              "z_range": round(float(er / math.sqrt(b.cov[0, 0])), 2),
                              "err_azimuth_deg": round(math.degrees(ea), 5),
                              "z_azimuth": round(float(ea / math.sqrt(b.cov[1, 1])), 2)}
    m = tracking(data, mgr, events)
    out.update(position_rmse_m=round(m["position_rmse_m"], 1), breaks=m["breaks"], false_tracks=m["false_tracks"],
               confirmed_tracks=m["confirmed_tracks"], counts=mgr.accounting())
    return out


def measure_gates(args: argparse.Namespace, base: ManagerConfig) -> None:
    """d² of every screened measurement in clean runs and how many the default gates reject; the
    gross errors' d²."""
    import radartracker.tracking.lifecycle as lifecycle

    seen: list[tuple[str, float, object]] = []  # (kind, d², the measurement's source item)
    current: list = [None]
    real_judge, real_apply = lifecycle.judge, lifecycle.TrackLifecycle.apply

    def recording_judge(config, kind, d2, *args, **kwargs):
        seen.append((kind, d2, current[0]))
        return real_judge(config, kind, d2, *args, **kwargs)

    def recording_apply(self, update, meas):
        current[0] = update.source
        return real_apply(self, update, meas)

    lifecycle.judge = recording_judge  # the life cycle's screening verdict, recorded with its d²
    lifecycle.TrackLifecycle.apply = recording_apply
    for name in args.scenarios:
        data = build_scenario(name, seed=args.seed, duration=args.duration).run()
        for model in args.models:
            seen.clear()
            mgr, _ = run(data, clean_items(data), attrs.evolve(base, motion_model=model))
            counts = mgr.accounting()
            for kind in ("plots", "adsb"):
                d = np.array([v for k, v, _ in seen if k == kind])
                if len(d):
                    q = np.quantile(d, [0.5, 0.99, 0.999, 0.9999])
                    print(json.dumps({"scenario": name, "motion_model": model, "kind": kind, "n": len(d),
                                      "mean": round(float(d.mean()), 2), "median": round(float(q[0]), 2),
                                      "q99": round(float(q[1]), 1), "q999": round(float(q[2]), 1),
                                      "q9999": round(float(q[3]), 1), "max": round(float(d.max()), 1),
                                      "rejected": counts.get(f"{kind}_outlier", 0),
                                      "tracks_reinitialised": mgr.track_counts().get("tracks_reinitialised", 0)}))
    # the gross errors' d² against healthy tracks: a run screened with the default gates, recording
    # the d² of each injected measurement by the fault it carries
    data = build_scenario("paris", seed=args.seed, duration=args.duration).run()
    clean = clean_items(data)
    faulty, _ = inject(clean, 0.01, np.random.default_rng(args.seed))
    def key(x, dr=0.0):  # values, not identity: the manager hands on converted copies of plots
        return (x.time, x.icao24, x.lat, x.lon) if isinstance(x, AdsbReport) else (
            x.time, x.radar, x.range_m - dr, x.azimuth_rad, x.mode_s)

    originals = {key(x) for x in clean}
    seen.clear()
    run(data, faulty, base)
    by_fault: dict[str, list[float]] = {}
    for _, d2, src in seen:
        if key(src) not in originals:
            fault = ("adsb_1deg" if isinstance(src, AdsbReport) else
                     "range_20km" if key(src, 20_000.0) in originals else "mode_s_swapped")
            by_fault.setdefault(fault, []).append(d2)
    for fault, d in sorted(by_fault.items()):
        d = np.array(d)
        print(json.dumps({"scenario": "paris, 1 % gross errors", "fault": fault, "n_screened": len(d),
                          "min": round(float(d.min()), 1), "q01": round(float(np.quantile(d, 0.01)), 1),
                          "median": round(float(np.median(d)), 1)}))


def markdown(rows: list[dict]) -> str:
    """The rows as the Markdown table of docs/reliability.md."""
    radars = list(rows[0]["biases"])
    head = ["rate", "screening", *[f"{r} Δr err m (z) / Δθ err mdeg (z)" for r in radars], "position RMSE m",
            "breaks", "false tracks", "rejected (outlier / implausible ADS-B / time jump)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        c = row["counts"]
        cells = [f"{row['rate'] * 100:g} %", row["screening"]]
        for r in radars:
            b = row["biases"][r]
            cells.append(f"{b['err_range_m']:.1f} ({b['z_range']:.1f}) / "
                         f"{b['err_azimuth_deg'] * 1e3:.1f} ({b['z_azimuth']:.1f})")
        cells += [f"{row['position_rmse_m']:.1f}", str(row["breaks"]), str(row["false_tracks"]),
                  f"{c.get('plots_outlier', 0) + c.get('adsb_outlier', 0)} / {c.get('adsb_implausible_speed', 0)} / "
                  f"{c.get('plots_time_jump', 0) + c.get('adsb_time_jump', 0)}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=1200.0, help="scenario seconds (paris: 3600 in full)")
    ap.add_argument("--rates", type=float, nargs="+", default=[0.001, 0.01, 0.05])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--estimator", default="coupled-sparse")
    ap.add_argument("--models", nargs="+", default=["cv", "imm"], help="motion models for --measure-gates")
    ap.add_argument("--scenarios", nargs="*", default=["paris", "manoeuvres", "tracking", "demo"],
                    help="clean scenarios for --measure-gates")
    ap.add_argument("--measure-gates", action="store_true")
    args = ap.parse_args()
    logging.disable(logging.WARNING)
    base = ManagerConfig(estimator=args.estimator)
    if args.measure_gates:
        measure_gates(args, base)
        return
    data = build_scenario("paris", seed=args.seed, duration=args.duration).run()
    items = clean_items(data)
    rows = []
    for rate in [0.0, *args.rates]:
        rng = np.random.default_rng([args.seed, int(rate * 1e4)])
        faulty, injected = inject(items, rate, rng) if rate else (items, {})
        for screening in ("off", "on"):
            started = time.perf_counter()
            cfg = attrs.evolve(base, **OFF) if screening == "off" else base
            mgr, events = run(data, faulty, cfg)
            row = {"rate": rate, "screening": screening, "injected": injected, **report(data, mgr, events),
                   "seconds": round(time.perf_counter() - started, 1)}
            print(json.dumps(row), flush=True)
            rows.append(row)
    print()
    print(markdown(rows))


if __name__ == "__main__":
    main()

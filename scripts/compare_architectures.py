"""Central (plot-level) against distributed (track-to-track) fusion on the same simulated inputs.

Each built-in scenario (``demo``, ``seed``, ``manoeuvres``, ``paris`` — shortened to ``--duration``
seconds so the comparison fits a shared 2-core machine) and real flight-inspection flights from
``../shared/data/real_flights.csv.gz`` (OpenSky Network; each flown through three *biased* radars around
it, ADS-B on, first ``--flight-s`` seconds) is replayed twice with the same TrackManager, motion model,
estimator and screening: ``--architecture central --association manager`` and ``--architecture
distributed``. Per run: position RMSE of the track estimates against the truth, continuity (min over
aircraft), breaks, swaps, false tracks, bias error and z of every radar, bias standard deviation, and
CPU seconds per input (plot or ADS-B report; the machine is shared, so absolute times are loaded ones).

Prints one JSON line per run, writes the Markdown table into ``docs/fusion.md`` between its markers and
the figure ``docs/figures/fusion_comparison.png``::

    python scripts/compare_architectures.py [--duration 600] [--flights N] [--no-doc]
    python scripts/compare_architectures.py --sweep 300   # the FusionConfig table (one setting at a time)
"""

from __future__ import annotations

import argparse
import json
import math
import re
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from radartracker.domain import Aircraft, Radar  # noqa: E402
from radartracker.geometry.plane import SystemPlane  # noqa: E402
from radartracker.io.tables import ScenarioData  # noqa: E402
from radartracker.pipeline.config import RunConfig  # noqa: E402
from radartracker.pipeline.run import run  # noqa: E402
from radartracker.simulation.flights import load_flights  # noqa: E402
from radartracker.simulation.scenarios import build_scenario  # noqa: E402
from radartracker.simulation.simulator import RecordedTrajectory, SimAircraft, SimRadar, Simulator  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FULL = ROOT.parent / "shared" / "data" / "real_flights.csv.gz"
DOC = ROOT / "docs" / "fusion.md"
FIG = ROOT / "docs" / "figures" / "fusion_comparison.png"
SCENARIOS = ("demo", "seed", "manoeuvres", "paris")
ARCHS = ("central", "distributed")
# real flights: three radars around the flight's centroid, with the seed's biases (Δr m, Δθ °)
RADARS = [("T4", -20.0, -15.0, 4.0, 120.0, 0.15), ("E8", 40.0, 10.0, 8.0, -80.0, -0.10),
          ("E12", -10.0, 45.0, 12.0, 60.0, 0.20)]


def flight_scenario(fid: str, f, seed: int, seconds: float) -> ScenarioData:
    ref = (float(np.mean(f.lat)), float(np.mean(f.lon)))
    plane = SystemPlane(*ref)
    radars = []
    for rid, x_km, y_km, period, dr, da in RADARS:
        lat, lon = plane.to_geodetic(x_km * 1e3, y_km * 1e3)
        radars.append(SimRadar(Radar(rid, float(lat), float(lon), 100.0, 70.0, math.radians(0.08), period, 250e3),
                               dr, math.radians(da), pd=0.9))
    traj = RecordedTrajectory.from_geodetic(plane, f.time, f.lat, f.lon, f.altitude_m)
    ac = Aircraft(f.icao24, fid[:8], "1000", adsb=True, nacp=8)
    t0 = float(f.time[0])
    return Simulator(ref, radars, [SimAircraft(ac, traj)], t0, min(float(f.time[-1]), t0 + seconds),
                     seed=seed, name=fid).run()


def measure(data: ScenarioData, arch: str, fusion: dict | None = None) -> dict:
    cfg = RunConfig(architecture=arch, association="manager", fusion=fusion or {})
    cpu = time.process_time()
    res = run(data, cfg, progress=False)
    cpu = time.process_time() - cpu
    s = res.summary()
    b = s["biases"].values()
    tr = s["tracking"]
    return {
        "inputs": len(data.plots) + len(data.adsb),
        "rmse_m": s["truth"]["position_rmse_m"], "n_rmse": s["truth"]["estimates_compared"],
        "continuity_min": tr["continuity_min"], "breaks": tr["breaks"], "swaps": tr["swaps"],
        "false_tracks": tr["false_tracks"], "aircraft": len(tr["per_target"]),
        "bias_err_range_m": [abs(x["error_range_m"]) for x in b],
        "bias_err_az_deg": [abs(x["error_azimuth_deg"]) for x in b],
        "bias_sd_range_m": [x["sd_range_m"] for x in b], "bias_sd_az_deg": [x["sd_azimuth_deg"] for x in b],
        "bias_z": [max(abs(x["z_range"]), abs(x["z_azimuth"])) for x in b],
        "cpu_s": cpu, "us_per_input": 1e6 * cpu / max(len(data.plots) + len(data.adsb), 1),
        "mean_nees": s["consistency"]["mean_nees"],
    }


# one FusionConfig setting changed at a time from its default
SWEEP = [({}, "defaults"), ({"period_s": 1.0}, "period_s 1"), ({"period_s": 4.0}, "period_s 4"),
         ({"bias_every_s": 4.0}, "bias_every_s 4"), ({"bias_every_s": 30.0}, "bias_every_s 30"),
         ({"r_inflation": 1.0}, "r_inflation 1"), ({"r_inflation": 4.0}, "r_inflation 4")]


def sweep(duration: float, seed: int) -> str:
    """The fusion settings, one at a time, on demo and manoeuvres: the table that backs the defaults."""
    lines = ["| setting | " + " | ".join(f"{n}: RMSE m / range-bias sd m / max \\|z\\| / NEES" for n in ("demo", "manoeuvres"))
             + " |", "|---|---|---|"]
    datas = {n: build_scenario(n, seed=seed, duration=duration).run() for n in ("demo", "manoeuvres")}
    for change, label in SWEEP:
        cells = []
        for name, data in datas.items():
            r = measure(data, "distributed", change)
            print(json.dumps({"sweep": label, "scenario": name, **r}), flush=True)
            cells.append(f"{r['rmse_m']:.1f} / {np.mean(r['bias_sd_range_m']):.1f} / {max(r['bias_z']):.2f} / "
                         f"{r['mean_nees']:.2f}")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def pooled(rows: list[dict]) -> dict:
    """Several runs (the real flights) as one: RMSE pooled over estimates, counts summed, lists joined."""
    n = sum(r["n_rmse"] for r in rows)
    out = {"rmse_m": math.sqrt(sum(r["rmse_m"] ** 2 * r["n_rmse"] for r in rows) / max(n, 1)), "n_rmse": n,
           "continuity_min": min(r["continuity_min"] for r in rows)}
    for k in ("inputs", "breaks", "swaps", "false_tracks", "aircraft", "cpu_s"):
        out[k] = sum(r[k] for r in rows)
    for k in ("bias_err_range_m", "bias_err_az_deg", "bias_sd_range_m", "bias_sd_az_deg", "bias_z"):
        out[k] = [v for r in rows for v in r[k]]
    out["us_per_input"] = 1e6 * out["cpu_s"] / max(out["inputs"], 1)
    return out


def table(results: dict, durations: dict) -> str:
    lines = ["| scenario (s simulated) | architecture | position RMSE m | continuity min | breaks | swaps | "
             "false tracks | mean \\|bias error\\| range m / az ° | mean bias sd range m / az ° | max \\|z\\| | "
             "µs CPU per input |", "|" + "---|" * 11]
    for (name, arch), r in results.items():
        lines.append(
            f"| {name} ({durations[name]}) | {arch} | {r['rmse_m']:.1f} | {r['continuity_min']:.2f} | {r['breaks']} | "
            f"{r['swaps']} | {r['false_tracks']} | {np.mean(r['bias_err_range_m']):.1f} / "
            f"{np.mean(r['bias_err_az_deg']):.3f} | {np.mean(r['bias_sd_range_m']):.1f} / "
            f"{np.mean(r['bias_sd_az_deg']):.3f} | {max(r['bias_z']):.2f} | {r['us_per_input']:.0f} |")
    return "\n".join(lines)


def figure(results: dict, path: Path) -> None:
    names = list(dict.fromkeys(n for n, _ in results))
    panels = [("position RMSE (m)", lambda r: r["rmse_m"]),
              ("mean |range bias error| (m)", lambda r: np.mean(r["bias_err_range_m"])),
              ("mean range-bias sd (m)", lambda r: np.mean(r["bias_sd_range_m"])),
              ("µs CPU per input (loaded machine)", lambda r: r["us_per_input"])]
    fig, axes = plt.subplots(1, len(panels), figsize=(16, 3.8))
    x = np.arange(len(names))
    for ax, (title, get) in zip(axes, panels):
        for k, arch in enumerate(ARCHS):
            ax.bar(x + (k - 0.5) * 0.38, [get(results[(n, arch)]) for n in names], 0.38, label=arch)
        ax.set_xticks(x, names, rotation=30, ha="right")
        ax.set_title(title, fontsize=10)
    axes[0].legend()
    fig.suptitle("Central (plot-level) vs distributed (track-to-track, covariance intersection) fusion")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--duration", type=float, default=600.0, help="simulated seconds of each built-in scenario")
    ap.add_argument("--flights", type=int, default=4, help="real flight-inspection flights (cal_* in the data)")
    ap.add_argument("--flight-s", type=float, default=900.0, help="simulated seconds of each real flight")
    ap.add_argument("--data", default=str(FULL), help="real_flights.csv.gz-style file")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-doc", action="store_true", help="print only; leave docs/ untouched")
    ap.add_argument("--sweep", type=float, default=None, metavar="SECONDS",
                    help="instead: the FusionConfig settings one at a time on demo and manoeuvres of SECONDS")
    args = ap.parse_args()
    if args.sweep is not None:
        md = sweep(args.sweep, args.seed)
        print(md)
        if not args.no_doc:
            text = re.sub(r"(<!-- sweep:begin -->\n).*?(<!-- sweep:end -->)",
                          lambda m: m.group(1) + md + "\n" + m.group(2), DOC.read_text(), flags=re.S)
            DOC.write_text(text)
        return
    results, durations = {}, {}
    for name in SCENARIOS:
        data = build_scenario(name, seed=args.seed, duration=args.duration).run()
        durations[name] = f"{args.duration:g}"
        for arch in ARCHS:
            results[(name, arch)] = r = measure(data, arch)
            print(json.dumps({"scenario": name, "architecture": arch, **r}), flush=True)
    if args.flights and Path(args.data).exists():
        flights = load_flights(args.data)
        cal = sorted(k for k in flights if k.startswith("cal_"))[: args.flights]
        runs = {arch: [] for arch in ARCHS}
        for i, fid in enumerate(cal):
            data = flight_scenario(fid, flights[fid], args.seed + i, args.flight_s)
            for arch in ARCHS:
                runs[arch].append(measure(data, arch))
                print(json.dumps({"scenario": fid, "architecture": arch, **runs[arch][-1]}), flush=True)
        name = f"{len(cal)} real flights"
        durations[name] = f"{len(cal)}×{args.flight_s:g}"
        for arch in ARCHS:
            results[(name, arch)] = pooled(runs[arch])
    md = table(results, durations)
    print(md)
    if not args.no_doc:
        text = DOC.read_text()
        text = re.sub(r"(<!-- architectures:begin -->\n).*?(<!-- architectures:end -->)",
                      lambda m: m.group(1) + md + "\n" + m.group(2), text, flags=re.S)
        DOC.write_text(text)
        figure(results, FIG)


if __name__ == "__main__":
    main()

"""CPU cost of the track-filter side of each measurement in the TrackManager, against the compiled kernels alone.

    python scripts/bench_filter_side.py [FOLDER] [--repeat 5]

FOLDER is a scenario folder replayed as ``radartracker replay FOLDER --manager`` does (default: simulated
traffic, 200 aircraft × 28 radars × 3 minutes; the default ``imm`` motion model). The calls the manager
makes on this side are recorded, then replayed on new filters in two ways, after a warm-up:

* ``filter_side``: what the TrackManager does on this side — each frame's ADS-B plausibility checks
  (``check_many``), its measurements of confirmed tracks in one ``TrackFilter.screen_many``, the others'
  ``screen`` (bias correction, prediction, d² and the update in the gate), ``judge`` (the screening run),
  the ``estimate()`` reads, the Mode C altitude filter, and the track starts;
* ``kernels``: the screening calls alone on the same arrays (``screen_many`` with its compiled loop, the
  compiled ``imm_screen`` of the others) and the same starts.

Both replays alternate, so a changing load on a shared machine hits both alike. One JSON line per repeat:
CPU µs per measurement (``time.process_time``) of each, their difference, the ``screen_many`` calls' share
of ``filter_side`` per measurement they screen (``screen_many_us``: at light traffic a frame's fixed cost
shows there), and whether both end with the same filter states (bit for bit; the nan of a buffer's "none"
equal to nan).
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np


def record(folder: str | None) -> tuple[list, object, object, int]:
    """The manager's filter-side calls in order, its screening and motion settings, and the number of inputs."""
    from radartracker.estimation import screening
    from radartracker.pipeline.config import RunConfig, resolve
    from radartracker.pipeline.run import motion_factory
    from radartracker.pipeline.stream import iter_files, iter_scenario
    from radartracker.tracking import manager as manager_module
    from radartracker.tracking.association import AltitudeTrack

    if folder is None:
        from radartracker.simulation.traffic import traffic_scenario
        data = traffic_scenario(seed=1, duration=180.0, aircraft=200, radars=28).run()
        items = list(iter_scenario(data))
    else:
        from radartracker.io.scenario import open_scenario
        files = open_scenario(folder)
        data, items = files.data, list(iter_files(files))
    cfg = resolve(RunConfig(association="manager"), data, "coupled-sparse")  # simulated traffic is labelled
    factory = motion_factory(cfg)
    cls = type(factory())
    if "screen" not in vars(cls) or not getattr(factory(), "_compiled", False):
        raise SystemExit("the kernel replay needs the built-in imm motion model with its compiled modes")
    ops: list[tuple] = []
    ids: dict[int, int] = {}

    def key(obj: object) -> int:
        return ids.setdefault(id(obj), len(ids))

    def copy(a):
        return np.array(a, float)

    saved = [(cls, "start"), (cls, "screen"), (cls, "update"), (cls, "estimate"),
             (screening.AdsbPlausibility, "check_many"), (AltitudeTrack, "update"), (manager_module, "judge")]
    originals = {(owner, name): owner.__dict__[name] for owner, name in saved}
    logged = {"start": lambda s, a: ("start", key(s), float(a[0]), copy(a[1]), copy(a[2])),
              "screen": lambda s, a: ("screen", key(s), float(a[0]), *map(copy, a[1:6]), a[6] if len(a) > 6 else None),
              "update": lambda s, a: ("update", key(s), float(a[0]), copy(a[1]), copy(a[2])),
              "estimate": lambda s, a: ("estimate", key(s)),
              "check_many": lambda s, a: ("adsb", list(a[0]), *map(copy, a[1:4]), np.array(a[4])),
              }

    def logging(owner, name):
        f = originals[(owner, name)]
        tag = "alt_update" if owner is AltitudeTrack else name

        def call(self, *a):
            out = f(self, *a)
            ops.append(logged[name](self, a) if tag != "alt_update" else ("alt_update", key(self), float(a[0]),
                                                                            float(a[1])))
            return out
        return call

    def judge(config, kind, d2, run, identified, tentative, t, z, R):
        ops.append(("judge", kind, identified, tentative))
        return originals[(manager_module, "judge")](config, kind, d2, run, identified, tentative, t, z, R)

    alt_start = AltitudeTrack.__dict__["start"].__func__
    many = cls.__dict__["screen_many"].__func__

    def screen_many(c, filters, *a):  # logged before the call: it changes the filters
        ops.append(("screen_many", [key(f) for f in filters], *map(copy, a)))
        return many(c, filters, *a)

    try:
        cls.screen_many = classmethod(screen_many)
        for owner, name in saved[:-1]:
            setattr(owner, name, logging(owner, name))
        manager_module.judge = judge
        AltitudeTrack.start = classmethod(lambda c, t, h: (lambda r: (ops.append(("alt_start", key(r), t, h)), r)[1])(
            alt_start(c, t, h)))
        mgr = manager_module.TrackManager(data.radars, data.reference, cfg.manager_settings(), None,
                                          filter_factory=factory)
        for item in items:
            mgr.process(item)
        mgr.flush()
    finally:
        for (owner, name), f in originals.items():
            setattr(owner, name, f)
        AltitudeTrack.start = classmethod(alt_start)
        cls.screen_many = classmethod(many)
    return ops, cfg.manager_settings().screening, factory, len(items)


def filter_side(ops: list, config, factory) -> tuple[float, float, dict]:
    """Replay the filter side as the manager runs it; (CPU seconds, of which in screen_many, filters by key)."""
    from radartracker.estimation.screening import AdsbPlausibility, judge
    from radartracker.tracking.association import AltitudeTrack

    filters, altitude, runs, last, many = {}, {}, {}, None, 0.0
    adsb = AdsbPlausibility(config)
    c0 = time.process_time()
    for op in ops:
        kind = op[0]
        if kind == "screen_many":
            batch = [filters[k] for k in op[1]]
            c = time.process_time()
            type(batch[0]).screen_many(batch, *op[2:])
            many += time.process_time() - c
        elif kind == "screen":
            _, f, t, z, C, R, bias, bias_cov, gate = op
            d2, zc, Rc, _ = filters[f].screen(t, z, C, R, bias, bias_cov, gate)
            last = (f, d2, t, zc, Rc)
        elif kind == "judge":
            f, d2, t, zc, Rc = last
            runs[f] = judge(config, op[1], d2, runs.get(f, []), op[2], op[3], t, zc, Rc)[1]
        elif kind == "update":
            _, f, t, z, R = op
            filters[f].update(t, z, R)
        elif kind == "estimate":
            filters[op[1]].estimate()
        elif kind == "adsb":
            adsb.check_many(*op[1:])
        elif kind == "alt_update":
            altitude[op[1]].update(op[2], op[3])
        elif kind == "alt_start":
            altitude[op[1]] = AltitudeTrack.start(op[2], op[3])
        elif kind == "start":
            filters[op[1]] = factory()
            filters[op[1]].start(*op[2:])
    return time.process_time() - c0, many, filters


def kernels_alone(ops: list, factory) -> tuple[float, dict]:
    """Replay only the compiled screening calls (and the starts, and updates not made in screening)."""
    from radartracker.api import kernels

    filters, zc, Rc = {}, np.empty(2), np.empty((2, 2))
    c0 = time.process_time()
    for op in ops:
        kind = op[0]
        if kind == "screen_many":
            type(filters[op[1][0]]).screen_many([filters[k] for k in op[1]], *op[2:])
        elif kind == "screen":
            _, f, t, z, C, R, bias, bias_cov, gate = op
            flt = filters[f]
            _, _, code = kernels.imm_screen(flt._buf, t - flt.time, flt._pred_time == t, z, C, R, bias, bias_cov,
                                            zc, Rc, -1.0 if gate is None else gate)
            flt.time, flt._pred_time = (t, math.nan) if code == -2 else (flt.time, t)
        elif kind == "update":
            _, f, t, z, R = op
            filters[f].update(t, z, R)
        elif kind == "start":
            filters[op[1]] = factory()
            filters[op[1]].start(*op[2:])
    return time.process_time() - c0, filters


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", nargs="?")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    ops, config, factory, n_inputs = record(args.folder)
    # measurements given to a filter
    n = sum(len(op[1]) if op[0] == "screen_many" else 1 for op in ops if op[0] in ("screen_many", "screen", "update", "start"))
    n_many = sum(len(op[1]) for op in ops if op[0] == "screen_many")
    filter_side(ops, config, factory)  # warm-up
    kernels_alone(ops, factory)
    for _ in range(args.repeat):
        side, many, a = filter_side(ops, config, factory)
        alone, b = kernels_alone(ops, factory)
        same = all(np.array_equal(a[k]._buf, b[k]._buf, equal_nan=True) and a[k].time == b[k].time for k in a)
        print(json.dumps({"folder": args.folder or "traffic 200x28x180s", "inputs": n_inputs, "measurements": n,
                          "filter_side_us": round(side / n * 1e6, 2), "kernels_us": round(alone / n * 1e6, 2),
                          "overhead_us": round((side - alone) / n * 1e6, 2),
                          "screen_many_us": round(many / max(n_many, 1) * 1e6, 2), "same_states": same}), flush=True)


if __name__ == "__main__":
    main()

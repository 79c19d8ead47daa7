"""One pipeline: a scenario through an association, a bias estimator and (with the TrackManager)
track filters, into one recorder and one result (:class:`RunResult`).

What differs between evaluation and operation is the *association*, a component chosen in
:class:`RunConfig`:

* ``labels`` — each plot goes to the aircraft named by its truth label (simulated data), else by its
  Mode S address; ADS-B by its address. A track starts at its first measurement with a wide prior
  and ends ``drop_after_s`` after its last. Plots and ADS-B reports are converted to the plane in
  bulk (:mod:`radartracker.estimation.measurement`) and handed to the estimator in time order.
* ``manager`` — the :class:`TrackManager`: admission, reordering, gating and assignment, M-of-N
  confirmation, track filters of the chosen motion model; the estimator gets the measurements of
  confirmed tracks.

Both feed the same :class:`Recorder` (track events with state, covariance and identity; biases over
time) and give the same :class:`RunResult`, written by :func:`radartracker.pipeline.writer.write_outputs`.
Every input is used or counted under a named reason.
"""

from __future__ import annotations

import contextlib
import csv
import gc
import itertools
import logging
import math
import time as _time
from collections import Counter
from collections.abc import Iterable, Iterator
from pathlib import Path

import attrs
import numpy as np
from tqdm import tqdm

from radartracker.errors import ConfigurationError, PluginError
from radartracker.estimation.base import Estimator, PlaneMeasurement
from radartracker.estimation.coupling import CouplingGraph
from radartracker.estimation.kalman import SingularInnovation
from radartracker.estimation.measurement import convert_adsb, convert_plots, fill_altitudes, merge, plot_keys
from radartracker.estimation.screening import REINIT, REJECT, LabelledScreen
from radartracker.fusion.center import LocalTracks
from radartracker.pipeline.distributed import run_distributed
from radartracker.geometry.plane import SystemPlane
from radartracker.io.scenario import open_scenario
from radartracker.io.tables import ScenarioData
from radartracker.pipeline.config import RunConfig, motion_factory, resolve
from radartracker.pipeline.recorder import Recorder
from radartracker.pipeline.result import RunResult
from radartracker.pipeline.stream import NotTimeOrdered, iter_files, iter_scenario
from radartracker.pipeline.writer import OutputStream, write_outputs
from radartracker.registry import FilterFactory, default_estimator, make_estimator, make_manager
from radartracker.clock import StreamClock

log = logging.getLogger(__name__)
GC_YOUNG_THRESHOLD = 50_000  # chosen by measurement: docs/performance.md, "Garbage collection"
PROGRESS_EVERY = 256  # inputs between two moves of the progress bar (~10-25 ms of a replay)


def run(data: ScenarioData, config: RunConfig | None = None, *, estimator: Estimator | None = None,
        progress: bool = True, local_tracks: LocalTracks | None = None, inputs: Iterable | None = None,
        sink: OutputStream | None = None, total: int | None = None) -> RunResult:
    """Run ``data`` through the association, estimator and motion model of ``config``.

    ``local_tracks`` (``--architecture distributed`` only): radar tracks imported from CAT048
    (:func:`radartracker.fusion.local_tracks_from_asterix`), fused instead of tracking ``data``'s plots.

    ``estimator`` replaces the plugin named in ``config``: it is given every radar of ``data``, and its
    own configuration must use the run's process noise ``q`` (a mismatch is refused, not ignored).

    Streaming (TrackManager association, central architecture): ``inputs`` are the time-ordered items
    (:func:`radartracker.pipeline.stream.iter_files`; ``total`` of them, about, for the progress bar)
    in place of ``data``'s tables, and ``sink`` writes the events and biases as they come; they are
    kept in memory only when ``data`` holds truth to evaluate them against.
    """
    config = config or RunConfig()
    name = type(estimator).name if estimator is not None else (config.estimator or default_estimator())
    cfg = resolve(config, data, name)
    if local_tracks is not None and cfg.architecture != "distributed":
        raise ConfigurationError("local tracks (CAT048 track reports) need --architecture distributed")
    radar_ids = [r.id for r in data.radars]
    if estimator is not None:
        if config.estimator_options:
            raise ConfigurationError("estimator options apply to a plugin name, not to an estimator instance")
        q_inst = getattr(getattr(estimator.config, "motion", None), "q", None)
        if q_inst != cfg.q:
            raise ConfigurationError(f"estimator instance {name!r} uses q = {q_inst} but the run uses q = {cfg.q}: "
                                     "build it with EstimatorConfig(motion=MotionModel(q)) or set the run's q")
        est = make_estimator(estimator, None, radar_ids)
    else:
        est = make_estimator(name, cfg.estimator_settings(), radar_ids, cfg.estimator_options)
    factory = motion_factory(cfg) if cfg.motion_model is not None else None
    plugins = {"estimator": attrs.asdict(est.options) if getattr(est, "options", None) is not None else {},
               "motion_model": attrs.asdict(factory.config) if factory is not None else None}
    if inputs is not None and (cfg.architecture != "central" or cfg.association != "manager"):
        raise ConfigurationError("only the TrackManager association of the central architecture is streamed")
    rec = Recorder(cfg.bias_log_interval_s, sink=sink, keep=data.truth is not None)
    started = _time.perf_counter()
    with young_garbage():
        if cfg.architecture == "distributed":
            counts, coupling = run_distributed(data, cfg, est, factory, rec, progress, cfg.fusion_settings(),
                                               local_tracks)
        elif cfg.association == "labels":
            counts, coupling = _by_labels(data, cfg, est, rec, progress)
        else:
            counts, coupling = _by_manager(data, cfg, est, factory, rec, progress, inputs, total)
    seconds = _time.perf_counter() - started
    rec.flush()
    plane = sink.plane if sink is not None else SystemPlane(*data.reference)  # a projection costs ~25 ms
    return RunResult(data=data, config=cfg, plane=plane, events=rec.events(),
                     biases=rec.biases(), final_biases={r: est.bias(r) for r in radar_ids}, counts=dict(counts),
                     seconds=seconds, nis=np.asarray(rec.nis, float), coupling=coupling, plugins=plugins,
                     streamed=sink is not None, track_count=len(rec.track_ids))


@contextlib.contextmanager
def young_garbage(threshold: int = GC_YOUNG_THRESHOLD) -> Iterator[None]:
    """Python's cyclic collector looks at its youngest generation every ``threshold`` net allocations of
    containers while the block runs (default 700): an input and what is made from it live for the reorder
    window, thousands of inputs, so at 700 they were promoted and scanned again in the older generations
    (docs/performance.md: about 15 % of a national replay). Restored when the block ends."""
    old = gc.get_threshold()
    gc.set_threshold(max(threshold, old[0]), *old[1:])
    try:
        yield
    finally:
        gc.set_threshold(*old)


def _by_labels(data: ScenarioData, cfg: RunConfig, est: Estimator, rec: Recorder,
               progress: bool) -> tuple[Counter, CouplingGraph]:
    """Association by truth label (else Mode S address); tracks end ``drop_after_s`` after their last update."""
    plane = SystemPlane(*data.reference)
    counts: Counter[str] = Counter()
    p, a = data.plots, data.adsb
    keys = plot_keys(p, p.has_truth_labels)
    alt, defaulted = fill_altitudes(p, keys, cfg.default_altitude_m)
    if defaulted:
        counts["plots_altitude_assumed"] = defaulted
    meas = merge(convert_plots(p, data.radars, plane, keys, alt), convert_adsb(a, plane))
    # identity columns in the same (stable, time) order as ``merge``
    order = np.argsort(np.concatenate([p.time, a.time]), kind="stable")
    reported = np.concatenate([p.altitude_m, a.altitude_m])[order]
    mode_s = np.concatenate([p.mode_s, a.icao24])[order]
    nacp = np.concatenate([np.full(len(p), 11), a.nacp.astype(int)])[order]
    mode_3a = np.concatenate([p.mode_3a, np.full(len(a), None, object)])[order]
    labels = np.concatenate([p.target if p.has_truth_labels else np.full(len(p), None, object),
                             np.full(len(a), None, object)])[order]

    life = cfg.labels
    prior_cov = np.diag([life.prior_sd_position_m**2] * 2 + [life.prior_sd_velocity_mps**2] * 2)
    coupling = CouplingGraph(est.radars)
    ids = itertools.count(1)
    track: dict[object, int] = {}  # aircraft key → live track id
    last_seen: dict[object, float] = {}
    ident: dict[int, list] = {}  # track id → [altitude, mode_s, mode_3a, label]
    next_sweep = -math.inf
    # the TrackManager's admission and screening rules (radartracker.tracking.admission, estimation.screening)
    screening = cfg.screening_settings()
    clock, screen = StreamClock(cfg.clock_settings()), LabelledScreen(screening)

    def end(k: object, t: float) -> None:
        tid = track.pop(k)
        del last_seen[k]
        x = est.aircraft(tid)
        rec.event(t, tid, "deleted", "deleted", _extrapolate(x.state, t - x.time), None, *ident.pop(tid))
        est.remove_aircraft(tid)
        coupling.remove_aircraft(tid)
        screen.forget(tid)

    for i in tqdm(range(len(meas)), desc=f"replay {cfg.estimator}", unit="meas", delay=2.0, mininterval=1.0,
                  disable=not progress):
        t, radar, key = float(meas.time[i]), meas.radar[i], meas.key[i]
        kind = "plots" if radar is not None else "adsb"
        if not clock.admit(t):
            counts[f"{kind}_time_jump"] += 1
            continue
        if key is None:
            counts[f"{kind}_unassociated"] += 1
            continue
        if not meas.valid[i]:
            counts[f"{kind}_impossible_geometry"] += 1
            continue
        if t >= next_sweep:  # end the tracks unseen for drop_after_s
            for k in [k for k, ts in last_seen.items() if t - ts > life.drop_after_s]:
                end(k, t)
            next_sweep = t + 1.0
        if screening.enabled and radar is None and (why := screen.adsb.check(key, t, meas.z[i], math.sqrt(meas.R[i][0, 0]), nacp[i])):
            counts[why] += 1
            continue
        if screening.enabled and key in track:
            verdict = screen.screen(est, PlaneMeasurement(t, track[key], radar, meas.z[i], meas.C[i], meas.R[i]), kind)
            if verdict == REJECT:
                counts[f"{kind}_outlier"] += 1
                continue
            if verdict == REINIT:  # the aircraft's state, not its measurements, is wrong: start it again
                counts["tracks_reinitialised"] += 1
                end(key, t)
        new = key not in track
        tid = next(ids) if new else track[key]
        if new:
            est.add_aircraft(tid, t, np.array([meas.z[i][0], meas.z[i][1], 0.0, 0.0]), prior_cov)
            coupling.add_aircraft(tid)
            ident[tid] = [None, None, None, labels[i] if labels[i] is not None else None]
        try:
            innov = est.update(PlaneMeasurement(t, tid, radar, meas.z[i], meas.C[i], meas.R[i]))
        except SingularInnovation as exc:
            counts[f"{kind}_singular"] += 1
            log.warning("measurement at t=%s of %s not used: %s", t, key, exc)
            if new:
                est.remove_aircraft(tid)
                coupling.remove_aircraft(tid)
                del ident[tid]
            continue
        except Exception as exc:  # a plugin's bug or refusal: say which plugin, aircraft and time
            raise PluginError(f"estimator {cfg.estimator!r} failed on aircraft {key} (track {tid}) at t={t:.3f} s: "
                              f"{type(exc).__name__}: {exc}") from exc
        track[key], last_seen[key] = tid, t
        coupling.observe(tid, radar, t)
        counts[f"{kind}_used"] += 1
        rec.nis.append(innov.nis)
        idt = ident[tid]
        idt[0] = reported[i] if not math.isnan(reported[i]) else idt[0]
        idt[1], idt[2] = mode_s[i] or idt[1], mode_3a[i] or idt[2]
        x = est.aircraft(tid)
        if new:
            rec.event(t, tid, "created", "confirmed", x.state, x.cov, *idt)
        rec.event(t, tid, "confirmed" if new else "updated", "confirmed", x.state, x.cov, *idt)
        if radar is not None and rec.bias_due(radar, t):
            rec.bias(t, est.bias(radar))
    return counts, coupling


def _extrapolate(state: np.ndarray, dt: float) -> np.ndarray:
    return np.concatenate([state[:2] + state[2:] * max(dt, 0.0), state[2:]])


def _by_manager(data: ScenarioData, cfg: RunConfig, est: Estimator, factory: FilterFactory, rec: Recorder,
                progress: bool, inputs: Iterable | None = None,
                total: int | None = None) -> tuple[Counter, CouplingGraph]:
    """Association by the TrackManager; events carry the track filter's state and covariance."""
    mgr = make_manager(data.radars, data.reference, cfg.manager_settings(), estimator=est, filter_factory=factory)
    mgr.events.subscribe(rec.listen)
    if inputs is None:
        inputs, total = iter_scenario(data), len(data.plots) + len(data.adsb)
    bar = tqdm(total=total, desc=f"track {cfg.estimator}/{cfg.motion_model}", unit="item", delay=2.0,
               mininterval=1.0) if progress else contextlib.nullcontext()
    with bar:  # without a progress bar, the inputs themselves (a disabled tqdm still passes each through a generator)
        for piece in counted(inputs, bar) if progress else (inputs,):
            for item in piece:
                mgr.process(item)
                rid = getattr(item, "radar", None)
                if rid is not None and rec.bias_due(rid, item.time):  # each radar's bias once a second
                    rec.bias(item.time, est.bias(rid))
    mgr.flush()
    return Counter(mgr.accounting()), mgr.coupling


def counted(inputs: Iterable, bar: tqdm, every: int = PROGRESS_EVERY) -> Iterator[list]:
    """``inputs`` in lists of ``every``, ``bar`` moved on by each list once it is used: through tqdm's own
    iterator each input paid ~0.2 µs CPU (a generator step, a count and a clock read; scripts/bench_frame_costs.py)."""
    it = iter(inputs)
    while piece := list(itertools.islice(it, every)):
        yield piece
        bar.update(len(piece))


def streamable(folder: Path | str, config: RunConfig) -> bool:
    """Whether :func:`replay_folder` can stream the scenario folder ``folder`` under ``config``: the
    TrackManager association (named, or chosen by ``auto`` because ``plots.csv`` has no ``target``
    column) and the central architecture."""
    folder = Path(folder)
    if config.architecture != "central" or not folder.is_dir() or config.association == "labels":
        return False
    if config.association == "manager":
        return True
    try:
        with (folder / "plots.csv").open(encoding="utf-8-sig", newline="") as f:
            header = next(csv.reader([f.readline()]), [])
    except (OSError, UnicodeDecodeError, csv.Error):
        return False  # read whole: the reader names the problem
    return "target" not in [h.strip() for h in header]


def replay_folder(folder: Path | str, config: RunConfig, out: Path | str, *, progress: bool = True,
                  prefetch: bool = False) -> RunResult:
    """Replay the scenario folder ``folder`` into the prepared folder ``out`` (tables, summary, config),
    streamed when :func:`streamable` (memory flat in the recording's length), else read whole: the
    same files either way. A file whose kept rows are not in time order cannot be merged as it is
    read: that run is abandoned and the folder read whole. ``prefetch``: see
    :func:`radartracker.pipeline.stream.iter_files`."""
    if streamable(folder, config):
        files = open_scenario(folder, skip_bad=config.skip_bad)
        sink = OutputStream(out, SystemPlane(*files.data.reference))
        try:
            result = run(files.data, config, progress=progress, inputs=iter_files(files, prefetch=prefetch),
                         sink=sink, total=files.rows)
            result.label_spans = files.label_spans
            summary = result.summary()  # evaluated before the tables replace an earlier run's
        except NotTimeOrdered as exc:
            sink.abort(exc)
            log.info("%s: reading the whole scenario instead of streaming it", exc)
        except BaseException as exc:
            sink.abort(exc)
            raise
        else:
            sink.close()
            write_outputs(result, out, summary=summary)
            return result
    from radartracker.io.sources import read_source

    result = run(read_source(folder, skip_bad=config.skip_bad), config, progress=progress)
    write_outputs(result, out)
    return result

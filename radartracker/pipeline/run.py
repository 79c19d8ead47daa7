"""One pipeline: a scenario through the TrackManager (association, track filters, the bias estimator)
into one recorder and one result (:class:`RunResult`).

There is one tracker. What differs between evaluation and operation is its *associator*, a plugin
chosen in :class:`RunConfig`: ``labels`` sends each plot to the track of its truth label (simulated data;
the evaluation of the tracker with perfect association), ``gnn`` (the default of ``--association
manager``) associates by Mode S address and gating, as in operation. ``--architecture distributed``
runs one manager per radar and a fusion centre (:mod:`radartracker.pipeline.distributed`).

The :class:`Recorder` listens to the manager's events (state, covariance and identity) and records the
biases over time; :func:`radartracker.pipeline.writer.write_outputs` writes the result. Every input is
used or counted under a named reason.
"""

from __future__ import annotations

import contextlib
import csv
import gc
import itertools
import logging
import time as _time
from collections import Counter
from collections.abc import Iterable, Iterator
from pathlib import Path

import attrs
import pyarrow as pa
from tqdm import tqdm

from radartracker.domain import BiasState
from radartracker.errors import ConfigurationError, RadarTrackerError
from radartracker.estimation.base import Estimator
from radartracker.estimation.coupling import CouplingGraph
from radartracker.fusion.center import LocalTracks
from radartracker.pipeline.distributed import run_distributed
from radartracker.geometry.plane import SystemPlane
from radartracker.io.scenario import open_scenario
from radartracker.io.tablefiles import columns, find_table
from radartracker.io.tables import ScenarioData
from radartracker.pipeline.config import RunConfig, motion_factory, resolve
from radartracker.pipeline.recorder import Recorder
from radartracker.pipeline.result import RunResult
from radartracker.pipeline.stream import NotTimeOrdered, iter_files, iter_scenario
from radartracker.pipeline.writer import OutputStream, write_outputs
from radartracker.registry import FilterFactory, default_estimator, make_estimator, make_manager

log = logging.getLogger(__name__)
GC_YOUNG_THRESHOLD = 50_000  # chosen by measurement: docs/performance.md, "Garbage collection"
PROGRESS_EVERY = 256  # inputs between two moves of the progress bar: often enough to look live


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
    if inputs is not None and cfg.architecture != "central":
        raise ConfigurationError("only the central architecture is streamed")
    rec = Recorder(cfg.bias_log_interval_s, sink=sink, keep=data.truth is not None)
    started = _time.perf_counter()
    with young_garbage():
        if cfg.architecture == "distributed":
            counts, coupling, track_counts, track_nis = run_distributed(data, cfg, est, factory, rec, progress,
                                                             cfg.fusion_settings(), local_tracks)
            final = {r: est.bias(r) for r in radar_ids}
        else:
            counts, coupling, track_counts, track_nis, final = _by_manager(data, cfg, est, factory, rec, progress,
                                                                           inputs, total)
    seconds = _time.perf_counter() - started
    rec.flush()
    plane = sink.plane if sink is not None else SystemPlane(*data.reference)  # the sink's, not a second one
    return RunResult(data=data, config=cfg, plane=plane, events=rec.events(),
                     biases=rec.biases(), final_biases=final, counts=dict(counts),
                     track_counts=track_counts, track_nis=track_nis,
                     seconds=seconds, mean_nis=rec.mean_nis, coupling=coupling, plugins=plugins,
                     streamed=sink is not None, track_count=len(rec.track_ids))


@contextlib.contextmanager
def young_garbage(threshold: int = GC_YOUNG_THRESHOLD) -> Iterator[None]:
    """Python's cyclic collector looks at its youngest generation every ``threshold`` net allocations of
    containers while the block runs (default 700): an input and what is made from it live for the reorder
    window, thousands of inputs, so at 700 they were promoted and scanned again in the older generations.
    The objects that exist when the block starts (modules, compiled code, the caller's data: some 180 000
    in a replay) are frozen (``gc.freeze``) so that the oldest generation's collections do not scan them
    again and again, and given back to the collector (``gc.unfreeze``) when it ends, with the threshold
    (docs/performance.md, "Garbage collection"). A caller that froze objects itself keeps them frozen."""
    old = gc.get_threshold()
    gc.set_threshold(max(threshold, old[0]), *old[1:])
    freeze = gc.get_freeze_count() == 0
    if freeze:
        gc.freeze()
    try:
        yield
    finally:
        if freeze:
            gc.unfreeze()
        gc.set_threshold(*old)


def _by_manager(data: ScenarioData, cfg: RunConfig, est: Estimator, factory: FilterFactory, rec: Recorder,
                progress: bool, inputs: Iterable | None = None,
                total: int | None = None
                ) -> tuple[Counter, CouplingGraph, dict[str, int], dict[str, float], dict[str, BiasState]]:
    """The TrackManager with the run's associator; events carry the track filter's state and covariance.
    Returns the inputs' accounting, the coupling graph, the track counts, the tracks' innovations and the
    final biases as the tracks used them (:meth:`TrackManager.bias`)."""
    mgr = make_manager(data.radars, data.reference, cfg.manager_settings(), estimator=est, filter_factory=factory)
    mgr.events.subscribe(rec.listen)
    mgr.feed.on_nis = rec.add_nis
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
                    rec.bias(item.time, mgr.bias(rid))
    mgr.flush()
    return Counter(mgr.accounting()), mgr.coupling, mgr.track_counts(), mgr.innovations(), mgr.biases()


def counted(inputs: Iterable, bar: tqdm, every: int = PROGRESS_EVERY) -> Iterator[list]:
    """``inputs`` in lists of ``every``, ``bar`` moved on by each list once it is used: through tqdm's own
    iterator each input would pay a generator step, a count and a clock read."""
    it = iter(inputs)
    while piece := list(itertools.islice(it, every)):
        yield piece
        bar.update(len(piece))


def streamable(folder: Path | str, config: RunConfig) -> bool:
    """Whether :func:`replay_folder` can stream the scenario folder ``folder`` under ``config``: the
    TrackManager association (named, or chosen by ``auto`` because the plots have no ``target``
    column) and the central architecture."""
    folder = Path(folder)
    if config.architecture != "central" or not folder.is_dir() or config.association == "labels":
        return False
    if config.association == "manager":
        return True
    try:
        plots = find_table(folder, "plots")
        header = columns(plots) if plots is not None else []
    except (OSError, UnicodeDecodeError, csv.Error, RadarTrackerError, pa.ArrowException):
        return False  # read whole: the reader names the problem
    return "target" not in header


def replay_folder(folder: Path | str, config: RunConfig, out: Path | str, *, progress: bool = True,
                  prefetch: bool = False, table_format: str = "csv") -> RunResult:
    """Replay the scenario folder ``folder`` into the prepared folder ``out`` (tables as ``table_format``, csv
    or parquet; summary, config), streamed when :func:`streamable` (memory flat in the recording's length),
    else read whole: the same files either way. A table whose kept rows are not in time order cannot be
    merged as it is read: that run is abandoned and the folder read whole. ``prefetch``: see
    :func:`radartracker.pipeline.stream.iter_files`."""
    if streamable(folder, config):
        files = open_scenario(folder, skip_bad=config.skip_bad)
        sink = OutputStream(out, SystemPlane(*files.data.reference), table_format)
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
            write_outputs(result, out, summary=summary, streamed=sink)
            return result
    from radartracker.io.sources import read_source

    result = run(read_source(folder, skip_bad=config.skip_bad), config, progress=progress)
    write_outputs(result, out, table_format=table_format)
    return result

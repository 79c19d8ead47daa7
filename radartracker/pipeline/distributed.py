"""The distributed architecture (seed 004): one TrackManager per radar, a fusion centre over their tracks.

Each radar's plots go to its own :class:`TrackManager` (the run's motion model; its own estimator
instance with the bias held at zero — a radar alone cannot observe its bias, so its tracks carry
it); their confirmed track
estimates are the local reports of :class:`FusionCentre`, which makes the system tracks and the
radars' bias estimates every ``FusionConfig.period_s``. ADS-B reports go to the centre only (radar
heads do not see them). The system tracks feed the run's :class:`Recorder` exactly as the central
paths' tracks do, so the outputs, their schema and the evaluation are the same.
"""

from __future__ import annotations

import heapq
import math
from collections import Counter
from collections.abc import Callable

import attrs
import numpy as np
from tqdm import tqdm

from radartracker.domain import AdsbReport, Plot, nacp_sigma_m
from radartracker.estimation.base import Estimator
from radartracker.estimation.coupling import CouplingGraph
from radartracker.fusion.center import (FusionCentre, FusionConfig, LocalReport, LocalTrackEnd, LocalTracks,
                                       SystemTrack)
from radartracker.geometry.plane import SystemPlane
from radartracker.io.tables import ScenarioData
from radartracker.pipeline.recorder import Recorder
from radartracker.pipeline.stream import iter_scenario
from radartracker.registry import FilterFactory, default_estimator, make_estimator, make_manager
from radartracker.tracking.events import ENDS, TrackEvent
from radartracker.tracking.manager import TrackManager
from radartracker.tracking.track import Track


def run_distributed(data: ScenarioData, cfg, est: Estimator, factory: FilterFactory, rec: Recorder,
                    progress: bool, fusion: FusionConfig | None = None,
                    local_tracks: LocalTracks | None = None) -> tuple[Counter, CouplingGraph, dict[str, int]]:
    """Local trackers, fusion centre and recorder over ``data`` (``cfg`` the run's resolved RunConfig);
    with ``local_tracks`` (imported from CAT048) those replace the local trackers and ``data``'s plots."""
    fusion = fusion or FusionConfig()
    plane = SystemPlane(*data.reference)
    mcfg = cfg.manager_settings()
    coupling = CouplingGraph(est.radars)

    def system_event(t: float, tr: SystemTrack, kind: str, ident: tuple) -> None:
        if kind == "created":
            coupling.add_aircraft(tr.id)
            rec.event(t, tr.id, "created", "confirmed", tr.state, tr.cov, *ident)
            kind = "confirmed"
        elif kind == "deleted":
            coupling.remove_aircraft(tr.id)
            rec.event(t, tr.id, "deleted", "deleted", tr.state, None, *ident)
            return
        rec.event(t, tr.id, kind, "confirmed", tr.state, tr.cov, *ident)
        for rid, _ in tr.members:
            coupling.observe(tr.id, rid, t)

    centre = FusionCentre(data.radars, plane, est, cfg.q, fusion, system_event, mcfg.primary_altitude_m,
                          cfg.screening_settings())
    managers = {} if local_tracks is not None else local_trackers(data, cfg, factory, centre.report, centre.drop)
    if local_tracks is None:
        stream, total = iter_scenario(data), len(data.plots) + len(data.adsb)
    else:  # imported local tracks (CAT048): no local trackers, their reports and ends in time order
        stream = heapq.merge(iter_scenario(data), local_tracks.items(), key=lambda item: item.time)
        total = len(data.adsb) + len(local_tracks.reports) + len(local_tracks.ends)
    next_epoch = math.nan
    for item in tqdm(stream, total=total, desc="distributed", unit="item",
                     delay=2.0, mininterval=1.0, disable=not progress):
        if math.isnan(next_epoch):
            next_epoch = math.ceil(item.time / fusion.period_s) * fusion.period_s
        while item.time >= next_epoch:
            for mgr in managers.values():  # a radar head's clock runs without plots too
                mgr.advance(next_epoch)
            centre.epoch(next_epoch)
            _log_biases(rec, est, next_epoch)
            next_epoch += fusion.period_s
        if isinstance(item, Plot):
            managers[item.radar].process(item)
        elif isinstance(item, AdsbReport):
            x, y = plane.to_plane(item.lat, item.lon)
            sd = nacp_sigma_m(item.nacp)
            centre.adsb_report(item.time, item.icao24, np.array([float(x), float(y)]), np.eye(2) * sd * sd, item.nacp)
        elif isinstance(item, LocalReport):
            centre.report(item)
        else:
            centre.drop(item.radar, item.track)
    for mgr in managers.values():
        mgr.flush()
    if not math.isnan(next_epoch):
        centre.epoch(next_epoch, final=True)
        _log_biases(rec, est, next_epoch)
    counts: Counter[str] = Counter()
    track_counts: Counter[str] = Counter()
    for mgr in managers.values():
        counts.update(mgr.accounting())
        track_counts.update(mgr.track_counts())
    counts.update(centre.counts)
    return counts, coupling, dict(track_counts), pooled_innovations([m.innovations() for m in managers.values()])


def pooled_innovations(parts: list[dict[str, float]]) -> dict[str, float]:
    """The local trackers' innovation statistics (:meth:`TrackManager.innovations`) as one."""
    n = sum(p["count"] for p in parts)
    total = sum(p["count"] * p["mean_nis"] for p in parts if p["count"])
    return {"count": n, "mean_nis": total / n if n else math.nan}


def local_trackers(data: ScenarioData, cfg, factory: FilterFactory, report: Callable[[LocalReport], None],
                   drop: Callable[[str, int], None]) -> dict[str, TrackManager]:
    """One TrackManager per radar (``cfg`` the run's resolved RunConfig); each confirmed or updated
    track's estimate goes to ``report``, each deletion to ``drop``."""
    mcfg = cfg.manager_settings()
    managers: dict[str, TrackManager] = {}
    # a radar head does not know its own bias: its tracker corrects nothing (prior held at zero), so its
    # tracks carry the whole bias, which the centre then estimates
    local_settings = attrs.evolve(cfg.estimator_settings(), bias_sd_range_m=1e-6, bias_sd_azimuth_rad=1e-12)
    for radar in data.radars:
        def on_event(ev: TrackEvent, tr: Track, rid: str = radar.id) -> None:
            if ev.kind in ENDS:
                drop(rid, ev.track)
                return
            if ev.kind not in ("confirmed", "updated"):
                return
            t0, x, P = tr.filter.estimate()
            report(LocalReport(t0, rid, ev.track, np.array(x, float), np.array(P, float), tr.altitude_m,
                               tr.mode_s, tr.mode_3a))

        local_est = make_estimator(cfg.estimator, local_settings, [radar.id], cfg.estimator_options)
        managers[radar.id] = make_manager([radar], data.reference, mcfg, estimator=local_est, filter_factory=factory)
        managers[radar.id].events.subscribe(on_event)
    return managers


def _log_biases(rec: Recorder, est: Estimator, t: float) -> None:
    for rid in est.radars:
        rec.bias(t, est.bias(rid))


def collect_local_tracks(data: ScenarioData, config=None) -> LocalTracks:
    """The local tracks the distributed architecture's per-radar trackers make of ``data``'s plots
    (``config`` a RunConfig; its motion model and estimator settings apply): the input a radar head
    that tracks would send, for :func:`write_local_tracks`."""
    from radartracker.pipeline.config import RunConfig, motion_factory, resolve

    config = config or RunConfig(architecture="distributed")
    cfg = resolve(config, data, config.estimator or default_estimator())
    reports, ends, now = [], [], [0.0]
    managers = local_trackers(data, cfg, motion_factory(cfg) if cfg.motion_model is not None else None,
                              reports.append, lambda rid, track: ends.append(LocalTrackEnd(now[0], rid, track)))
    for item in iter_scenario(data):
        if isinstance(item, Plot):
            now[0] = item.time
            managers[item.radar].process(item)
    for mgr in managers.values():
        mgr.flush()
    reports.sort(key=lambda r: r.time)
    ends.sort(key=lambda e: e.time)
    return LocalTracks(reports, ends)

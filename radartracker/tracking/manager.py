"""TrackManager: plot streams in, tracks, bias estimates and events out (DESIGN §2, §6).

A manager is a short recipe of stages, each a class of its own module with one job:

1. **Admission** (:class:`~radartracker.tracking.admission.Admission`): unknown radars, invalid inputs,
   time stamps far ahead of the stream's robust clock, duplicates and inputs behind the reordering
   horizon are rejected and counted; the inputs of a genuine jump of the stream are held, then admitted.
2. **Reordering** (:class:`~radartracker.tracking.admission.ReorderWindow`): admitted inputs wait until
   the stream's confirmed time is ``reorder_window_s`` ahead of them, then leave in time order, into frames of
   ``frame_s`` seconds.
3. **Frame** (:class:`~radartracker.tracking.frame.FrameBuilder`): a frame's plots, ADS-B reports and
   unbiased positions in the plane, and the live tracks predicted to it
   (:class:`~radartracker.tracking.frame.Prediction`).
4. **Association** (an :class:`~radartracker.tracking.associators.Associator` plugin, ``gnn`` by default):
   each radar's plots to tracks; ADS-B reports go to the track with their address, unbiased positions by
   identity or gating.
5. **Heights** (:class:`~radartracker.tracking.height.HeightEstimator`): the plots without altitude of tracks
   whose height the slant ranges have made observable, converted again at that height.
6. **Life cycle** (:class:`~radartracker.tracking.lifecycle.TrackLifecycle`): screening, the track
   filters (a motion-model plugin), initiation, M-of-N confirmation, misses (which antenna swept which
   track: :class:`~radartracker.tracking.coverage.AntennaSweep`), coasting and deletion.
7. **Estimator feed** (:class:`~radartracker.tracking.feed.EstimatorFeed`): the measurements of confirmed
   tracks to the bias estimator plugin and the coupling graph at the frame's end.
8. **Events** (:class:`~radartracker.tracking.events.EventSink`): every event, with its track, to the
   listeners and to the caller.

Every input is either used or counted under a named reason (:meth:`TrackManager.accounting`).
:meth:`TrackManager.snapshot` / :meth:`TrackManager.restore` save and load the whole state in a versioned,
checksummed document (:mod:`radartracker.tracking.snapshot`).
"""

from __future__ import annotations

import itertools
import math
from collections import Counter
from collections.abc import Callable, Iterable
from pathlib import Path


from radartracker.domain import AdsbReport, BiasState, Plot, Radar
from radartracker.errors import ConfigurationError, PluginError
from radartracker.estimation.base import Estimator, PlaneMeasurement
from radartracker.estimation.coupling import CouplingGraph
from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.tracking.admission import Admission, ReorderWindow
from radartracker.tracking.associators import Associator, RadarPlots, associate_position
from radartracker.tracking.config import ManagerConfig
from radartracker.tracking.coverage import AntennaSweep
from radartracker.tracking.events import EventSink, TrackEvent, new_tuple
from radartracker.tracking.feed import EstimatorFeed
from radartracker.tracking.frame import Frame, FrameBuilder, Prediction
from radartracker.tracking.height import HeightEstimator
from radartracker.tracking.lifecycle import TrackLifecycle, Update
from radartracker.tracking.prepared import PlaneConverter
from radartracker.tracking.schema import save_manager
from radartracker.tracking.track import Track

Input = Plot | AdsbReport | PlaneMeasurement


class TrackManager:
    """Association, track life cycle and estimation for a stream of plots and ADS-B reports (module
    docstring), with its plugins built: ``estimator`` (given every radar), ``new_filter`` (a track-filter
    factory: ``new_filter()`` a new filter, ``new_filter(config)`` one of a snapshot's config, ``.name``)
    and ``associator``. :func:`radartracker.registry.make_manager` builds them from ``config``'s names."""

    def __init__(self, radars: list[Radar], reference: tuple[float, float], config: ManagerConfig, *,
                 estimator: Estimator, new_filter: Callable, associator: Associator) -> None:
        self.config = config
        self.radars = {r.id: r for r in radars}
        self.reference = tuple(reference)
        self.plane = SystemPlane(*reference)
        frames = {r.id: RadarFrame(r.lat, r.lon, r.height_m, self.plane) for r in radars}
        self.counts: Counter[str] = Counter()
        for rid in self.radars:  # a measurement carries C = ∂z/∂(ρ, θ) and R, not the slant range ρ
            if extra := estimator.config.sensor(rid).extra:
                raise ConfigurationError(f"the TrackManager does not carry bias component {extra[0]!r} (radar "
                                         f"{rid!r}, estimator {estimator.name!r}) yet: use "
                                         "radartracker.pipeline.registration")
        self.estimator, self.new_filter, self.associator = estimator, new_filter, associator
        self.coupling = CouplingGraph(list(self.radars))
        self.events = EventSink()
        self.admission = Admission(self.radars, config.clock, self.counts)
        self.window = ReorderWindow(config.reorder_window_s, config.clock.step_after, config.clock.window)
        converter = PlaneConverter(radars, frames, self.plane)
        self.antennas = AntennaSweep(radars, [frames[r.id].xy for r in radars],
                                     [self._grid_north(r) for r in radars])
        self.feed = EstimatorFeed(estimator, self.coupling, self.counts, self._plugin_failed)
        self.frames = FrameBuilder(converter, config.primary_altitude_m, config.primary_altitude_sd_m, self.feed.bias)
        self.life = TrackLifecycle(config, new_filter, self.feed, self.events, self.counts, self._plugin_failed)
        self.life.labels = getattr(associator, "labels", False)
        self.heights = HeightEstimator(converter, config.height, config.primary_altitude_m,
                                       config.primary_altitude_sd_m, self.feed.bias, estimator.config.bias_sd_range_m)
        self.life.took = self.heights.took
        self.frame: int | None = None  # the number of the frame being gathered (time // frame_s)
        self.gathered: list[Input] = []  # its inputs so far
        self.updates = itertools.count()  # the order of the updates made within a frame

    # --- public API ------------------------------------------------------------------------------
    def process(self, item: Input) -> list[TrackEvent]:
        """Admit one plot, ADS-B report or unbiased position; return the events it caused (possibly none yet)."""
        window, capacity = self.window, self.config.reorder_capacity
        for t, admitted in self.admission.admit(item, window.horizon):
            newest = window.newest
            window.push(admitted, t)
            if len(window) > capacity:
                self._overfull(newest is None or t > newest)
            until = window.until
            if window.due(until):
                self._release(until)
        return self.events.take()

    def process_many(self, items: Iterable[Input]) -> list[TrackEvent]:
        """Process every item, then flush; all events in order."""
        events: list[TrackEvent] = []
        for item in items:
            events.extend(self.process(item))
        events.extend(self.flush())
        return events

    def advance(self, now: float) -> list[TrackEvent]:
        """The stream's clock reached ``now`` (inputs for other consumers, e.g. the other radars of the
        distributed architecture): release what the reordering window allows, and close the last frame if it
        ended before that, so a quiet radar's tracks are not held back a scan."""
        until = now - self.config.reorder_window_s
        self._release(until)
        if self.frame is not None and self.gathered and (self.frame + 1) * self.config.frame_s <= until:
            self._run_frame(self.frame)
            self.frame += 1
        return self.events.take()

    def flush(self, end: bool = True) -> list[TrackEvent]:
        """Process what the stream has reached: at the end of a recording (``end``) or a service's stop.

        The window is released up to its settled time (:meth:`ReorderWindow.settled`, with a slack of half
        ``delete_after_s``), so an input alone far ahead of the stream never advances the tracks' time (it
        would delete every track at once). At the end of a recording that input, and the inputs held ahead of
        the clock never confirmed by a clock step, are counted ``*_time_jump``; at a stop they stay waiting,
        in the snapshot, for the stream that resumes."""
        if end:
            self.admission.drop_held()
        self._release(self.window.settled(0.5 * self.config.delete_after_s))
        if end:
            for _, item in self.window.release(math.inf):
                self.admission.withdraw(item, "time_jump")
        if self.frame is not None and self.gathered:
            self._run_frame(self.frame)
        self.gathered = []
        return self.events.take()

    @property
    def tracks(self) -> dict[int, Track]:
        """The live tracks by id, in the order they started."""
        return self.life.tracks

    def confirmed_tracks(self) -> list[Track]:
        """The live tracks that are confirmed or coasting."""
        return [t for t in self.tracks.values() if t.live]

    def bias(self, radar: str) -> BiasState:
        """``radar``'s current bias estimate [Δr (m), Δθ (rad)] and covariance, as the tracks are corrected with
        it: components the data do not inform at their prior, named in ``unobservable``
        (:mod:`radartracker.estimation.observability`)."""
        return self.feed.state(radar)

    def biases(self) -> dict[str, BiasState]:
        """:meth:`bias` of every radar, by radar id."""
        return {rid: self.feed.state(rid) for rid in self.radars}

    def accounting(self) -> dict[str, int]:
        """Counts by reason, including measurements still held by tentative tracks and inputs waiting."""
        out = Counter(self.counts)
        for tr in self.tracks.values():
            for p in tr.pending:
                out[f"{p.kind}_in_tentative_tracks"] += 1
        out["waiting_in_reorder_window"] = len(self.window) + len(self.gathered) + len(self.admission.held)
        return {k: v for k, v in out.items() if v}

    def track_counts(self) -> dict[str, int]:
        """What happened to tracks beyond their events (``tracks_reinitialised``: a track deleted and started
        again from a measurement its rejected ones agreed with); not inputs, so apart from :meth:`accounting`."""
        return {k: v for k, v in self.life.track_counts.items() if v}

    def innovations(self) -> dict[str, float]:
        """The confirmed tracks' normalised innovations d² = νᵀS⁻¹ν of the measurements they accepted
        (S = P̄_pp + C P_ς Cᵀ + R, :mod:`~radartracker.tracking.lifecycle`): ``count`` and ``mean_nis``
        (χ² with 2 degrees of freedom, mean 2, when the filters' covariances and R are right)."""
        n, total = self.life.nis
        return {"count": n, "mean_nis": total / n if n else math.nan}

    def snapshot(self, path: Path | str) -> None:
        """Save the whole state to ``path``, atomically (:mod:`radartracker.tracking.schema`;
        :func:`radartracker.registry.restore_manager` reads it back)."""
        save_manager(self, path)

    # --- frames ----------------------------------------------------------------------------------
    def _release(self, until: float) -> None:
        """Hand the inputs up to ``until`` to their frames (:meth:`_gather`)."""
        self._gather(self.window.release(until))

    def _overfull(self, moved_on: bool) -> None:
        """The window holds more than ``reorder_capacity`` inputs: a flood sharing a few time stamps. If the
        input just pushed is newer than everything waiting (the stream has moved on), the oldest input leaves
        early, into its frame; otherwise the newest input is dropped (``*_reorder_overflow``): the flood's
        own, whether it sits ahead of the stream or arrives at its time, never a good input behind it."""
        if moved_on:
            self._gather([self.window.pop_oldest()])
        else:
            self.admission.withdraw(self.window.drop_newest(), "reorder_overflow")

    def _gather(self, released: Iterable[tuple[float, Input]]) -> None:
        """Each (time, input) into its frame; run each frame once an input of a later one comes (frames
        without input between them still sweep the antennas; a gap of 240 frames or more is one). A frame
        that gathers ``reorder_capacity`` inputs (a flood) is processed in parts, to bound the memory."""
        fs, cap = self.config.frame_s, self.config.reorder_capacity
        for t, item in released:
            frame = math.floor(t / fs)
            if self.frame is None:
                self.frame = frame
            while frame > self.frame:
                self._run_frame(self.frame)
                self.frame = self.frame + 1 if frame - self.frame < 240 else frame
            self.gathered.append(item)
            if len(self.gathered) >= cap:
                self._run_frame(self.frame)

    def _run_frame(self, number: int) -> None:
        """One frame: convert, associate, refine heights, apply in time order, find misses, delete, feed the
        estimator."""
        t_a, t_b = number * self.config.frame_s, (number + 1) * self.config.frame_s
        items, self.gathered = self.gathered, []
        tracks = list(self.tracks.values())
        pred = Prediction(tracks, 0.5 * (t_a + t_b))
        self.life.begin_frame(pred)
        frame = self.frames.build(t_a, t_b, items, tracks)
        n = len(frame.plots)
        self.antennas.observe(frame.meas.radar[:n], frame.meas.time[:n], frame.azimuth)
        updates, hits = self._associate(frame, pred)
        updates += self._identified(frame, pred)
        self.heights.refine(frame, updates, tracks)
        if tracks:
            swept, covered = self.antennas.sweep(pred.position, t_a, t_b)
            self.life.missed(tracks, swept, hits, t_a, t_b)
        updates.sort()
        rows, apply = frame.meas.rows(), self.life.apply
        for u in updates:
            apply(u, rows)
        if tracks:
            self.life.sweep(tracks, covered, t_b)
        self.feed.flush()

    def _associate(self, frame: Frame, pred: Prediction) -> tuple[list[Update], set[tuple[int, int]]]:
        """The frame's plots, radar by radar in the radars' order, through the associator: the updates and
        the (radar row, track index) pairs that got a plot (not missed)."""
        updates: list[Update] = []
        hits: set[tuple[int, int]] = set()
        meas, seq = frame.meas, self.updates
        for r, rid in enumerate(self.radars):
            rows = frame.radar_rows.get(rid)
            if rows is None:
                continue
            s = slice(rows.start, rows.stop)
            plots = frame.plots[s]
            bias, bias_cov = self.feed.bias(rid)
            result = self.associator.associate(
                RadarPlots(rid, plots, meas.z[s], meas.C[s], meas.R[s], frame.valid[s], bias, bias_cov), pred)
            for k, i in enumerate(result.track.tolist()):
                if i < -1:
                    self.counts[result.reasons.get(k, "plots_refused_by_associator")] += 1
                    continue
                updates.append(new_tuple(Update, (plots[k].time, next(seq), pred.tracks[i] if i >= 0 else None,
                                                  rows.start + k, plots[k])))
                if i >= 0:
                    hits.add((r, i))
        return updates, hits

    def _identified(self, frame: Frame, pred: Prediction) -> list[Update]:
        """The updates of the frame's ADS-B reports (the track with their address) and unbiased positions
        (:func:`~radartracker.tracking.associators.associate_position`)."""
        seq, cfg = self.updates, self.config
        with_code = self.life.with_code
        out = [new_tuple(Update, (rep.time, next(seq), with_code(rep.icao24), row, rep))
               for row, rep in enumerate(frame.reports, frame.first_report_row)]
        for row, m in enumerate(frame.positions, frame.first_position_row):
            i = associate_position(m, pred, cfg.gate, cfg.search_radius_m) if pred.tracks else None
            out.append(Update(m.time, next(seq), pred.tracks[i] if i is not None else None, row, m))
        return out

    def _plugin_failed(self, plugin: str, track: int | None, time: float, exc: Exception) -> PluginError:
        """The error a run ends with when a plugin raises: names the plugin, the aircraft and the time."""
        tr = self.tracks.get(track) if track is not None else None
        who = "a new track" if track is None else f"track {track}" + (f" (Mode S {tr.mode_s})" if tr and tr.mode_s else "")
        return PluginError(f"{plugin} failed on {who} at t={time:.3f} s: {type(exc).__name__}: {exc}")

    def _grid_north(self, r: Radar) -> float:
        """Grid azimuth of true north at the radar (meridian convergence), to compare azimuths."""
        x0, y0 = self.plane.to_plane(r.lat, r.lon)
        x1, y1 = self.plane.to_plane(min(r.lat + 0.01, 89.99), r.lon)
        return math.atan2(float(x1 - x0), float(y1 - y0))

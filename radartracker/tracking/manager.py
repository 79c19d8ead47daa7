"""TrackManager: plot streams in, tracks, bias estimates and events out (DESIGN §2, §6).

Pipeline for every input — a :class:`Plot`, an :class:`AdsbReport`, or a
:class:`PlaneMeasurement` with ``radar=None`` (an unbiased position with its covariance, such as a
triangulated fix; associated by its ``aircraft`` key if that is a Mode S address, else by gating):

1. **Admission** — unknown radars, non-domain objects, time jumps beyond ``max_time_jump_s``,
   duplicates, plots older than the reordering horizon and time stamps far ahead of the robust
   stream time (:mod:`radartracker.tracking.admission`) are rejected and counted by reason.
2. **Reordering** — admitted inputs wait in a heap until the newest time is ``reorder_window_s``
   ahead of them, so moderately out-of-order streams are processed in time order.
3. **Frames** — released inputs are processed in frames of ``frame_s`` seconds. The plots of one
   radar within a frame (a sector of one antenna scan) are associated together:
   Mode S address → the track with that address; otherwise global nearest neighbour with gates on
   the bias-corrected predicted position and the full innovation covariance
   (:mod:`radartracker.tracking.association`), Mode 3/A codes restricting the candidates.
   Confirmed tracks take the plots they gate before tentative ones; Mode C altitude gates too
   (:class:`AltitudeTrack`). Unassigned plots start tentative tracks, unless they lie within
   ``new_track_exclusion`` of a confirmed track. ADS-B reports go to the track with their address.
4. **Misses** — each radar's antenna phase is estimated from its plots (α(t) = φ + 2πt/T); a track
   in coverage whose azimuth the antenna swept during the frame without a plot has missed a
   detection. Tentative tracks are confirmed by M hits out of N opportunities and dropped when that
   is no longer reachable; a confirmed track that misses is *coasting*; a track without an update
   for ``delete_after_s`` or outside every radar's coverage is deleted.
5. **Estimation** — each track has a kinematic filter (a ``radartracker.motion_models`` plugin: CV,
   IMM, adaptive) fed with bias-corrected positions z − C_s ς̂ (covariance R + C_s P_ς C_sᵀ); the
   bias estimator plugin receives the raw measurements of confirmed tracks (a track's tentative
   measurements are handed over when it is confirmed) and is told when tracks end — a frame's work at
   its end, in order, so the frame reads ς̂, P_ς as they were at its start. Before that,
   every measurement of an existing track is screened (:mod:`radartracker.estimation.screening`):
   ADS-B plausibility, then d² against the track's bias-corrected prediction; a rejected one is
   counted (``*_outlier``) and touches nothing; repeated rejections re-initialise an identified track.

Every input is either used or counted under a named reason (:attr:`TrackManager.counts`).
:meth:`snapshot` / :meth:`restore` save and load the whole state (tracks, estimator, coupling
graph, queues) in a versioned, checksummed msgpack file (no pickle), so a restored manager continues
bit for bit.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import math
from collections import Counter, deque
from collections.abc import Callable, Iterable
from operator import attrgetter, itemgetter
from pathlib import Path
from typing import NamedTuple

import attrs
import numpy as np

from radartracker.tracking.association import (ALTITUDE_GATE, AltitudeTrack, altitude_d2, altitude_spread, assign,
                                                assign_tiers, candidate_pairs, gate_costs)
from radartracker.estimation.coupling import CouplingGraph
from radartracker.estimation.screening import (ACCEPT, REINIT, REJECT, AdsbPlausibility, ScreeningConfig,
                                               bias_corrected, judge)
from radartracker.tracking.admission import ClockConfig, StreamClock
from radartracker.domain import AdsbReport, BiasState, Plot, Radar
from radartracker.errors import PluginError
from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.estimation.kalman import SingularInnovation
from radartracker.estimation.motion import MotionModel
from radartracker.estimation.base import Estimator, EstimatorConfig, PlaneMeasurement
from radartracker.tracking.coverage import smooth_phases, sweep
from radartracker.tracking.prepared import PlaneConverter
from radartracker.tracking.states import StateTable
from radartracker.tracking.filters import MotionConfig, TrackFilter
from radartracker.tracking.snapshot import load_manager, save_manager
from radartracker.registry import (available_estimators, load_motion_model, make_estimator, make_filter_factory,
                                   option_fields)

log = logging.getLogger(__name__)
EVENT_KINDS = ("created", "confirmed", "updated", "coasting", "deleted")
_ZERO2, _ZERO22 = np.zeros(2), np.zeros((2, 2))
_INPUT_KINDS = {"p": "plots", "a": "adsb", "m": "positions"}  # admission key tag → counting name
_USED = {kind: f"{kind}_used" for kind in _INPUT_KINDS.values()}
# a frame's inputs' fields, read in one C loop over its list
_TIME, _RANGE, _AZIMUTH, _ALTITUDE = (attrgetter(f) for f in ("time", "range_m", "azimuth_rad", "altitude_m"))
_LAT, _LON, _NACP = attrgetter("lat"), attrgetter("lon"), attrgetter("nacp")
_ADD, _UPDATE, _REMOVE = "add", "update", "remove"  # kinds of the frame's queued estimator work
_ROW = itemgetter(3)  # an update's row of the frame's measurements
_op_kind = itemgetter(0)  # an op's kind (_flush_estimator groups runs of one kind)
# exact estimators first, the scalable one before the dense one (docs/estimators.md); decoupled is a last resort
PREFERRED_ESTIMATORS = ("coupled-sparse", "coupled", "blom", "decoupled")


def default_estimator() -> str:
    """The best installed estimator plugin: the first of ``PREFERRED_ESTIMATORS`` that is installed."""
    installed = available_estimators()
    return next((n for n in PREFERRED_ESTIMATORS if n in installed), installed[0] if installed else PREFERRED_ESTIMATORS[0])


@attrs.frozen
class ManagerConfig:
    """Settings of the TrackManager (see the module docstring for what each stage does)."""

    estimator: str = attrs.field(factory=default_estimator)
    # aircraft turn: the estimator's CV model needs process noise, or it explains a turn by biases
    estimator_config: EstimatorConfig = attrs.field(factory=lambda: EstimatorConfig(motion=MotionModel(5.0)))
    motion_model: str = "imm"  # chosen by measurement: docs/tracking.md, "Association of primary-only traffic"
    # the motion model's settings; None: its config_class() defaults, with q from estimator_config (motion_q)
    motion: MotionConfig | None = None
    motion_options: dict[str, str] = attrs.field(factory=dict)  # KEY=VALUE settings applied on top of ``motion``
    estimator_options: dict[str, str] = attrs.field(factory=dict)  # KEY=VALUE options of the estimator plugin
    gate: float = 13.82  # χ²₂ 99.9 % quantile
    confirm_m: int = 3
    confirm_n: int = 5
    delete_after_s: float = 40.0
    reorder_window_s: float = 2.0
    frame_s: float = 0.5
    max_time_jump_s: float = 3600.0
    primary_altitude_m: float = 6000.0
    primary_altitude_sd_m: float = 3500.0  # its uncertainty, added to R of plots converted at it
    search_radius_m: float = 25_000.0
    new_track_exclusion: float = 27.63  # χ²₂ 1 − 10⁻⁶: no tentative track this close to a confirmed one
    screening: ScreeningConfig = attrs.field(factory=ScreeningConfig)
    clock: ClockConfig = attrs.field(factory=ClockConfig)


def motion_q(cfg: ManagerConfig) -> dict[str, str]:
    """``cfg.motion_options``, plus ``q`` = the estimator's process noise ``estimator_config.motion.q``
    when the motion model has a ``q`` setting that neither ``motion`` nor the options set: one aircraft
    process-noise density for the estimator and the track filters unless told otherwise."""
    options = dict(cfg.motion_options)
    if cfg.motion is None and "q" not in options and "q" in option_fields(load_motion_model(cfg.motion_model).config_class):
        options["q"] = repr(cfg.estimator_config.motion.q)
    return options


class TrackEvent(NamedTuple):
    """Something that happened to a track: ``kind`` is one of ``EVENT_KINDS``, ``state`` the track's
    [x, y, vx, vy] at ``time`` (extrapolated for coasting and deleted events).

    An immutable named tuple, equal only to a TrackEvent with equal fields, not an attrs class: one is made
    for every event, about one per input, in a third of the time a frozen attrs instance takes.
    """

    time: float
    track: int
    kind: str
    status: str
    state: tuple[float, float, float, float]

    def __eq__(self, other: object) -> bool:
        return type(other) is TrackEvent and tuple.__eq__(self, other)

    def __ne__(self, other: object) -> bool:
        return not self.__eq__(other)

    __hash__ = tuple.__hash__


class FrameMeasurements(NamedTuple):
    """A frame's measurements in the plane, one row each (its plots radar by radar, its ADS-B reports, its
    unbiased positions): time, z (n×2), C_s (n×2×2, 0 for an unbiased sensor), R (n×2×2) and the radar's row
    in the manager's converter (−1: unbiased). Updates and queued estimator work refer to them by row."""

    time: np.ndarray
    z: np.ndarray
    C: np.ndarray
    R: np.ndarray
    radar: np.ndarray


_F8 = np.dtype(float)
_make_event = tuple.__new__  # _make_event(TrackEvent, fields): TrackEvent(*fields) without a Python call


@attrs.define
class ManagedTrack:
    """A track as the manager keeps it: its filter, identity codes, status and detection history."""

    id: int
    filter: TrackFilter
    status: str
    created: float
    last_update: float
    mode_s: str | None = None
    mode_3a: str | None = None
    altitude_m: float | None = None
    history: deque = attrs.field(factory=deque)
    pending: list[tuple[PlaneMeasurement, str]] = attrs.field(factory=list)  # (measurement, kind)
    n_plots: int = 0
    n_adsb: int = 0
    rejected: list = attrs.field(factory=list)  # consecutive consistent screening rejections (screening.extend_run)
    vertical: AltitudeTrack | None = None  # Mode C altitude and vertical rate, for gating
    # the filter's estimate() (t, x, P), read once after each change of the filter (TrackManager._estimate_of)
    estimate: tuple | None = attrs.field(default=None, eq=False, repr=False)


def _finite_position(m: PlaneMeasurement) -> bool:
    z, R = np.asarray(m.z, float), np.asarray(m.R, float)
    return (math.isfinite(m.time) and z.shape == (2,) and R.shape == (2, 2) and bool(np.isfinite(z).all())
            and bool(np.isfinite(R).all()) and bool(np.allclose(R, R.T)) and bool(np.all(np.linalg.eigvalsh(R) > 0)))


class TrackManager:
    """Association, track life cycle and estimation for a stream of plots and ADS-B reports.

    ``estimator`` (an instance, given each radar it lacks) and ``filter_factory`` (a callable
    returning a new :class:`TrackFilter`) replace the plugins named in ``config``.
    """

    def __init__(self, radars: list[Radar], reference: tuple[float, float], config: ManagerConfig | None = None,
                 on_event: Callable[[TrackEvent], None] | None = None, *, estimator: Estimator | None = None,
                 filter_factory: Callable[[], TrackFilter] | None = None) -> None:
        self.config = config or ManagerConfig()
        self.radars = {r.id: r for r in radars}
        self.plane = SystemPlane(*reference)
        self.reference = reference
        self.frames = {r.id: RadarFrame(r.lat, r.lon, r.height_m, self.plane) for r in radars}
        self._north = {rid: self._grid_north(r) for rid, r in self.radars.items()}
        self._converter = PlaneConverter(radars, self.frames, self.plane)  # a frame's plots and ADS-B in one pass
        rids = list(self.radars)  # radar constants as arrays by row, for per-frame geometry (_coverage)
        self._radar_rows = {"row": {rid: k for k, rid in enumerate(rids)},
                            "xy": np.array([self.frames[rid].xy for rid in rids], float).reshape(len(rids), 2),
                            "north": np.array([self._north[rid] for rid in rids], float),
                            "period": np.array([r.period_s for r in self.radars.values()], float),
                            "max_range": np.array([r.max_range_m for r in self.radars.values()], float)}
        cfg = self.config
        self.estimator = (make_estimator(cfg.estimator, cfg.estimator_config, list(self.radars), cfg.estimator_options)
                          if estimator is None else make_estimator(estimator, None, list(self.radars)))
        # the filter factory: factory() a new track filter, factory(config) one with a snapshot's config
        self._filter_cls = (make_filter_factory(cfg.motion_model, motion_q(cfg), cfg.motion)
                            if filter_factory is None else make_filter_factory(filter_factory))
        self.coupling = CouplingGraph(list(self.radars))
        self.tracks: dict[int, ManagedTrack] = {}
        self.counts: Counter[str] = Counter()
        self.on_event = on_event
        self.event_log: list[tuple] | None = None  # a list: each event appended as a row too (_emit)
        self._ids = itertools.count(1)
        self._seq = itertools.count()
        self._queue: deque = deque()  # admitted inputs no earlier than any before them (most), oldest first
        self._heap: list = []  # the others, as (time, arrival number, input)
        self._newest: float | None = None
        self._horizon = -math.inf  # everything at or before this time has been released
        self._recent: dict[tuple, float] = {}  # admission keys of inputs after the horizon (duplicates), and older
        self._recent_limit = 10_000  # the size at which the older ones are forgotten (_release)
        self._frame: int | None = None
        self._frame_items: list = []
        self._phase = np.zeros(len(rids), complex)  # each radar's antenna phase φ, by row (_track_phases)
        self._phased = np.zeros(len(rids), bool)  # which radars have one (a plot seen)
        self._events: list[TrackEvent] = []
        self._deferred: list[tuple] = []  # the frame's estimator work, applied at its end (_flush_estimator)
        self._meas: FrameMeasurements | None = None  # the frame's measurements (_convert_frame), while it runs
        self._biases: dict[str, tuple] = {}  # each radar's (ς̂, P_ς) as read in this frame (_bias)
        self._codes: dict[str, int] = {}  # Mode S address → id of its live track (_track_with_code)
        self._states = StateTable()  # the live tracks' (t, x[:4]) as one array (_predict)
        self.clock = StreamClock(self.config.clock)
        self.adsb_check = AdsbPlausibility(self.config.screening)

    # --- public API ------------------------------------------------------------------------------
    def process(self, item: Plot | AdsbReport) -> list[TrackEvent]:
        """Admit one plot or ADS-B report; return the events it caused (possibly none yet)."""
        self._events = []
        t = self._admit(item)
        if t is not None:
            newest = self._newest
            if newest is None or t >= newest:
                self._queue.append(item)
                self._newest = newest = t
            else:
                heapq.heappush(self._heap, (t, next(self._seq), item))
            self._release(newest - self.config.reorder_window_s)
        return self._events

    def process_many(self, items: Iterable[Plot | AdsbReport]) -> list[TrackEvent]:
        """Process every item, then flush; all events in order."""
        events: list[TrackEvent] = []
        for item in items:
            events.extend(self.process(item))
        events.extend(self.flush())
        return events

    def advance(self, now: float) -> list[TrackEvent]:
        """The stream's clock reached ``now`` (inputs for other consumers, e.g. the other radars of the
        distributed architecture): release and process what the reorder window allows, closing the
        last frame if it ended before that, so a quiet radar's tracks are not held back a scan."""
        self._events = []
        until = now - self.config.reorder_window_s
        self._release(until)
        if self._frame is not None and self._frame_items and (self._frame + 1) * self.config.frame_s <= until:
            self._run_frame(self._frame)
            self._frame += 1
        return self._events

    def flush(self) -> list[TrackEvent]:
        """Release and process everything still waiting (end of a recording)."""
        self._events = []
        self._release(math.inf)
        if self._frame is not None and self._frame_items:
            self._run_frame(self._frame)
        self._frame_items = []
        return self._events

    def snapshot(self, path: Path | str) -> None:
        """Save the whole state (tracks, estimator, coupling graph, queues) to ``path``, atomically
        (format: :mod:`radartracker.tracking.snapshot`)."""
        save_manager(self, path)

    @classmethod
    def restore(cls, path: Path | str, on_event: Callable[[TrackEvent], None] | None = None, *,
                estimator: Estimator | None = None, filter_factory: Callable[[], TrackFilter] | None = None) -> TrackManager:
        """A manager continuing exactly where :meth:`snapshot` left off (SnapshotError for a bad file);
        a manager given its plugins as objects is restored with new objects of the same classes."""
        mgr = load_manager(cls, path, on_event, estimator=estimator, filter_factory=filter_factory)
        mgr._codes = {tr.mode_s: tr.id for tr in mgr.tracks.values() if tr.mode_s is not None}
        for tr in mgr.tracks.values():  # read again from the filters, in the form _estimate_of gives
            tr.estimate = None
        if isinstance(mgr._phase, dict):  # an earlier release's snapshot: the antenna phases by radar id
            phases, mgr._phase = mgr._phase, np.zeros(len(mgr.radars), complex)
            for k, rid in enumerate(mgr.radars):
                mgr._phase[k], mgr._phased[k] = phases.get(rid, 0j), rid in phases
        mgr._states = StateTable(mgr.tracks.values())
        return mgr

    def accounting(self) -> dict[str, int]:
        """Counts by reason, including measurements still held by tentative tracks."""
        out = Counter(self.counts)
        for tr in self.tracks.values():
            if tr.status == "tentative":
                for _, kind in tr.pending:
                    out[f"{kind}_in_tentative_tracks"] += 1
        out["waiting_in_reorder_window"] = len(self._queue) + len(self._heap) + len(self._frame_items)
        return {k: v for k, v in out.items() if v}

    def biases(self) -> dict[str, BiasState]:
        """The current bias estimate [Δr (m), Δθ (rad)] and covariance of every radar, by radar id."""
        return {rid: self.estimator.bias(rid) for rid in self.radars}

    def confirmed_tracks(self) -> list[ManagedTrack]:
        """The live tracks that are confirmed or coasting (``tracks`` holds every live track by id)."""
        return [t for t in self.tracks.values() if t.status in ("confirmed", "coasting")]

    # --- admission and reordering ----------------------------------------------------------------
    def _admit(self, item: object) -> float | None:
        """``item``'s time if it is admitted (then kept as a key for duplicates), else ``None`` (counted)."""
        if isinstance(item, Plot):
            t = item.time
            if item.radar not in self.radars:
                return self._reject("plots_unknown_radar", item)
            key = ("p", item.radar, t, item.range_m, item.azimuth_rad)
        elif isinstance(item, AdsbReport):
            t = item.time
            key = ("a", item.icao24, t, item.lat, item.lon)
        elif isinstance(item, PlaneMeasurement) and item.radar is None and _finite_position(item):
            t = item.time
            key = ("m", item.aircraft, t, float(item.z[0]), float(item.z[1]))
        else:
            return self._reject("invalid_input", item)
        newest = self._newest
        if newest is not None and t > newest + self.config.max_time_jump_s:
            return self._reject(f"{_INPUT_KINDS[key[0]]}_time_jump", item)
        if t <= self._horizon:
            return self._reject(f"{_INPUT_KINDS[key[0]]}_late", item)
        if key in self._recent:
            return self._reject(f"{_INPUT_KINDS[key[0]]}_duplicate", item)
        if not self.clock.admit(t):
            return self._reject(f"{_INPUT_KINDS[key[0]]}_time_jump", item)
        self._recent[key] = t
        return t

    def _reject(self, reason: str, item: object) -> None:
        if self.counts[reason] < 5:
            log.warning("rejected (%s): %r", reason, item)
        self.counts[reason] += 1

    def _release(self, until: float) -> None:
        """Hand the inputs up to ``until`` to their frames in (time, arrival) order. An input waits in the heap
        only if it came after a later one, so an input of the queue comes first at equal times."""
        queue, heap, frame_s, floor = self._queue, self._heap, self.config.frame_s, math.floor
        while True:
            if heap and (not queue or heap[0][0] < queue[0].time):
                if heap[0][0] > until:
                    break
                t, _, item = heapq.heappop(heap)
            elif queue and (t := queue[0].time) <= until:
                item = queue.popleft()
            else:
                break
            self._horizon = t
            frame = floor(t / frame_s)
            if frame != self._frame:  # the first input, or one past the frame being gathered
                if self._frame is None:
                    self._frame = frame
                while frame > self._frame:
                    self._run_frame(self._frame)
                    # frames without input still sweep the antennas (misses) — a long gap is one sweep
                    self._frame = self._frame + 1 if frame - self._frame < 240 else frame
            self._frame_items.append(item)
        if len(self._recent) > self._recent_limit:  # forget keys at or before the horizon: such an input is late
            self._recent = {k: t for k, t in self._recent.items() if t > self._horizon}
            # at twice what is left (or 10 000): a table of a long reorder window is not swept every few inputs
            self._recent_limit = max(10_000, 2 * len(self._recent))

    # --- one frame ----------------------------------------------------------------------------
    def _run_frame(self, frame: int) -> None:
        fs = self.config.frame_s
        t_a, t_b = frame * fs, (frame + 1) * fs
        items, self._frame_items = self._frame_items, []
        live = list(self.tracks.values())
        pred = self._predict(live, 0.5 * (t_a + t_b))
        pred["span"] = (t_a, t_b)
        updates: list[tuple] = []  # (time, seq, track or None, row of the frame's measurements, input)
        by_radar: dict[str, list[Plot]] = {}  # the frame's plots of each radar, in order (one pass, not one per radar)
        reports, positions = [], []
        for p in items:
            if isinstance(p, Plot):
                ps = by_radar.get(p.radar)
                if ps is None:
                    by_radar[p.radar] = [p]
                else:
                    ps.append(p)
            elif isinstance(p, AdsbReport):
                reports.append(p)
            else:
                positions.append(p)
        meas, ok, azimuth = self._convert_frame(by_radar, reports, positions, live)
        self._meas = meas
        self._track_phases(meas.radar[:len(azimuth)], meas.time[:len(azimuth)], azimuth)
        first, base = {}, 0  # the first row of each radar's plots in the frame's measurements
        for rid, plots in by_radar.items():
            first[rid], base = base, base + len(plots)
        assigned = self._associate(by_radar, first, ok, live, pred, updates)
        seq = self._seq
        for k, rep in enumerate(reports, base):
            updates.append((rep.time, next(seq), self._track_with_code(rep.icao24), k, rep))
        for k, m in enumerate(positions, base + len(reports)):
            updates.append(self._position_measurement(m, k, live, pred))
        self._misses(live, pred, assigned, t_a, t_b)
        updates.sort()  # by (time, seq): seq is unique, so the tracks and measurements are never compared
        self._apply_all(updates)
        self._sweep(live, pred, t_b)
        self._flush_estimator()
        self._meas = None

    @staticmethod
    def _estimate_of(tr: ManagedTrack) -> tuple:
        """``tr.filter.estimate()``, kept until the filter changes (the manager reads it once per frame for
        every live track, and for gating, screening and events), its state a contiguous float64 vector
        (so that the frame's states are one join of their bytes, :meth:`_predict`)."""
        if tr.estimate is None:
            tr.estimate = TrackManager._normalized(tr.filter.estimate())
        return tr.estimate

    @staticmethod
    def _normalized(e: tuple) -> tuple:
        """Estimate (t, x, P) with x a contiguous float64 vector."""
        x = e[1]
        if type(x) is not np.ndarray or x.dtype is not _F8 or x.ndim != 1 or not x.flags.c_contiguous:
            return e[0], np.ascontiguousarray(x, float).ravel(), e[2]
        return e

    def _predict(self, live: list[ManagedTrack], t: float) -> dict[str, np.ndarray]:
        """Straight-line extrapolation of every live track to ``t`` (for search, misses, coverage), as
        arrays over the frame's tracks; the filters' own predictions are computed only for gating candidates."""
        pos = self._states.positions(live, self._estimate_of, t)
        # identities are fixed while a frame is associated: index them once per frame, not per radar
        index = {tr.mode_s: i for i, tr in enumerate(live)}
        index.pop(None, None)
        index.pop("", None)
        return {"pos": pos, "t": t, "exact": {}, "index": index}

    @staticmethod
    def _exact(live: list[ManagedTrack], pred: dict, idx: np.ndarray) -> tuple[np.ndarray, ...]:
        """The filters' predictions (position, velocity, position covariance) of tracks ``idx``."""
        cache, t = pred["exact"], pred["t"]
        for i in np.unique(idx):
            if i not in cache:
                tr = live[i]
                try:
                    x, P = tr.filter.predict(max(t, TrackManager._estimate_of(tr)[0]))
                    cache[i] = (x[:2], x[2:], P[:2, :2])
                except ValueError:  # the filter refuses this step: the track cannot be gated
                    cache[i] = (np.full(2, np.nan), np.zeros(2), np.eye(2))
        return tuple(np.array([cache[i][k] for i in idx]) for k in range(3))

    def _coverage(self, pred: dict) -> tuple[np.ndarray, np.ndarray]:
        """Which radar's antenna swept which of the frame's tracks (radars × tracks, rows of radars without
        a phase all False) and which tracks some radar covers, in one compiled pass per frame
        (:func:`radartracker.tracking.coverage.sweep`); the frame is ``pred["span"]``."""
        if "covered" not in pred:
            c, (t_a, t_b) = self._radar_rows, pred["span"]
            m, n = len(c["period"]), len(pred["pos"])
            start = np.angle(self._phase) + 2 * math.pi * t_a / c["period"]
            swept, covered = np.empty((m, n), bool), np.empty(n, bool)
            sweep(np.ascontiguousarray(pred["pos"], float), c["xy"], c["north"], c["max_range"], start,
                  2 * math.pi * (t_b - t_a) / c["period"], self._phased, swept, covered)
            pred["swept"], pred["covered"] = swept, covered
        return pred["swept"], pred["covered"]

    def _convert_frame(self, by_radar: dict[str, list[Plot]], reports: list[AdsbReport], positions: list[PlaneMeasurement],
                       live: list[ManagedTrack]) -> tuple[FrameMeasurements, np.ndarray, np.ndarray]:
        """The frame's measurements in the plane, in rows: its plots radar by radar, then its ADS-B reports,
        then its unbiased positions; which plots have a valid geometry, and the plots' azimuths. The plots and ADS-B positions are
        converted in one pass (:class:`~radartracker.tracking.prepared.PlaneConverter`): a plot at its Mode C
        altitude, else its Mode S track's, else ``primary_altitude_m`` with that guess's spread added to R;
        an ADS-B report has R = σ(NACp)² I, C = 0."""
        plots = list(itertools.chain.from_iterable(by_radar.values()))
        n, primary = len(plots), self.config.primary_altitude_m
        heights = list(map(_ALTITUDE, plots))
        unknown = None in heights
        if unknown:
            by_code = ({t.mode_s: t for t in live if t.mode_s}
                       if any(h is None and p.mode_s for h, p in zip(heights, plots)) else {})
            heights = [h if h is not None else (by_code[p.mode_s].altitude_m if p.mode_s in by_code and
                                                by_code[p.mode_s].altitude_m is not None else primary)
                       for h, p in zip(heights, plots)]
        alt = np.array(heights, float)
        rho = np.fromiter(map(_RANGE, plots), float, n)
        theta = np.fromiter(map(_AZIMUTH, plots), float, n)
        m, k = len(reports), len(by_radar)
        lat = np.fromiter(map(_LAT, reports), float, m)
        lon = np.fromiter(map(_LON, reports), float, m)
        nacp = np.fromiter(map(_NACP, reports), np.int64, m)
        # each radar's plots are together: its row and count, not a row looked up plot by plot
        z, C, R, radar, ok = self._converter.convert_frame(
            np.fromiter(map(self._converter.row.__getitem__, by_radar), np.int64, k),
            np.fromiter(map(len, by_radar.values()), np.int64, k), rho, theta, alt, lat, lon, nacp)
        rows = radar[:n]
        # an assumed altitude is uncertain: near the radar its error moves the plot by km along the beam
        if unknown:
            guess = np.fromiter((p.altitude_m is None for p in plots), bool, n) & (alt == primary)
            if guess.any():  # all radars' at once (element by element: the same numbers as radar by radar)
                R[:n][guess] += altitude_spread(C[:n][guess], rho[guess], alt[guess],
                                                self._converter.height[rows[guess]], self.config.primary_altitude_sd_m)
        if positions:  # unbiased rows: C = 0, radar row −1
            zm = np.array([np.asarray(p.z, float) for p in positions], float).reshape(len(positions), 2)
            Rm = np.array([np.asarray(p.R, float) for p in positions], float).reshape(len(positions), 2, 2)
            z = np.concatenate([z, zm])
            C = np.concatenate([C, np.zeros((len(positions), 2, 2))])
            R = np.concatenate([R, Rm])
            radar = np.concatenate([radar, np.full(len(positions), -1, np.int64)])
        times = np.fromiter(map(_TIME, itertools.chain(plots, reports, positions)), float, len(z))
        return FrameMeasurements(times, z, C, R, radar), ok, theta

    def _associate(self, by_radar: dict[str, list[Plot]], first: dict[str, int], valid: np.ndarray,
                   live: list[ManagedTrack], pred: dict, updates: list) -> dict[str, set[int]]:
        """The frame's plots to their tracks, as updates, radar by radar in the radars' order (which plot of a
        time is applied first; ``first``: the row of each radar's first plot in the frame's measurements): by
        Mode S address, the others by gating (:meth:`_gate`). Returns the indices in ``live`` of the tracks each
        radar's plots went to (module docstring, step 3). One call per frame, not per radar: light traffic has
        a plot or two per radar and frame."""
        seq, index, counts, valid = self._seq, pred["index"], self.counts, valid.tolist()
        assigned: dict[str, set[int]] = {}
        for rid in self.radars:
            plots = by_radar.get(rid)
            if plots is None:
                continue
            base = first[rid]
            taken: set[int] = set()
            rest: list[int] = []
            for k, p in enumerate(plots):
                code = p.mode_s
                if not valid[base + k]:
                    counts["plots_impossible_geometry"] += 1
                elif code is None:
                    rest.append(k)
                elif (i := index.get(code)) is None:
                    updates.append((p.time, next(seq), None, base + k, p))
                elif i in taken:
                    counts["plots_duplicate_in_scan"] += 1
                else:
                    taken.add(i)
                    updates.append((p.time, next(seq), live[i], base + k, p))
            if rest:
                self._gate(rid, plots, base, rest, taken, live, pred, updates)
            assigned[rid] = taken
        return assigned

    def _gate(self, rid: str, plots: list[Plot], base: int, rest: list[int], taken: set[int], live: list[ManagedTrack],
              pred: dict, updates: list) -> None:
        """Radar ``rid``'s plots ``rest`` without a Mode S address (their rows ``base`` + k) to tracks by gating on
        position (bias-corrected), Mode 3/A code and Mode C altitude, the nearest in gate first (confirmed tracks
        before tentative ones); a plot near a confirmed track that is not its own starts no track. Adds the
        tracks taken to ``taken``."""
        end = base + len(plots)
        meas = self._meas
        z, C, R = meas.z[base:end], meas.C[base:end], meas.R[base:end]
        seq = self._seq
        if "codes" not in pred:  # the tracks' Mode 3/A codes and which have a Mode S address: only for such plots
            pred["codes"] = np.array([tr.mode_3a for tr in live], object).reshape(len(live))
            pred["mode_s"] = np.array([tr.mode_s is not None for tr in live], bool).reshape(len(live))
        free = ~pred["mode_s"]
        free[list(taken)] = False
        codes = pred["codes"]
        allowed = np.array([free & ((codes == None) | (codes == plots[k].mode_3a) | (plots[k].mode_3a is None))  # noqa: E711
                            for k in rest]).reshape(len(rest), len(live))
        zr = z[rest]
        pairs = candidate_pairs(zr, pred["pos"], self.config.search_radius_m, allowed)
        bias, bias_cov = self._bias(rid)
        if len(pairs):
            pos, vel, cov = self._exact(live, pred, pairs[:, 1])
            dt = np.array([plots[rest[k]].time for k in pairs[:, 0]]) - pred["t"]
            d2, cost = gate_costs(zr[pairs[:, 0]], C[rest][pairs[:, 0]], R[rest][pairs[:, 0]], bias, bias_cov,
                                  pos + vel * dt[:, None], cov)
            # Mode C: a pair whose altitudes disagree is not a pair; d_h² joins the cost (its mean, 1, if unknown)
            h = np.array([np.nan if plots[rest[k]].altitude_m is None else plots[rest[k]].altitude_m for k in pairs[:, 0]])
            d2h = altitude_d2(h, [live[i].vertical for i in pairs[:, 1]], dt + pred["t"])
            d2 = np.where(d2h > ALTITUDE_GATE, np.inf, d2)
            cost = cost + np.where(np.isnan(d2h), 1.0, d2h)
            tier = np.array([t.status == "tentative" for t in live], int)
            matches, in_gate = assign_tiers(pairs, d2, cost, self.config.gate, tier, self.config.new_track_exclusion)
        else:
            matches, in_gate = {}, np.zeros(0, bool)
        for j, k in enumerate(rest):
            tr = live[matches[j]] if j in matches else None
            if tr is not None:
                taken.add(matches[j])
            elif j < len(in_gate) and in_gate[j]:  # near a confirmed track, not its plot: no new track
                self.counts["plots_near_confirmed_track"] += 1
                continue
            updates.append((plots[k].time, next(seq), tr, base + k, plots[k]))

    def _track_phases(self, rows: np.ndarray, t: np.ndarray, theta: np.ndarray) -> None:
        """Each radar's antenna phase φ (α(t) = φ + 2πt/T), smoothed over its plots in order (radar rows
        ``rows``, times ``t`` and azimuths ``theta`` of the frame's plots, as converted):
        p ← 0.98 p + exp(i(θ − 2πt/T)), the exponentials of all the frame's plots in one array call, the
        recurrences in one compiled loop (:func:`~radartracker.tracking.coverage.smooth_phases`)."""
        if not len(theta):
            return
        terms = np.exp(1j * (theta - 2 * math.pi * t / self._radar_rows["period"][rows]))
        smooth_phases(self._phase, terms, rows)
        self._phased[rows] = True

    def _track_with_code(self, code: str | None) -> ManagedTrack | None:
        """The live track with Mode S address ``code`` (at most one: a code's track is looked up before
        one is started), from the index kept as tracks start and end (rebuilt on restore)."""
        return None if code is None else self.tracks.get(self._codes.get(code, -1))

    def _position_measurement(self, m: PlaneMeasurement, row: int, live: list[ManagedTrack], pred: dict) -> tuple:
        """The update of an unbiased position (e.g. a triangulated fix), row ``row`` of the frame's
        measurements: its track by identity, else by gating."""
        tr = next((t for t in live if m.aircraft is not None and t.mode_s == m.aircraft), None)
        if tr is None and live and m.aircraft is None:
            pairs = candidate_pairs(m.z[None, :], pred["pos"], self.config.search_radius_m)
            if len(pairs):
                pos, vel, cov = self._exact(live, pred, pairs[:, 1])
                n = len(pairs)
                d2, cost = gate_costs(np.repeat(m.z[None], n, 0), np.zeros((n, 2, 2)), np.repeat(m.R[None], n, 0),
                                      np.zeros(2), np.zeros((2, 2)), pos + vel * (m.time - pred["t"]), cov)
                best = dict(assign(pairs, d2, cost, self.config.gate))
                tr = live[best[0]] if 0 in best else None
        return m.time, next(self._seq), tr, row, m

    # --- applying updates -------------------------------------------------------------------------
    def _apply_all(self, updates: list[tuple]) -> None:
        """The frame's updates (time, seq, track, row, input), in order. With screening on, the ADS-B
        reports are checked first (:class:`AdsbPlausibility`, its state per address evolving in the same
        order), and the measurements of confirmed tracks go to their filters in one
        :meth:`TrackFilter.screen_many`; those it did are booked here, as :meth:`_apply` books an accepted
        measurement of a confirmed track, the others go through :meth:`_apply`, each at its place in the order."""
        if not self.config.screening.enabled:
            for _, _, tr, row, src in updates:
                self._apply(tr, row, src)
            return
        updates = self._plausible(updates)
        rows, done, (x, P) = self._screen_confirmed(updates)
        plan = [-1] * len(updates)  # the row in screen_many's output of each update it did, else −1
        for i in np.flatnonzero(done).tolist():
            plan[rows[i]] = i
        # the states as lists for the events, unless the estimates are as estimate() gives them (any length)
        states = x.tolist() if type(x) is np.ndarray and x.dtype is _F8 and x.shape[1:] == (4,) else None
        changed, defer, record, apply, took = (self._states.changed, self._deferred.append, self._record, self._apply,
                                               self._took)
        for (_, _, tr, row, src), i in zip(updates, plan):
            if i < 0:
                apply(tr, row, src)
                continue
            t = float(src.time)
            if tr.rejected:  # screening accepted it: a run of rejections ends
                tr.rejected = []
            tr.estimate = e = (t, x[i], P[i]) if states is not None else self._normalized((t, x[i], P[i]))
            changed(tr)
            radar, kind = (src.radar, "plots") if type(src) is Plot else (None, "adsb")
            took(tr, src, kind)
            defer((_UPDATE, src.time, tr.id, radar, row, kind))
            tr.status = "confirmed"
            if states is None:
                self._emit(src.time, tr, "updated")
            else:  # _emit's event, its state at hand
                record(_make_event(TrackEvent, (t, tr.id, "updated", "confirmed", tuple(states[i]))), e[2], tr)

    def _plausible(self, updates: list[tuple]) -> list[tuple]:
        """``updates`` without the ADS-B reports :class:`AdsbPlausibility` rejects (counted), all of the
        frame's checked in order in one :meth:`AdsbPlausibility.check_many`."""
        idx = [j for j, u in enumerate(updates) if type(u[4]) is AdsbReport]
        if not idx:
            return updates
        reports = [updates[j][4] for j in idx]
        rows = np.fromiter(map(_ROW, map(updates.__getitem__, idx)), np.int64, len(idx))
        meas = self._meas
        verdicts = self.adsb_check.check_many([r.icao24 for r in reports], meas.time[rows], meas.z[rows],
                                              np.sqrt(meas.R[rows, 0, 0]), np.fromiter(map(_NACP, reports), np.int64, len(idx)))
        dropped = set()
        for j, why in zip(idx, verdicts):
            if why is not None:
                self.counts[why] += 1
                dropped.add(j)
        return [u for j, u in enumerate(updates) if j not in dropped] if dropped else updates

    def _screen_confirmed(self, updates: list[tuple]) -> tuple[list[int], np.ndarray, tuple]:
        """The radar and ADS-B measurements of confirmed tracks, screened and applied in order by one
        :meth:`TrackFilter.screen_many`: (their indices in ``updates``, done, (χ̂, P̂)), by its rows. A track
        with another kind of measurement in the frame, or whose first one is older than its estimate, is left
        to :meth:`_apply`."""
        rows: list[int] = []
        excluded: set[int] = set()
        for j, (t, _, tr, _, src) in enumerate(updates):
            if tr is None or tr.status == "tentative":
                continue
            if type(src) is PlaneMeasurement or t < (tr.estimate or self._estimate_of(tr))[0]:
                excluded.add(tr.id)
            else:
                rows.append(j)
        if excluded:
            rows = [j for j in rows if updates[j][2].id not in excluded]
        if not rows:
            return [], np.zeros(0, bool), (np.zeros((0, 4)), np.zeros((0, 4, 4)))
        cls = type(updates[rows[0]][2].filter)
        rows = [j for j in rows if type(updates[j][2].filter) is cls]  # others one by one (mixed models are rare)
        n = len(rows)
        chosen = [updates[j] for j in rows]
        filters = [u[2].filter for u in chosen]
        meas = self._meas
        g = np.fromiter(map(_ROW, chosen), np.int64, n)
        times, z, C, R, radar = meas.time[g], meas.z[g], meas.C[g], meas.R[g], meas.radar[g]
        # the (ς̂, P_ς) of the radars measured here, as the frame reads them (zeros for the unbiased, radar −1)
        # (a dict of the few radar rows present, by first appearance: np.unique costs ~50 µs a call, a frame's fixed cost)
        keys = radar.tolist()
        present = {k: i for i, k in enumerate(dict.fromkeys(keys))}
        ids = self._converter.ids
        table = [(_ZERO2, _ZERO22) if k < 0 else self._bias(ids[k]) for k in present]
        index = np.fromiter(map(present.__getitem__, keys), np.int64, n)
        bias = np.array([b for b, _ in table], float)[index]
        bias_cov = np.array([P for _, P in table], float)[index]
        cfg = self.config.screening
        gate = np.where(radar >= 0, cfg.gate("plots", False), cfg.gate("adsb", False))
        try:
            _, _, _, done, x, P = cls.screen_many(filters, times, z, C, R, bias, bias_cov, gate)
        except Exception as exc:  # a plugin's bug: name it and the frame's first such measurement
            raise self._plugin_failed(f"motion model {self._filter_cls.name!r}", chosen[0][2].id, times[0], exc) from exc
        return rows, done, (x, P)

    def _apply(self, tr: ManagedTrack | None, row: int, src: Plot | AdsbReport | PlaneMeasurement) -> None:
        """Update ``row`` of the frame's measurements (its input ``src``) for track ``tr`` (None: find or start
        one): screening, the track's filter and life cycle, the estimator's queue and the events."""
        meas = self._meas
        z, C, R = meas.z[row], meas.C[row], meas.R[row]
        if isinstance(src, Plot):
            radar, kind, code = src.radar, "plots", src.mode_s
            bias, bias_cov = self._bias(radar)
        else:
            radar, bias, bias_cov = None, _ZERO2, _ZERO22
            if isinstance(src, AdsbReport):
                kind, code = "adsb", src.icao24
            else:
                kind, code = "positions", (src.aircraft if isinstance(src.aircraft, str) else None)
        zc = Rc = None  # z − C ς̂, R + C P_ς Cᵀ: from screening, else made below
        updated = False  # by screening, when the measurement passed
        if tr is not None and tr.id not in self.tracks:  # re-initialised earlier in this frame
            tr = None
        if tr is None:  # an ADS-B report may find the track a plot of this frame just started
            tr = self._track_with_code(code)
        if self.config.screening.enabled:  # (an ADS-B report has passed AdsbPlausibility: _apply_all)
            verdict = ACCEPT
            if tr is not None:
                verdict, zc, Rc, updated = self._screen(tr, z, C, R, bias, bias_cov, src.time, kind)
            if verdict == REJECT:
                return
            if verdict == REINIT:  # the track, not its measurements, is wrong: start again from this one
                log.warning("track %s (%s) re-initialised after %d rejected measurements", tr.id, tr.mode_s,
                            self.config.screening.reinit_after)
                self.counts["tracks_reinitialised"] += 1
                self._delete(tr, src.time)
                tr = None
        if zc is None:
            zc, Rc = bias_corrected(z, C, R, bias, bias_cov) if radar is not None else (z, R)
        if tr is None:
            filt = self._filter_cls()
            try:
                filt.start(src.time, zc, Rc)
            except Exception as exc:
                raise self._plugin_failed(f"motion model {self._filter_cls.name!r}", None, src.time, exc) from exc
            tr = ManagedTrack(next(self._ids), filt, "tentative", src.time, src.time, mode_s=code,
                              history=deque(maxlen=self.config.confirm_n))
            self.tracks[tr.id] = tr
            self._states.add(tr)
            if code is not None:
                self._codes[code] = tr.id
            self._emit(src.time, tr, "created")
        elif not updated:
            try:
                tr.estimate = None
                self._states.changed(tr)
                tr.filter.update(src.time, zc, Rc)
            except ValueError as exc:  # SingularInnovation, or a filter refusing the time step
                self.counts["plots_refused_by_filter" if radar else "unbiased_refused_by_filter"] += 1
                log.warning("track %s refused a measurement at t=%s: %s", tr.id, src.time, exc)
                return
            except Exception as exc:
                raise self._plugin_failed(f"motion model {self._filter_cls.name!r}", tr.id, src.time, exc) from exc
        self._took(tr, src, kind)
        if tr.status == "tentative":
            tr.pending.append((PlaneMeasurement(src.time, tr.id, radar, z, C, R), kind))
            if sum(tr.history) >= self.config.confirm_m:
                self._confirm(tr)
        else:
            self._estimate(src.time, tr.id, radar, row, kind)
            tr.status = "confirmed"
            self._emit(src.time, tr, "updated")

    @staticmethod
    def _took(tr: ManagedTrack, src: Plot | AdsbReport | PlaneMeasurement, kind: str) -> None:
        """Track ``tr`` took measurement ``src`` of ``kind``: its last update, counts, Mode 3/A code, altitude
        with its vertical filter, and a detection in its history."""
        tr.last_update = src.time
        if kind == "plots":
            tr.n_plots += 1
            tr.mode_3a = src.mode_3a or tr.mode_3a
            h = src.altitude_m
            if h is not None:
                tr.altitude_m = h
                if tr.vertical is None:
                    tr.vertical = AltitudeTrack.start(src.time, h)
                else:
                    tr.vertical.update(src.time, h)
        elif kind == "adsb":
            tr.n_adsb += 1
            if src.altitude_m is not None:
                tr.altitude_m = src.altitude_m
        tr.history.append(True)

    def _screen(self, tr: ManagedTrack, z: np.ndarray, C: np.ndarray, R: np.ndarray, bias: np.ndarray,
                bias_cov: np.ndarray, t: float, kind: str) -> tuple[str, np.ndarray | None, np.ndarray | None, bool]:
        """Screening verdict for measurement (z, C, R) of track ``tr`` with its radar's bias estimate, the
        bias-corrected (zc, Rc = R + C P_ς Cᵀ) it judged (None, None when the filter refuses the step) and
        whether the filter took it: d² against the track filter's prediction, so S = P̄_pp + C P_ς Cᵀ + R,
        and a measurement in the gate updates the filter in the same call (:meth:`TrackFilter.screen`)
        unless it is older than the track's estimate (judged against that, then updated at its time)."""
        cfg, tentative = self.config.screening, tr.status == "tentative"
        t_est = (tr.estimate or self._estimate_of(tr))[0]
        gate = cfg.gate(kind, tentative) if t >= t_est else None
        try:
            if gate is not None:
                tr.estimate = None
                self._states.changed(tr)
            d2, zc, Rc, updated = tr.filter.screen(max(t, t_est), z, C, R, bias, bias_cov, gate)
        except ValueError:  # the filter refuses this step; its update refuses it too and counts it
            return ACCEPT, None, None, False
        except Exception as exc:  # a plugin's bug: name it, its track and the time
            raise self._plugin_failed(f"motion model {self._filter_cls.name!r}", tr.id, t, exc) from exc
        if gate is not None and d2 <= gate:  # judge's ACCEPT, which ends a run of rejections (the common case)
            if tr.rejected:
                tr.rejected = []
            return ACCEPT, zc, Rc, updated
        verdict, tr.rejected = judge(cfg, kind, d2, tr.rejected, tr.mode_s is not None, tentative, t, zc, Rc)
        if verdict == REJECT:
            self.counts[f"{kind}_outlier"] += 1
        return verdict, zc, Rc, updated

    def _confirm(self, tr: ManagedTrack) -> None:
        first = tr.pending[0][0]
        sd_v = tr.filter.config.prior_sd_velocity_mps
        prior = np.diag([1e8, 1e8, sd_v**2, sd_v**2])
        self._deferred.append((_ADD, first.time, tr.id, np.array([*first.z, 0.0, 0.0]), prior))
        for m, kind in tr.pending:
            self._estimate(m.time, m.aircraft, m.radar, (m.z, m.C, m.R), kind)
        tr.pending = []
        tr.status = "confirmed"
        self._emit(tr.last_update, tr, "confirmed")

    def _estimate(self, time: float, aircraft: int, radar: str | None, meas: int | tuple, kind: str) -> None:
        """One measurement of a confirmed track for the estimator, queued until the frame's end
        (:meth:`_flush_estimator`): ``meas`` a row of the frame's measurements, or (z, C, R) of an earlier
        frame's (the manager's own arrays, nothing writes into them)."""
        self._deferred.append((_UPDATE, time, aircraft, radar, meas, kind))

    def _bias(self, radar: str) -> tuple[np.ndarray, np.ndarray]:
        """(ς̂, P_ς) of ``radar``, read from the estimator once per frame: it changes only at the frame's end."""
        b = self._biases.get(radar)
        if b is None:
            b = self._biases[radar] = self.estimator.bias_arrays(radar)
        return b

    def _flush_estimator(self) -> None:
        """The frame's estimator and coupling-graph work in the order it arose: aircraft added at
        confirmation, measurements (each run of them in one :meth:`Estimator.update_many`), aircraft
        removed. The frame's screening, gating and track filters all read the bias estimate as it was
        at the frame's start (docs/design-notes.md, "The TrackManager reads the bias estimate once per frame")."""
        ops, self._deferred = self._deferred, []
        self._biases = {}
        name = f"estimator {self.estimator.name!r}"
        for kind, group in itertools.groupby(ops, _op_kind):
            if kind is _UPDATE:
                self._update_run(list(group))
                continue
            for op in group:
                if kind is _ADD:
                    _, time, key, x0, prior = op
                    try:
                        self.estimator.add_aircraft(key, time, x0, prior)
                    except Exception as exc:
                        raise self._plugin_failed(name, key, time, exc) from exc
                    self.coupling.add_aircraft(key)
                else:
                    _, time, key = op
                    try:
                        self.estimator.remove_aircraft(key)
                    except Exception as exc:
                        raise self._plugin_failed(name, key, time, exc) from exc
                    self.coupling.remove_aircraft(key)

    def _update_run(self, run: list[tuple]) -> None:
        """Measurements ``run`` (queued by :meth:`_estimate`) to the estimator in one ``update_many``, then to
        the coupling graph and the counts in one call each; one the estimator refuses as singular is counted
        (``*_singular``) and the rest of the run goes on after it."""
        start = 0
        while start < len(run):
            part = run[start:] if start else run
            _, time, aircraft, radar, rows, kind = zip(*part)
            n = len(part)
            done, failed = n, None
            z, C, R = self._measurements(rows)
            try:
                self.estimator.update_many(time, aircraft, radar, z, C, R)
            except SingularInnovation as exc:
                done, failed = getattr(exc, "index", 0), exc
            except Exception as exc:
                i = getattr(exc, "index", 0)
                raise self._plugin_failed(f"estimator {self.estimator.name!r}", aircraft[i], time[i], exc) from exc
            if done == n:
                self.coupling.observe_many(aircraft, radar, time)
                self.counts.update(map(_USED.__getitem__, kind))
            else:
                self.coupling.observe_many(aircraft[:done], radar[:done], time[:done])
                self.counts.update(map(_USED.__getitem__, kind[:done]))
                self.counts[f"{kind[done]}_singular"] += 1
                log.warning("estimator refused a measurement of track %s: %s", aircraft[done], failed)
                done += 1
            start += done

    def _measurements(self, rows: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(z, C, R) of queued measurements as new arrays: each a row of the frame's measurements, or (z, C, R)
        of an earlier frame's (a confirmed track's tentative ones, written in one by one)."""
        n, frame = len(rows), self._meas
        try:
            g = np.fromiter(rows, np.int64, n)
            earlier: list[int] = []
        except TypeError:
            g = np.fromiter((r if type(r) is int else -1 for r in rows), np.int64, n)
            earlier = np.flatnonzero(g < 0).tolist()
        if frame is not None:
            z, C, R = frame.z[g], frame.C[g], frame.R[g]
        else:  # none of this frame
            z, C, R = np.empty((n, 2)), np.empty((n, 2, 2)), np.empty((n, 2, 2))
        for k in earlier:
            z[k], C[k], R[k] = rows[k]
        return z, C, R

    # --- misses, deletion, events ------------------------------------------------------------------
    def _misses(self, live: list[ManagedTrack], pred: dict, assigned: dict[str, set[int]], t_a: float, t_b: float) -> None:
        """Tracks in a radar's coverage whose azimuth its antenna swept in [t_a, t_b) without a plot
        (``assigned``: the indices in ``live`` of the tracks each radar's plots went to): one array pass
        over radars × the frame's tracks (:meth:`_coverage`), then a loop over the misses only."""
        if not live:
            return
        radar, track = np.nonzero(self._coverage(pred)[0])  # radar by radar, as the antennas swept
        if not len(track):
            return
        row = self._radar_rows["row"]  # a plot of this radar in the frame: not missed
        hits = {(row[rid], i) for rid, taken in assigned.items() for i in taken}
        for r, i in zip(radar.tolist(), track.tolist()):
            tr = live[i]
            if (r, i) in hits or tr.created >= t_a:  # started in this frame: not missed
                continue
            tr.history.append(False)
            if tr.status == "confirmed":
                tr.status = "coasting"
                self._emit(t_b, tr, "coasting")

    def _sweep(self, live: list[ManagedTrack], pred: dict, now: float) -> None:
        """Delete tracks that cannot be confirmed any more, are stale or left every radar's coverage (one
        pass over the frame's tracks: a few array calls cost more than it at light traffic)."""
        if not live:
            return
        cfg = self.config
        stale, hopeless = cfg.delete_after_s, cfg.confirm_n - cfg.confirm_m  # (misses a tentative track can afford)
        for tr, covered in zip(live, self._coverage(pred)[1].tolist()):
            if ((now - tr.last_update > stale or not (covered or tr.n_adsb)
                 or tr.status == "tentative" and len(tr.history) - sum(tr.history) > hopeless) and tr.id in self.tracks):
                self._delete(tr, now)

    def _delete(self, tr: ManagedTrack, now: float) -> None:
        del self.tracks[tr.id]
        self._states.remove(tr.id)
        if tr.mode_s is not None and self._codes.get(tr.mode_s) == tr.id:
            del self._codes[tr.mode_s]
        if tr.status == "tentative":
            for _, kind in tr.pending:
                self.counts[f"{kind}_in_dropped_tentative_tracks"] += 1
        else:
            self._deferred.append((_REMOVE, now, tr.id))
        tr.status = "deleted"
        self._emit(now, tr, "deleted")

    def _plugin_failed(self, plugin: str, track: int | None, time: float, exc: Exception) -> PluginError:
        """The error a run ends with when a plugin raises: names the plugin, the aircraft and the time."""
        tr = self.tracks.get(track) if track is not None else None
        who = "a new track" if track is None else f"track {track}" + (f" (Mode S {tr.mode_s})" if tr and tr.mode_s else "")
        return PluginError(f"{plugin} failed on {who} at t={time:.3f} s: {type(exc).__name__}: {exc}")

    def _emit(self, time: float, tr: ManagedTrack, kind: str) -> None:
        """Make the event, hand it to ``on_event`` and, when :attr:`event_log` is a list, append its row
        (event, P, altitude_m, mode_s, mode_3a): P the filter's covariance of the event's state when that
        is the estimate at the event's time (not extrapolated), else None, and the track's identity now."""
        t0, x, P = tr.estimate or self._estimate_of(tr)
        x0, y0, vx, vy = x.tolist()[:4]
        if time > t0:  # coasting/deleted events happen after the last update: report the position then
            x0, y0 = x0 + vx * (time - t0), y0 + vy * (time - t0)
        self._record(_make_event(TrackEvent, (float(time), tr.id, kind, tr.status, (x0, y0, vx, vy))),
                     P if t0 == time else None, tr)

    def _record(self, ev: TrackEvent, P: np.ndarray | None, tr: ManagedTrack) -> None:
        """Event ``ev`` of track ``tr`` to the call's events, ``on_event`` and :attr:`event_log` (with ``P``)."""
        self._events.append(ev)
        if self.on_event is not None:
            self.on_event(ev)
        if self.event_log is not None:  # a recorder's rows: no call per event (docs/api.md)
            self.event_log.append((ev, P, tr.altitude_m, tr.mode_s, tr.mode_3a))

    def _grid_north(self, r: Radar) -> float:
        """Grid azimuth of true north at the radar (meridian convergence), to compare azimuths."""
        x0, y0 = self.plane.to_plane(r.lat, r.lon)
        x1, y1 = self.plane.to_plane(min(r.lat + 0.01, 89.99), r.lon)
        return math.atan2(float(x1 - x0), float(y1 - y0))

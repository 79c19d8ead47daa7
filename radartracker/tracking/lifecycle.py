"""The track life cycle: a measurement's screening and update, initiation, M-of-N confirmation,
coasting and deletion — and the events each of them causes.

:meth:`TrackLifecycle.apply` takes one :class:`Update` (a measurement and the track association gave it,
or None): its d² against the track's bias-corrected prediction (S = P̄_pp + C_s P_ς C_sᵀ + R) is judged
(:func:`radartracker.estimation.screening.judge`); a rejected measurement is counted (``*_outlier``) and
touches nothing, repeated consistent rejections of an identified track re-initialise it; an accepted one
updates the track filter with z_c = z − C_s ς̂, R_c = R + C_s P_ς C_sᵀ. A new track is tentative; its
measurements are held until ``confirm_m`` hits out of ``confirm_n`` opportunities confirm it, when the
estimator is given the aircraft and all of them (:mod:`radartracker.tracking.feed`). A confirmed track
whose position an antenna swept without a plot is *coasting*; one not updated for ``delete_after_s``,
outside every radar's coverage, or tentative and unable to reach M of N, is deleted.
"""

from __future__ import annotations

import logging
import math
from collections import Counter, deque
from collections.abc import Callable
from operator import attrgetter
from typing import NamedTuple

import numpy as np

from radartracker.domain import AdsbReport, Plot
from radartracker.errors import PluginError
from radartracker.estimation.base import PlaneMeasurement
from radartracker.estimation.screening import ACCEPT, REINIT, REJECT, AdsbPlausibility, bias_corrected, judge
from radartracker.tracking.config import ManagerConfig
from radartracker.tracking.duplicates import TWIN, duplicate_of
from radartracker.tracking.events import ENDS, EventSink, TrackEvent, new_tuple
from radartracker.tracking.feed import AddAircraft, EstimatorFeed, Measure, RemoveAircraft
from radartracker.tracking.frame import Prediction
from radartracker.tracking.track import Pending, Track

log = logging.getLogger(__name__)
_LAST_UPDATE, _N_ADSB, _CREATED = attrgetter("last_update"), attrgetter("n_adsb"), attrgetter("created")
_STATUS = attrgetter("status")


class Update(NamedTuple):
    """A measurement of the frame for a track: ``source`` (the input), its ``row`` in the frame's
    measurements, and ``track`` (None: the track with its identity, else a new one). Sorted by
    (time, seq): the frame applies its updates in time order, at equal times in the order they were made."""

    time: float
    seq: int
    track: Track | None
    row: int
    source: Plot | AdsbReport | PlaneMeasurement


def _kind_and_code(src: Plot | AdsbReport | PlaneMeasurement) -> tuple[str, str | None, str | None]:
    """(counting kind, radar, Mode S address) of an input."""
    if isinstance(src, Plot):
        return "plots", src.radar, src.mode_s
    if isinstance(src, AdsbReport):
        return "adsb", None, src.icao24
    return "positions", None, src.aircraft if isinstance(src.aircraft, str) else None


class TrackLifecycle:
    """The live tracks (``tracks`` by id, in the order they started) and what happens to them (module
    docstring). ``new_filter()`` makes a track filter; ``failed`` makes a plugin's error."""

    def __init__(self, config: ManagerConfig, new_filter: Callable, feed: EstimatorFeed, sink: EventSink,
                 counts: Counter, failed: Callable[..., PluginError]) -> None:
        self.config = config
        self.new_filter = new_filter
        self.feed = feed
        self.sink = sink
        self.counts = counts  # inputs by the reason they were used or refused
        self.track_counts: Counter[str] = Counter()  # what happened to tracks (re-initialisations)
        self.failed = failed
        self.tracks: dict[int, Track] = {}
        self.by_mode_s: dict[str, int] = {}  # Mode S address → id of its live track
        self.by_target: dict[object, int] = {}  # truth label → id of its live track (with labels)
        self.next_id = 1
        self.adsb_check = AdsbPlausibility(config.screening)
        # the d² gate by (kind, tentative): ScreeningConfig.gate's, looked up once per measurement
        self.gates = {(k, t): config.screening.gate(k, t) for k in ("plots", "adsb", "positions") for t in (False, True)}
        self.labels = False  # tracks carry their first plot's truth label (set by a label associator)
        self.nis = [0, 0.0]  # count and sum of confirmed tracks' d² of the measurements they accepted
        self.neighbours: Prediction | None = None  # the frame's live tracks, where duplicates are looked for
        self.merged: dict[int, Track] = {}  # a track merged in this frame → the track that goes on for it
        self.took: Callable[[Track, Update], None] | None = None  # told of each measurement a track used

    def begin_frame(self, pred: Prediction) -> None:
        """A frame starts with live tracks ``pred``."""
        self.neighbours, self.merged = pred, {}

    def with_code(self, code: str | None) -> Track | None:
        """The live track with Mode S address ``code`` (at most one); with truth labels, else the track of
        that label (a simulated aircraft's label is its address)."""
        if code is None:
            return None
        tid = self.by_mode_s.get(code)
        if tid is None and self.labels:
            tid = self.by_target.get(code)
        return self.tracks.get(tid if tid is not None else -1)

    # --- one measurement ---------------------------------------------------------------------------
    def apply(self, u: Update, rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> None:
        """Screen ``u`` (its measurement ``rows[u.row]``: z, C_s, R) and update, start or re-initialise its
        track (module docstring)."""
        src, tr = u.source, u.track
        kind, radar, code = _kind_and_code(src)
        screening = self.config.screening
        z, C, R = rows[u.row]
        if kind == "adsb" and screening.enabled:
            why = self.adsb_check.check(src.icao24, src.time, z, math.sqrt(R[0, 0]), src.nacp)
            if why is not None:
                self.counts[why] += 1
                return
        bias, bias_cov = self.feed.bias(radar)
        if tr is not None and tr.id not in self.tracks:  # re-initialised, or merged, earlier in this frame
            tr = self.merged.get(tr.id)
        if tr is None:  # an ADS-B report may find the track a plot of this frame just started
            tr = self.with_code(code)
        zc = Rc = None
        updated = False
        if screening.enabled and tr is not None:
            verdict, zc, Rc, updated = self._screen(tr, z, C, R, bias, bias_cov, src.time, kind)
            if verdict == REJECT:
                return
            if verdict == REINIT:  # the track, not its measurements, is wrong: start again from this one
                log.warning("track %s (%s) re-initialised after %d rejected measurements", tr.id, tr.mode_s,
                            screening.reinit_after)
                self.track_counts["tracks_reinitialised"] += 1
                self.delete(tr, src.time)
                tr, updated = None, False
        if zc is None and not updated:
            zc, Rc = bias_corrected(z, C, R, bias, bias_cov) if radar is not None else (z, R)
        if tr is None:
            if len(self.tracks) >= self.config.max_tracks:  # a flood of plausible plots: bounded memory
                self.counts[f"{kind}_track_capacity"] += 1
                return
            tr = self._start(src, zc, Rc, code)
        elif not updated and not self._update(tr, src, zc, Rc, radar):
            return
        tr.took(src, kind)
        if self.took is not None:
            self.took(tr, u)
        if tr.status == "tentative":
            tr.pending.append(Pending(PlaneMeasurement(src.time, tr.id, radar, z, C, R), kind))
            if sum(tr.detections) >= self.config.confirm_m:
                self._confirm_or_merge(tr)
        else:
            self.feed.add(new_tuple(Measure, (src.time, tr.id, radar, z, C, R, kind)))
            tr.status = "confirmed"
            self.emit(src.time, tr, "updated")

    def _screen(self, tr: Track, z: np.ndarray, C: np.ndarray, R: np.ndarray, bias: np.ndarray,
                bias_cov: np.ndarray, t: float, kind: str) -> tuple[str, np.ndarray | None, np.ndarray | None, bool]:
        """(verdict, z_c, R_c, updated): d² against the filter's prediction, the filter updated in the same call
        when it passes (:meth:`TrackFilter.screen`); a measurement older than the estimate is judged at the
        estimate's time and not updated here. (ACCEPT, None, None, False) when the filter refuses the step."""
        cfg, tentative = self.config.screening, tr.status == "tentative"
        t_est = tr.epoch
        gate = self.gates[kind, tentative] if t >= t_est else None
        try:
            if gate is not None:
                tr.changed()
            d2, zc, Rc, updated = tr.filter.screen(max(t, t_est), z, C, R, bias, bias_cov, gate)
        except ValueError:  # the filter refuses this step; its update refuses it too and counts it
            return ACCEPT, None, None, False
        except Exception as exc:
            raise self.failed(f"motion model {self.new_filter.name!r}", tr.id, t, exc) from exc
        verdict, tr.rejected = judge(cfg, kind, d2, tr.rejected, tr.mode_s is not None, tentative, t, zc, Rc)
        if verdict == REJECT:
            self.counts[f"{kind}_outlier"] += 1
        elif not tentative and d2 < math.inf:  # a confirmed track's innovation: what its gates are sized on
            self.nis[0] += 1
            self.nis[1] += d2
        return verdict, zc, Rc, updated

    def _start(self, src: Plot | AdsbReport | PlaneMeasurement, zc: np.ndarray, Rc: np.ndarray,
               code: str | None) -> Track:
        filt = self.new_filter()
        try:
            filt.start(src.time, zc, Rc)
        except Exception as exc:
            raise self.failed(f"motion model {self.new_filter.name!r}", None, src.time, exc) from exc
        target = (getattr(src, "target", None) or code) if self.labels else None
        tr = Track(self.next_id, filt, "tentative", src.time, src.time, mode_s=code, target=target,
                   detections=deque(maxlen=self.config.confirm_n))
        self.next_id += 1
        self.tracks[tr.id] = tr
        if code is not None:
            self.by_mode_s[code] = tr.id
        if target is not None:
            self.by_target[target] = tr.id
        self.emit(src.time, tr, "created")
        return tr

    def _update(self, tr: Track, src: Plot | AdsbReport | PlaneMeasurement, zc: np.ndarray, Rc: np.ndarray,
                radar: str | None) -> bool:
        """The track's filter updated with (z_c, R_c); False (counted) if the filter refuses it."""
        try:
            tr.changed()
            tr.filter.update(src.time, zc, Rc)
        except ValueError as exc:  # SingularInnovation, or a filter refusing the time step
            self.counts["plots_refused_by_filter" if radar else "unbiased_refused_by_filter"] += 1
            log.warning("track %s refused a measurement at t=%s: %s", tr.id, src.time, exc)
            return False
        except Exception as exc:
            raise self.failed(f"motion model {self.new_filter.name!r}", tr.id, src.time, exc) from exc
        return True

    def _confirm(self, tr: Track) -> None:
        """M of N: the estimator gets the aircraft, from its first position with the velocity prior, and
        the track's held measurements."""
        first = tr.pending[0].measurement
        sd_v = tr.filter.config.prior_sd_velocity_mps
        self.feed.add(AddAircraft(first.time, tr.id, np.array([*first.z, 0.0, 0.0]),
                                  np.diag([1e8, 1e8, sd_v**2, sd_v**2])))
        for m, kind in tr.pending:
            self.feed.add(Measure(m.time, tr.id, m.radar, m.z, m.C, m.R, kind))
        tr.pending = []
        tr.status = "confirmed"
        self.emit(tr.last_update, tr, "confirmed")

    def _confirm_or_merge(self, tr: Track) -> None:
        """Confirm ``tr``, unless an older track follows its aircraft (:mod:`~radartracker.tracking.duplicates`):
        a twin is dropped (its held measurements counted ``*_in_merged_tracks``); a lost older track takes
        over its filter and measurements under the older number. Either way a ``merged`` event retires ``tr``."""
        found = duplicate_of(tr, self.neighbours, self.config.merge_distance_m)
        if found is None:
            self._confirm(tr)
            return
        old, how = found
        self.track_counts[f"tracks_merged_{how}"] += 1
        self.merged[tr.id] = old
        if how == TWIN:
            self.delete(tr, tr.last_update, "merged", "in_merged_tracks")
            return
        self.feed.add(RemoveAircraft(tr.last_update, old.id))  # its estimator state followed the lost path
        old.take_over(tr)
        self.delete(tr, tr.last_update, "merged")
        if old.mode_s is not None:
            self.by_mode_s[old.mode_s] = old.id
        self._confirm(old)

    # --- misses and deletion -----------------------------------------------------------------------
    def missed(self, tracks: list[Track], swept: np.ndarray, hits: set[tuple[int, int]], t_a: float, t_b: float) -> None:
        """Tracks ``tracks[i]`` whose position radar r's antenna swept in [t_a, t_b) (``swept`` radars ×
        tracks) without a plot for it (``hits``: the (radar row, track index) pairs of the frame's plots)
        missed a detection; a confirmed one is then coasting. A track started in the frame is not missed."""
        swept = swept.copy()
        if hits:
            r_hit, i_hit = zip(*hits)
            swept[list(r_hit), list(i_hit)] = False
        swept[:, np.fromiter(map(_CREATED, tracks), float, len(tracks)) >= t_a] = False
        for i in np.nonzero(swept)[1].tolist():  # radar by radar, as the antennas swept
            tr = tracks[i]
            tr.missed()
            if tr.status == "confirmed":
                tr.status = "coasting"
                self.emit(t_b, tr, "coasting")

    def sweep(self, tracks: list[Track], covered: np.ndarray, now: float) -> None:
        """Delete the tracks that are stale, outside every radar's coverage (unless ADS-B feeds them) or
        tentative with no chance of confirmation."""
        cfg = self.config
        n = len(tracks)
        last = np.fromiter(map(_LAST_UPDATE, tracks), float, n)
        kept = covered | np.fromiter(map(_N_ADSB, tracks), bool, n)
        due = (now - last > cfg.delete_after_s) | ~kept
        tentative = np.fromiter(map("tentative".__eq__, map(_STATUS, tracks)), bool, n)
        for i in np.flatnonzero(due | tentative).tolist():
            tr = tracks[i]
            if tr.id in self.tracks and (due[i] or tr.hopeless(cfg.confirm_m, cfg.confirm_n)):
                self.delete(tr, now)

    def delete(self, tr: Track, now: float, kind: str = "deleted", held: str = "in_dropped_tentative_tracks") -> None:
        """End ``tr`` with an event of ``kind`` (``deleted``, or ``merged`` into another track); a tentative
        track's held measurements are counted ``*_<held>``."""
        del self.tracks[tr.id]
        if tr.mode_s is not None and self.by_mode_s.get(tr.mode_s) == tr.id:
            del self.by_mode_s[tr.mode_s]
        if tr.target is not None and self.by_target.get(tr.target) == tr.id:
            del self.by_target[tr.target]
        if tr.status == "tentative":
            for p in tr.pending:
                self.counts[f"{p.kind}_{held}"] += 1
        else:
            self.feed.add(RemoveAircraft(now, tr.id))
        tr.status = "deleted"
        self.emit(now, tr, kind)

    def emit(self, time: float, tr: Track, kind: str) -> None:
        """The event of ``kind`` at ``time`` with the track's state then (extrapolated when later than its
        estimate; a deletion's at most ``delete_after_s`` past the last update, where the track was due: after
        a feed gap of two days its state two days on is nowhere)."""
        at = time if kind not in ENDS else min(time, tr.last_update + self.config.delete_after_s)
        self.sink.emit(new_tuple(TrackEvent, (float(time), tr.id, kind, tr.status, tr.state_at(at))), tr)

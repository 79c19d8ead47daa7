"""The fusion centre: local (per-radar) tracks aligned in time, associated to system tracks and fused.

Seed 004 fuses the monoradar tracks of 28 radars after time alignment, with weights. Here, at each
fusion epoch t every live local track i of radar j is

1. **aligned** — predicted from its last report to t with the constant-velocity model (A, Q of the
   run's q), and **bias-corrected** with the centre's estimate of radar j:
   p̃ = p − C_s ς̂_j, P̃_pp = P_pp + C_s P_ς C_sᵀ (C_s at the local position, as for a plot);
2. **associated** — a local track keeps its system track once linked; a new one joins the system
   track with its Mode S address, else the nearest system track by d² = Δpᵀ(P_sys + P̃)⁻¹Δp within a
   χ²₂ gate (GNN, one local track per radar per system track), else joins a system track started
   earlier in the same epoch (Mode S, else nearest in the gate: two radars' first tracks of one
   aircraft), else starts a system track;
3. **fused** by covariance intersection: P⁻¹ = Σ ω_i P̃_i⁻¹, x = P Σ ω_i P̃_i⁻¹ x̃_i with
   ω_i ∝ 1/tr P̃_i (the fast CI of Niehsen 2002). CI rather than Bar-Shalom–Campo because the
   cross-covariances between local tracks of one aircraft (common process noise, the shared bias
   estimate) are not exported by radar trackers; CI is consistent for any such correlation, at the
   price of a fused covariance larger than the optimal one.

Bias estimation: the centre's estimator plugin (the coupled filter of the central architecture)
receives each local track's *uncorrected* position as a measurement z = p + C_s ς_j + e with
R = κ P_pp, at most once every ``bias_every_s`` per local track (a filtered track's errors are
correlated in time; decimation to about one independent sample per few scans keeps the estimator
near consistent), and the ADS-B reports of system tracks with the report's Mode S address. Each
passes the same innovation screening as on the central paths (:class:`LabelledScreen`: ADS-B
plausibility, then d² against the estimator's own prediction) before it may move a bias.
Both wait ``delay`` (a scan of the slowest radar plus a period) in a buffer so that they reach the
estimator in time order.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Iterator

import attrs
import numpy as np

from radartracker.domain import Radar
from radartracker.estimation.base import Estimator, PlaneMeasurement
from radartracker.estimation.kalman import SingularInnovation
from radartracker.estimation.motion import MotionModel
from radartracker.estimation.screening import ACCEPT, LabelledScreen, ScreeningConfig
from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.tracking.association import assign, candidate_pairs


@attrs.frozen
class FusionConfig:
    """Fusion epochs every ``period_s``; χ²₂ ``gate`` for local-to-system association; local tracks
    older than ``stale_s`` leave their system track; ``bias_every_s`` and ``r_inflation`` (κ) as in
    the module docstring; ``search_radius_m`` bounds the association candidates; the estimator's
    measurements wait ``delay_scans`` of the slowest radar (plus a period) to come in time order —
    local reports lag their trackers' reorder window plus a fusion period (measured: at most 3.3 s on a
    real flight-inspection flight, with radars of 4, 8 and 12 s)."""

    period_s: float = attrs.field(default=2.0, validator=attrs.validators.gt(0.0))
    gate: float = attrs.field(default=13.82, validator=attrs.validators.gt(0.0))
    stale_s: float = attrs.field(default=40.0, validator=attrs.validators.gt(0.0))
    bias_every_s: float = attrs.field(default=12.0, validator=attrs.validators.ge(0.0))
    r_inflation: float = attrs.field(default=2.0, validator=attrs.validators.ge(1.0))
    search_radius_m: float = attrs.field(default=25_000.0, validator=attrs.validators.gt(0.0))
    delay_scans: float = attrs.field(default=1.0, validator=attrs.validators.ge(0.0))


@attrs.define
class LocalReport:
    """A local track's latest estimate: state χ = [x, y, vx, vy] (plane, biased by its radar) and
    covariance at ``time``, with the identity it carries."""

    time: float
    radar: str
    track: int
    state: np.ndarray
    cov: np.ndarray
    altitude_m: float | None = None
    mode_s: str | None = None
    mode_3a: str | None = None


@attrs.define
class LocalTrackEnd:
    """A local track ended (its radar head's track-end report)."""

    time: float
    radar: str
    track: int


@attrs.define
class LocalTracks:
    """Local track reports and ends from outside the run (e.g. CAT048 from radar heads), each list in
    time order; :func:`~radartracker.pipeline.distributed.run_distributed` then runs no local trackers."""

    reports: list[LocalReport]
    ends: list[LocalTrackEnd]

    def items(self) -> Iterator[LocalReport | LocalTrackEnd]:
        return heapq.merge(self.reports, self.ends, key=lambda item: item.time)


@attrs.define
class SystemTrack:
    """A fused track: state and covariance at ``time``, its member local tracks (radar, id)."""

    id: int
    time: float
    state: np.ndarray
    cov: np.ndarray
    members: set = attrs.field(factory=set)
    last_seen: float = 0.0
    fed: float = -math.inf  # time of the last measurement given to the estimator


EventSink = Callable[[float, SystemTrack, str, tuple], None]


class FusionCentre:
    """Aligns, associates and fuses local track reports; feeds the bias estimator (module docstring)."""

    def __init__(self, radars: list[Radar], plane: SystemPlane, estimator: Estimator, q: float,
                 config: FusionConfig, on_event: EventSink, default_altitude_m: float,
                 screening: ScreeningConfig | None = None) -> None:
        self.config, self.estimator, self.on_event = config, estimator, on_event
        self.screening = screening or ScreeningConfig()
        self.screen = LabelledScreen(self.screening)
        self.plane, self.motion = plane, MotionModel(q)
        self.frames = {r.id: RadarFrame(r.lat, r.lon, r.height_m, plane) for r in radars}
        self.default_altitude_m = default_altitude_m
        self.local: dict[tuple[str, int], LocalReport] = {}
        self.link: dict[tuple[str, int], int] = {}
        self.fed: dict[tuple[str, int], float] = {}
        self.tracks: dict[int, SystemTrack] = {}
        self.adsb: list[tuple[float, str, np.ndarray, np.ndarray]] = []
        self.pending: list[tuple] = []  # estimator measurements waiting for ``delay`` (_feed_estimator)
        self.delay = config.delay_scans * max((r.period_s for r in radars), default=0.0) + config.period_s
        self.counts: dict[str, int] = {}
        self._ids = 0

    # --- inputs -----------------------------------------------------------------------------------
    def report(self, r: LocalReport) -> None:
        self.local[(r.radar, r.track)] = r

    def drop(self, radar: str, track: int) -> None:
        """A local track ended."""
        self.local.pop((radar, track), None)
        self.fed.pop((radar, track), None)
        sid = self.link.pop((radar, track), None)
        if sid in self.tracks:
            self.tracks[sid].members.discard((radar, track))

    def adsb_report(self, time: float, icao24: str, z: np.ndarray, R: np.ndarray, nacp: int) -> None:
        if self.screening.enabled and (why := self.screen.adsb.check(icao24, time, z, math.sqrt(R[0, 0]), nacp)):
            self._count(why)
            return
        self.adsb.append((time, icao24, z, R))

    def _count(self, reason: str, n: int = 1) -> None:
        self.counts[reason] = self.counts.get(reason, 0) + n

    # --- one epoch ----------------------------------------------------------------------------------
    def epoch(self, t: float, final: bool = False) -> None:
        """Align, associate and fuse at ``t``; ``final``: the last epoch, every buffered measurement fed."""
        cfg = self.config
        for key in [k for k, r in self.local.items() if t - r.time > cfg.stale_s]:
            self.drop(*key)
        keys = list(self.local)
        aligned = self._aligned(keys, t)
        self._associate(keys, aligned, t)
        for sid, tr in list(self.tracks.items()):
            members = [i for i, k in enumerate(keys) if self.link.get(k) == sid]
            if not members:
                if t - tr.last_seen > cfg.stale_s:
                    del self.tracks[sid]
                    self.estimator.remove_aircraft(sid)
                    self.screen.forget(sid)
                    self.on_event(t, tr, "deleted", self._identity(tr))
                continue
            tr.state, tr.cov = covariance_intersection([aligned[i][0] for i in members],
                                                       [aligned[i][1] for i in members])
            tr.time, tr.last_seen = t, t
            self.on_event(t, tr, "updated", self._identity(tr))
        self._feed_estimator(t, final)

    def _aligned(self, keys: list[tuple[str, int]], t: float) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """(bias-corrected state, covariance, C_s) of every local track at ``t``."""
        out = []
        for key in keys:
            r = self.local[key]
            A, Q = self.motion.transition(t - r.time)
            x, P = A @ r.state, A @ r.cov @ A.T + Q
            C = self._jacobian(r.radar, x[:2], r.altitude_m)
            b = self.estimator.bias(r.radar)
            x = x.copy()
            x[:2] -= C @ b.bias
            P = P.copy()
            P[:2, :2] += C @ b.cov @ C.T
            out.append((x, P, C))
        return out

    def _jacobian(self, radar: str, p: np.ndarray, altitude_m: float | None) -> np.ndarray:
        frame = self.frames[radar]
        alt = self.default_altitude_m if altitude_m is None else altitude_m
        lat, lon = self.plane.to_geodetic(p[0], p[1])
        rho, _, _ = frame.polar(lat, lon, alt)
        return frame.bias_jacobian(np.asarray(p, float), float(rho), alt)

    def _associate(self, keys: list[tuple[str, int]], aligned: list, t: float) -> None:
        cfg = self.config
        ids = list(self.tracks)
        pred = {}
        for sid in ids:
            tr = self.tracks[sid]
            A, Q = self.motion.transition(t - tr.time)
            pred[sid] = (A @ tr.state, A @ tr.cov @ A.T + Q)
        by_code = {}
        for k, sid in self.link.items():
            if self.local[k].mode_s:
                by_code.setdefault(self.local[k].mode_s, sid)
        new = [i for i, k in enumerate(keys) if k not in self.link]
        rest = []
        for i in new:
            code = self.local[keys[i]].mode_s
            sid = by_code.get(code) if code else None
            if sid is not None and not any(m[0] == keys[i][0] for m in self.tracks[sid].members):
                self._join(keys[i], sid)
            else:
                rest.append(i)
        if rest and ids:
            z = np.array([aligned[i][0][:2] for i in rest])
            pos = np.array([pred[s][0][:2] for s in ids])
            radars = np.array([keys[i][0] for i in rest], object)
            allowed = np.array([[not any(m[0] == rd for m in self.tracks[s].members) for s in ids] for rd in radars])
            pairs = candidate_pairs(z, pos, cfg.search_radius_m, allowed)
            if len(pairs):
                nu = z[pairs[:, 0]] - pos[pairs[:, 1]]
                S = (np.array([aligned[rest[k]][1][:2, :2] for k in pairs[:, 0]])
                     + np.array([pred[ids[s]][1][:2, :2] for s in pairs[:, 1]]))
                d2 = np.einsum("ni,nij,nj->n", nu, np.linalg.inv(S), nu)
                matched = dict(assign(pairs, d2, d2 + np.log(np.linalg.det(S)), cfg.gate))
            else:
                matched = {}
        else:
            matched = {}
        born: list[int] = []  # system tracks started in this epoch
        for j, i in enumerate(rest):
            if j in matched:
                self._join(keys[i], ids[matched[j]])
            elif (sid := self._newborn(keys[i], aligned[i], born)) is not None:
                self._join(keys[i], sid)  # another radar's track of an aircraft first seen in this epoch
            else:
                x, P, _ = aligned[i]
                self._ids += 1
                tr = SystemTrack(self._ids, t, x.copy(), P.copy(), last_seen=t)
                self.tracks[tr.id] = tr
                self.estimator.add_aircraft(tr.id, t, x.copy(), P + np.diag([1e4, 1e4, 1e2, 1e2]))
                self._join(keys[i], tr.id)
                born.append(tr.id)
                self.on_event(t, tr, "created", self._identity(tr))

    def _newborn(self, key: tuple[str, int], aligned: tuple, born: list[int]) -> int | None:
        """The system track started earlier in this epoch that local track ``key`` joins: the one with
        its Mode S address, else the nearest within the χ²₂ gate (its founding state and covariance);
        never one that already holds a track of the same radar."""
        code = self.local[key].mode_s
        best, best_d2 = None, self.config.gate
        for sid in born:
            tr = self.tracks[sid]
            if any(m[0] == key[0] for m in tr.members):
                continue
            codes = {self.local[m].mode_s for m in tr.members} - {None}
            if code and code in codes:
                return sid
            if code and codes:
                continue  # another aircraft's address
            nu = aligned[0][:2] - tr.state[:2]
            d2 = float(nu @ np.linalg.solve(aligned[1][:2, :2] + tr.cov[:2, :2], nu))
            if d2 < best_d2:
                best, best_d2 = sid, d2
        return best

    def _join(self, key: tuple[str, int], sid: int) -> None:
        self.link[key] = sid
        self.tracks[sid].members.add(key)

    def _identity(self, tr: SystemTrack) -> tuple:
        reps = [self.local[k] for k in tr.members if k in self.local]
        alt = next((r.altitude_m for r in reps if r.altitude_m is not None), None)
        return (alt, next((r.mode_s for r in reps if r.mode_s), None), next((r.mode_3a for r in reps if r.mode_3a), None))

    def _feed_estimator(self, t: float, final: bool = False) -> None:
        """Decimated local-track positions and the ADS-B reports of identified system tracks, in time order.

        A local report arrives up to a scan after its time, ADS-B within a second: both wait in a
        buffer until ``t − delay`` (``delay_scans`` of the slowest radar plus a fusion period) and are then given
        in time order, so that an aircraft's frequent ADS-B does not make its radar reports "late"
        for the estimator (each aircraft's measurements must come in time order)."""
        cfg = self.config
        for key, sid in self.link.items():
            r = self.local[key]
            if r.time - self.fed.get(key, -math.inf) < cfg.bias_every_s:
                continue
            C = self._jacobian(r.radar, r.state[:2], r.altitude_m)
            self.pending.append((r.time, sid, r.radar, r.state[:2].copy(), C, cfg.r_inflation * r.cov[:2, :2], "local"))
            self.fed[key] = r.time
        by_code = {}
        for key, sid in self.link.items():
            if self.local[key].mode_s:
                by_code[self.local[key].mode_s] = sid
        for time, code, z, R in self.adsb:
            sid = by_code.get(code)
            if sid is None:
                self._count("adsb_unassociated")
            else:
                self.pending.append((time, sid, None, z, np.zeros((2, 2)), R, "adsb"))
        self.adsb = []
        horizon = math.inf if final else t - self.delay
        self.pending.sort(key=lambda b: b[0])
        ready = [b for b in self.pending if b[0] <= horizon]
        self.pending = [b for b in self.pending if b[0] > horizon]
        for time, sid, radar, z, C, R, kind in ready:
            tr = self.tracks.get(sid)
            if tr is None:
                self._count(f"{kind}_track_ended_before_estimator")
                continue
            if time < tr.fed:  # older than what this aircraft already gave the estimator
                self._count(f"{kind}_late_for_estimator")
                continue
            m = PlaneMeasurement(time, sid, radar, z, C, R)
            if self.screening.enabled and self.screen.screen(self.estimator, m, "adsb" if radar is None else "plots") != ACCEPT:
                self._count(f"{kind}_outlier")  # a rejected report never moves a bias
                continue
            try:
                self.estimator.update(m)
            except SingularInnovation:
                self._count(f"{kind}_singular")
                continue
            tr.fed = time
            self._count("local_track_reports_used" if kind == "local" else "adsb_used")


def covariance_intersection(xs: list[np.ndarray], Ps: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Fast covariance intersection: ω_i ∝ 1/tr P_i, P⁻¹ = Σ ω_i P_i⁻¹, x = P Σ ω_i P_i⁻¹ x_i."""
    if len(xs) == 1:
        return xs[0].copy(), Ps[0].copy()
    w = np.array([1.0 / np.trace(P) for P in Ps])
    w /= w.sum()
    infos = [wi * np.linalg.inv(P) for wi, P in zip(w, Ps)]
    P = np.linalg.inv(sum(infos))
    x = P @ sum(I @ x for I, x in zip(infos, xs))
    return x, 0.5 * (P + P.T)

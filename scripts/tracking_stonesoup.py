"""Stone Soup's plain GNN tracker on the same plots: the peer of ``scripts/tracking_report.py``.

Each plot is converted to the system plane with its Mode C altitude (``primary_altitude_m`` when it
has none), exactly as the TrackManager converts it, with covariance R = C W Cᵀ — but **without bias
correction** (Stone Soup has no registration). Tracker: nearly-constant-velocity Kalman filter
(``ConstantVelocity(q)`` per axis), ``DistanceHypothesiser`` with the Mahalanobis distance and the
same χ²₂ 99.9 % gate, ``GNNWith2DAssignment``, ``MultiMeasurementInitiator`` (3 plots),
``UpdateTimeDeleter`` (the same ``delete_after_s``). Scans are the plots of one radar within 0.5 s.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import math
import os
from pathlib import Path

import numpy as np
from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
from stonesoup.deleter.time import UpdateTimeDeleter
from stonesoup.hypothesiser.distance import DistanceHypothesiser
from stonesoup.initiator.simple import MultiMeasurementInitiator
from stonesoup.measures import Mahalanobis
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
from stonesoup.predictor.kalman import KalmanPredictor
from stonesoup.tracker.simple import MultiTargetTracker
from stonesoup.types.detection import Detection
from stonesoup.types.state import GaussianState
from stonesoup.updater.kalman import KalmanUpdater

from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.io.tables import ScenarioData
from radartracker.pipeline.evaluate import TrackHistory

EPOCH = dt.datetime(1970, 1, 1)


def converted_plots(data: ScenarioData, primary_altitude_m: float = 6000.0) -> tuple[np.ndarray, ...]:
    """(time, radar index, z (N, 2), R (N, 2, 2)) of every plot, uncorrected for bias."""
    plane = SystemPlane(*data.reference)
    p = data.plots
    z, R = np.full((len(p), 2), np.nan), np.zeros((len(p), 2, 2))
    ridx = np.zeros(len(p), int)
    for j, radar in enumerate(data.radars):
        idx = np.flatnonzero(p.radar == radar.id)
        frame = RadarFrame(radar.lat, radar.lon, radar.height_m, plane)
        alt = np.where(np.isnan(p.altitude_m[idx]), primary_altitude_m, p.altitude_m[idx])
        zz, ok = frame.to_plane(p.range_m[idx], p.azimuth_rad[idx], alt)
        C = frame.bias_jacobian(zz, p.range_m[idx], alt)
        z[idx] = np.where(ok[:, None], zz, np.nan)
        R[idx] = C @ radar.W @ np.swapaxes(C, 1, 2)
        ridx[idx] = j
    return p.time, ridx, z, R


def _scans(t: np.ndarray, ridx: np.ndarray, z: np.ndarray, R: np.ndarray, frame_s: float = 0.5):
    """(datetime, set of Detections): the plots of one radar within one frame, in time order."""
    order = np.lexsort((ridx, np.floor(t / frame_s)))
    key = None
    batch: set = set()
    when = None
    for i in order:
        if not np.isfinite(z[i]).all():
            continue
        k = (math.floor(t[i] / frame_s), ridx[i])
        if k != key and batch:
            yield when, batch
            batch = set()
        key = k
        when = EPOCH + dt.timedelta(seconds=float(t[i]))
        model = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=R[i])
        batch.add(Detection(z[i].reshape(2, 1), timestamp=when, measurement_model=model))
    if batch:
        yield when, batch


class CachedConstantVelocity(CombinedLinearGaussianTransitionModel):
    """Stone Soup's ``ConstantVelocity(q)`` on each axis, its F and Q for each time step made once: the same
    matrices, without scipy's ``block_diag`` on every prediction (a third of a run's samples)."""

    def matrix(self, **kwargs):
        return self._cached("F", super().matrix, kwargs)

    def covar(self, **kwargs):
        return self._cached("Q", super().covar, kwargs)

    def _cached(self, kind: str, make, kwargs: dict):
        cache = self.__dict__.setdefault("_by_step", {})
        key = (kind, kwargs.get("time_interval"))
        if key not in cache:
            cache[key] = make(**kwargs)
        return cache[key]


class PreGatedHypothesiser(DistanceHypothesiser):
    """Stone Soup's ``DistanceHypothesiser`` on the detections within ``radius_m`` of the track's
    straight-line extrapolation only (a pre-gate like the TrackManager's k-d tree search): the
    Mahalanobis gate of the plain hypothesiser normally lies well inside it, and the cost no longer
    grows with the number of tracks times detections."""

    radius_m: float = 25_000.0

    def hypothesise(self, track, detections, timestamp, **kwargs):
        x = np.ravel(track.state_vector)
        t0 = track.timestamp
        near = {d for d in detections
                if math.hypot(*(np.ravel(d.state_vector) - x[[0, 2]] - x[[1, 3]] * (d.timestamp - t0).total_seconds()))
                < self.radius_m}
        return super().hypothesise(track, near, timestamp, **kwargs)


def stonesoup_gnn(data: ScenarioData, q: float = 5.0, gate: float = 13.82, delete_after_s: float = 40.0,
                  prior_sd_velocity_mps: float = 300.0) -> dict[int, TrackHistory]:
    """Run Stone Soup's GNN tracker over ``data``'s plots; confirmed tracks as histories [x, y, vx, vy]."""
    t, ridx, z, R = converted_plots(data)
    transition = CachedConstantVelocity([ConstantVelocity(q), ConstantVelocity(q)])
    predictor = KalmanPredictor(transition)
    updater = KalmanUpdater(measurement_model=None)
    hypothesiser = PreGatedHypothesiser(predictor, updater, measure=Mahalanobis(), missed_distance=math.sqrt(gate))
    associator = GNNWith2DAssignment(hypothesiser)
    deleter = UpdateTimeDeleter(dt.timedelta(seconds=delete_after_s))
    prior = GaussianState(np.zeros((4, 1)), np.diag([0.0, prior_sd_velocity_mps**2, 0.0, prior_sd_velocity_mps**2]))
    init_hyp = PreGatedHypothesiser(predictor, updater, measure=Mahalanobis(), missed_distance=math.sqrt(gate))
    initiator = MultiMeasurementInitiator(prior, deleter, GNNWith2DAssignment(init_hyp), updater, min_points=3)
    tracker = MultiTargetTracker(initiator=initiator, deleter=deleter, detector=_scans(t, ridx, z, R),
                                 data_associator=associator, updater=updater)
    seen: dict[int, object] = {}
    for _, tracks in tracker:
        for tr in tracks:
            seen[id(tr)] = tr
    out = {}
    for n, tr in enumerate(seen.values()):
        times = np.array([(s.timestamp - EPOCH).total_seconds() for s in tr.states])
        states = np.array([np.ravel(s.state_vector)[[0, 2, 1, 3]] for s in tr.states], float)
        end = min(times[-1] + delete_after_s, float(t.max()))
        out[n] = TrackHistory(times, states, float(times[0]), end)
    return out


def plots_digest(data: ScenarioData) -> str:
    """SHA-256 of the plots (time, radar, range, azimuth, altitude): proof that two runs saw the same plots."""
    p = data.plots
    h = hashlib.sha256()
    for col in (p.time, p.range_m, p.azimuth_rad, p.altitude_m):
        h.update(np.ascontiguousarray(col, float).tobytes())
    h.update("\n".join(map(str, p.radar)).encode())
    return h.hexdigest()


def save_tracks(path: Path, tracks: dict[int, TrackHistory], digest: str, wall_s: float) -> None:
    """Write Stone Soup's track histories with the plots' digest and the run's wall time, atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    cols = {"digest": np.array(digest), "wall_s": np.array(wall_s), "ids": np.array(sorted(tracks), int)}
    for tid in sorted(tracks):
        h = tracks[tid]
        cols[f"t{tid}"], cols[f"s{tid}"], cols[f"span{tid}"] = h.times, h.states, np.array([h.start, h.end])
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez(tmp, **cols)
    os.replace(tmp, path)


def load_tracks(path: Path, digest: str) -> tuple[dict[int, TrackHistory], float]:
    """Track histories saved by :func:`save_tracks` for the same plots (``digest``), and the run's wall time."""
    with np.load(path, allow_pickle=False) as f:
        if str(f["digest"]) != digest:
            raise SystemExit(f"{path}: Stone Soup tracks of other plots (digest {str(f['digest'])[:12]}, these plots {digest[:12]})")
        out = {int(tid): TrackHistory(f[f"t{tid}"], f[f"s{tid}"], float(f[f"span{tid}"][0]), float(f[f"span{tid}"][1]))
               for tid in f["ids"]}
        return out, float(f["wall_s"])

"""The TrackManager's snapshot document: what a snapshot holds, field by field, and its checks.

A snapshot (file format: :mod:`radartracker.tracking.snapshot`) holds ``[meta, state]``. ``meta``
rebuilds the manager: ``{"kind": "TrackManager", "schema": SCHEMA, "radars", "reference", "config",
"estimator": class, "motion_model": class}``. ``state`` is this document, never the manager's
attributes::

    counts      {reason: count};  track_counts: {what: count};  innovations: {"count", "sum"} of the
                confirmed tracks' d² (:meth:`TrackManager.innovations`)
    admission   {"keys": [[tag, source, time, a, b]], "keys_limit", "clock": StreamClock state,
                 "held": [input] (the inputs of a run that may step the clock)}
    window      {"queue": [input], "heap": [[time, arrival, input]], "arrivals", "newest", "recent" (the
                 last times pushed, in order: the stream's confirmed time is taken from them), "horizon"}
    frame       the frame being gathered (null before the first input), "gathered": [input]
    antennas    AntennaSweep state;  adsb_check: AdsbPlausibility state
    tracks      [track], "next_track": the next track id
    estimator   the estimator plugin's state dict;  coupling: the coupling graph's state dict

An input is ``["p", time, radar, range_m, azimuth_rad, altitude_m, mode_s, mode_3a, target]``,
``["a", time, icao24, lat, lon, altitude_m, nacp]`` or ``["m", time, aircraft, z, R]`` (an unbiased
position); each is rebuilt through its validating constructor. A track is a map of its fields (see
:func:`_track_doc`) with its filter as ``{"class", "config", "state"}``. Restoring checks every field's
type, every cross-reference (track ids unique and below ``next_track``, statuses, detections within
``confirm_n``, pending measurements' shapes, radars known) and hands the plugins' state dicts to their
own ``load_state_dict``, which validate them; anything else is a ``ValueError`` naming the field.
"""

from __future__ import annotations

import math
from pathlib import Path
from collections import deque
from typing import Any

import numpy as np

from radartracker.domain import AdsbReport, Plot, Radar
from radartracker.estimation.base import PlaneMeasurement
from radartracker.tracking.association import AltitudeTrack
from radartracker.tracking.config import ManagerConfig
from radartracker.tracking.height import HeightFilter
from radartracker.errors import SnapshotError
from radartracker.tracking.snapshot import class_name, decode, encode, read_snapshot_file, write_snapshot_file
from radartracker.tracking.track import TRACK_STATUSES, Pending, Track

SCHEMA = 3
READS = (2, 3)  # schema 2 lacks the window's "recent" times (its newest stands for them) and track counts
_KINDS = ("plots", "adsb", "positions")


def _need(ok: bool, what: str) -> None:
    if not ok:
        raise ValueError(what)


def _number(v: Any, what: str, finite: bool = True) -> float:
    _need(type(v) in (int, float) and not isinstance(v, bool), f"{what}: a number expected, got {type(v).__name__}")
    _need(not finite or math.isfinite(v), f"{what}: a finite number expected")
    return float(v)


def _integer(v: Any, what: str, lo: int = 0, hi: int = 2**62) -> int:
    _need(type(v) is int and lo <= v <= hi, f"{what}: an integer in [{lo}, {hi}] expected")
    return v


def _floats(v: Any, n: int, what: str) -> np.ndarray:
    _need(isinstance(v, list) and len(v) == n, f"{what}: {n} numbers expected")
    return np.array([_number(x, what) for x in v], float)


# --- inputs ----------------------------------------------------------------------------------------

def input_doc(item: Plot | AdsbReport | PlaneMeasurement) -> list:
    if isinstance(item, Plot):
        return ["p", item.time, item.radar, item.range_m, item.azimuth_rad, item.altitude_m, item.mode_s,
                item.mode_3a, item.target]
    if isinstance(item, AdsbReport):
        return ["a", item.time, item.icao24, item.lat, item.lon, item.altitude_m, item.nacp]
    return ["m", item.time, item.aircraft, np.asarray(item.z, float).tolist(), np.asarray(item.R, float).ravel().tolist()]


def input_of(doc: Any, radars: frozenset, what: str) -> Plot | AdsbReport | PlaneMeasurement:
    _need(isinstance(doc, list) and doc and doc[0] in ("p", "a", "m"), f"{what}: not an input")
    tag = doc[0]
    _need(len(doc) == {"p": 9, "a": 7, "m": 5}[tag], f"{what}: wrong number of fields")
    if tag == "p":
        _need(doc[2] in radars, f"{what}: unknown radar {doc[2]!r}")
        _need(doc[8] is None or isinstance(doc[8], str), f"{what}: target must be text")
        return Plot(*doc[1:])
    if tag == "a":
        return AdsbReport(*doc[1:])
    _need(doc[2] is None or isinstance(doc[2], (str, int)), f"{what}: aircraft must be text or an integer")
    R = _floats(doc[4], 4, f"{what} R").reshape(2, 2)
    _need(bool(np.allclose(R, R.T)) and bool(np.all(np.linalg.eigvalsh(R) > 0)), f"{what}: R not positive definite")
    return PlaneMeasurement(_number(doc[1], f"{what} time"), doc[2], None, _floats(doc[3], 2, f"{what} z"),
                            np.zeros((2, 2)), R)


# --- tracks ----------------------------------------------------------------------------------------

def _track_doc(tr: Track) -> dict:
    v = tr.vertical
    return {"id": tr.id, "status": tr.status, "created": tr.created, "last_update": tr.last_update,
            "mode_s": tr.mode_s, "mode_3a": tr.mode_3a, "target": tr.target, "altitude_m": tr.altitude_m,
            "altitude_sd_m": tr.altitude_sd_m,
            "detections": list(tr.detections), "n_plots": tr.n_plots, "n_adsb": tr.n_adsb,
            "pending": [[p.measurement.time, p.measurement.radar, np.asarray(p.measurement.z, float).tolist(),
                         np.asarray(p.measurement.C, float).ravel().tolist(),
                         np.asarray(p.measurement.R, float).ravel().tolist(), p.kind] for p in tr.pending],
            "rejected": [[t, np.asarray(z, float).tolist(), sd] for t, z, sd in tr.rejected],
            "vertical": None if v is None else [v.time, v.h, v.v, v.p00, v.p01, v.p11],
            "height": None if tr.height is None else tr.height.state(),
            "filter": {"class": class_name(tr.filter), "config": encode(tr.filter.config, "filter config"),
                       "state": encode(tr.filter.state_dict(), "filter state")}}


def _pending_of(doc: Any, tid: int, radars: frozenset, what: str) -> Pending:
    _need(isinstance(doc, list) and len(doc) == 6, f"{what}: [time, radar, z, C, R, kind] expected")
    time, radar, z, C, R, kind = doc
    _need(radar is None or radar in radars, f"{what}: unknown radar {radar!r}")
    _need(kind in _KINDS, f"{what}: kind {kind!r}")
    m = PlaneMeasurement(_number(time, f"{what} time"), tid, radar, _floats(z, 2, f"{what} z"),
                         _floats(C, 4, f"{what} C").reshape(2, 2), _floats(R, 4, f"{what} R").reshape(2, 2))
    return Pending(m, kind)


TIME_BOUND_S = 1e11  # |time| of anything restored (3 000 years of seconds): time differences stay finite


def _time(v: Any, what: str) -> float:
    t = _number(v, what)
    _need(abs(t) <= TIME_BOUND_S, f"{what}: a time within ±{TIME_BOUND_S:g} s expected")
    return t


def _vertical(v: np.ndarray, what: str) -> AltitudeTrack:
    """The Mode C altitude filter (time, h, ḣ, p00, p01, p11) within physical bounds, its covariance positive."""
    t, h, rate, p00, p01, p11 = v.tolist()
    _time(t, what)
    _need(abs(h) <= 1e6 and abs(rate) <= 1e4, f"{what}: altitude and rate out of physical bounds")
    _need(0.0 < p00 <= 1e12 and 0.0 < p11 <= 1e12 and p01 * p01 <= p00 * p11, f"{what}: covariance not positive")
    return AltitudeTrack(t, h, rate, p00, p01, p11)


def _height(doc: Any, radars: int, cfg: ManagerConfig, what: str) -> HeightFilter:
    """A track's height filter (:meth:`HeightFilter.state`'s list: numbers, NaN where it has no fix yet)."""
    _need(isinstance(doc, list) and all(type(x) in (int, float) and not isinstance(x, bool) for x in doc),
          f"{what}: a list of numbers expected")
    try:
        return HeightFilter.of_state(doc, radars, cfg.height)
    except ValueError as exc:
        raise ValueError(f"{what}: {exc}") from None


def _optional_number(doc: dict, key: str, what: str) -> float | None:
    """``doc[key]``, a finite number or None (also where the key is absent)."""
    value = doc.get(key)
    return None if value is None else _number(value, f"{what} {key}")


def _rejection(doc: Any, what: str) -> tuple[float, np.ndarray, float]:
    _need(isinstance(doc, list) and len(doc) == 3, f"{what}: [time, z, sd] expected")
    return _number(doc[0], what), _floats(doc[1], 2, what), _number(doc[2], what)


def _track_of(doc: Any, mgr: Any, what: str) -> Track:
    keys = {"id", "status", "created", "last_update", "mode_s", "mode_3a", "target", "altitude_m", "detections",
            "n_plots", "n_adsb", "pending", "rejected", "vertical", "filter"}
    _need(isinstance(doc, dict) and set(doc) - {"height", "altitude_sd_m"} == keys,
          f"{what}: fields {sorted(keys)} expected")
    cfg, radars = mgr.config, frozenset(mgr.radars)
    tid = _integer(doc["id"], f"{what} id", 1)
    _need(doc["status"] in TRACK_STATUSES[:3], f"{what} status {doc['status']!r}")
    for k in ("mode_s", "mode_3a", "target"):
        _need(doc[k] is None or isinstance(doc[k], str), f"{what} {k}: text expected")
    det = doc["detections"]
    _need(isinstance(det, list) and len(det) <= cfg.confirm_n and all(type(d) is bool for d in det),
          f"{what} detections: at most confirm_n = {cfg.confirm_n} booleans expected")
    _need(isinstance(doc["pending"], list) and (doc["status"] == "tentative" or not doc["pending"]),
          f"{what} pending: only a tentative track holds measurements")
    _need(isinstance(doc["rejected"], list) and len(doc["rejected"]) <= cfg.screening.reinit_after,
          f"{what} rejected: at most reinit_after entries")
    f = doc["filter"]
    _need(isinstance(f, dict) and set(f) == {"class", "config", "state"} and isinstance(f["config"], bytes)
          and isinstance(f["state"], bytes), f"{what} filter: class, config and state expected")
    filt = mgr.new_filter(decode(f["config"]))
    _need(class_name(filt) == f["class"], f"{what} filter: the track filters were {f['class']}, this manager makes "
                                          f"{class_name(filt)}")
    filt.load_state_dict(decode(f["state"]))
    try:  # a track's filter holds an estimate: started, finite
        t, x, P = filt.estimate()
    except (ValueError, TypeError, KeyError, IndexError) as exc:
        raise ValueError(f"{what} filter: {exc}") from None
    _need(isinstance(t, float | int) and math.isfinite(t) and bool(np.isfinite(x).all()) and bool(np.isfinite(P).all()),
          f"{what} filter: its estimate is not finite")
    created, last = (_time(doc[k], f"{what} {k}") for k in ("created", "last_update"))
    _need(created <= last, f"{what}: created after its last update")
    v = doc["vertical"]
    vertical = None if v is None else _vertical(_floats(v, 6, f"{what} vertical"), f"{what} vertical")
    hf = doc.get("height")  # schema 2 and early 3 documents have none
    height = None if hf is None else _height(hf, len(mgr.radars), cfg, f"{what} height")
    return Track(tid, filt, doc["status"], created, last, mode_s=doc["mode_s"], mode_3a=doc["mode_3a"],
                 target=doc["target"],
                 altitude_m=_optional_number(doc, "altitude_m", what),
                 altitude_sd_m=_optional_number(doc, "altitude_sd_m", what),  # absent in older documents
                 detections=deque(det, maxlen=cfg.confirm_n),
                 pending=[_pending_of(p, tid, radars, f"{what} pending[{i}]") for i, p in enumerate(doc["pending"])],
                 n_plots=_integer(doc["n_plots"], f"{what} n_plots"), n_adsb=_integer(doc["n_adsb"], f"{what} n_adsb"),
                 rejected=[_rejection(r, f"{what} rejected[{i}]") for i, r in enumerate(doc["rejected"])],
                 vertical=vertical, height=height)


# --- the manager -----------------------------------------------------------------------------------

def state_document(mgr: Any) -> dict:
    """The state document of ``mgr`` (module docstring)."""
    adm, win = mgr.admission, mgr.window
    return {"counts": dict(mgr.counts), "track_counts": dict(mgr.life.track_counts),
            "innovations": {"count": mgr.life.nis[0], "sum": mgr.life.nis[1]},
            "admission": {"keys": [list(k) for k in adm.keys], "keys_limit": adm.keys_limit,
                          "clock": adm.clock.state_dict(), "held": [input_doc(i) for _, i in adm.held]},
            "window": {"queue": [input_doc(i) for i in win.queue],
                       "heap": [[t, a, input_doc(i)] for t, a, i in win.heap],
                       "arrivals": win.arrivals, "newest": win.newest, "recent": list(win.recent),
                       "horizon": win.horizon},
            "frame": mgr.frame, "gathered": [input_doc(i) for i in mgr.gathered],
            "antennas": mgr.antennas.state_dict(), "adsb_check": mgr.life.adsb_check.state_dict(),
            "tracks": [_track_doc(tr) for tr in mgr.tracks.values()],
            "next_track": mgr.life.next_id,
            "estimator": encode(mgr.estimator.state_dict(), "estimator state"),
            "coupling": encode(mgr.coupling.state_dict(), "coupling graph")}


def load_document(mgr: Any, doc: Any) -> None:
    """Fill the new manager ``mgr`` from state document ``doc``, every field checked first."""
    keys = {"counts", "admission", "window", "frame", "gathered", "antennas", "adsb_check", "tracks", "next_track",
            "estimator", "coupling"}
    _need(isinstance(doc, dict) and set(doc) - {"track_counts", "innovations"} == keys,
          f"state: fields {sorted(keys)} expected")
    radars = frozenset(mgr.radars)
    counts, track_counts = doc["counts"], doc.get("track_counts")
    if track_counts is None and isinstance(counts, dict):  # schema 2 counted them among the inputs' reasons
        counts = dict(counts)
        track_counts = {"tracks_reinitialised": counts.pop("tracks_reinitialised", 0)}
    for what, c in (("counts", counts), ("track_counts", track_counts)):
        _need(isinstance(c, dict) and all(isinstance(k, str) and type(v) is int and v >= 0 for k, v in c.items()),
              f"{what}: reason → count expected")
    nis = _innovations(doc.get("innovations", {"count": 0, "sum": 0.0}))  # a snapshot before them: none yet
    tracks = [_track_of(t, mgr, f"track[{i}]") for i, t in enumerate(_list(doc["tracks"], "tracks"))]
    ids = [t.id for t in tracks]
    next_track = _integer(doc["next_track"], "next_track", 1)
    _need(len(set(ids)) == len(ids) and all(i < next_track for i in ids), "tracks: ids unique and below next_track")
    frame = doc["frame"]
    _need(frame is None or type(frame) is int, "frame: an integer or null")
    gathered = [input_of(x, radars, f"gathered[{i}]") for i, x in enumerate(_list(doc["gathered"], "gathered"))]
    _load_window(mgr.window, doc["window"], radars)
    _load_admission(mgr.admission, doc["admission"], radars)
    mgr.antennas.load_state_dict(_dict(doc["antennas"], "antennas"))
    mgr.life.adsb_check.load_state_dict(_dict(doc["adsb_check"], "adsb_check"))
    _need(isinstance(doc["estimator"], bytes) and isinstance(doc["coupling"], bytes), "estimator, coupling: bytes")
    mgr.estimator.load_state_dict(decode(doc["estimator"]))
    mgr.coupling.load_state_dict(decode(doc["coupling"]))
    mgr.feed.forget()
    live = {t.id for t in tracks if t.status != "tentative"}
    _need(set(mgr.estimator.aircraft_keys) == live, "estimator: its aircraft are not the confirmed tracks")
    mgr.counts.update(counts)
    mgr.life.track_counts.update(track_counts)
    mgr.life.nis = nis
    mgr.frame, mgr.gathered = frame, gathered
    mgr.life.tracks = {t.id: t for t in tracks}
    mgr.life.by_mode_s = {t.mode_s: t.id for t in tracks if t.mode_s is not None}
    mgr.life.by_target = {t.target: t.id for t in tracks if t.target is not None}
    mgr.life.next_id = next_track


def _innovations(doc: Any) -> list:
    """[count, sum] of the confirmed tracks' d² from ``{"count", "sum"}``."""
    _need(isinstance(doc, dict) and set(doc) == {"count", "sum"}, "innovations: fields count, sum expected")
    count, total = _integer(doc["count"], "innovations count"), _number(doc["sum"], "innovations sum")
    _need(total >= 0.0 and (count > 0 or total == 0.0), "innovations: a sum of d² ≥ 0, 0 without a count")
    return [count, total]


def _list(v: Any, what: str) -> list:
    _need(isinstance(v, list), f"{what}: a list expected")
    return v


def _dict(v: Any, what: str) -> dict:
    _need(isinstance(v, dict), f"{what}: a map expected")
    return v


def _load_window(win: Any, doc: Any, radars: frozenset) -> None:
    fields = {"queue", "heap", "arrivals", "newest", "horizon"}
    _need(isinstance(doc, dict) and set(doc) - {"recent"} == fields, "window: fields")
    queue = [input_of(x, radars, f"window queue[{i}]") for i, x in enumerate(_list(doc["queue"], "window queue"))]
    heap = []
    for i, e in enumerate(_list(doc["heap"], "window heap")):
        _need(isinstance(e, list) and len(e) == 3, f"window heap[{i}]: [time, arrival, input] expected")
        item = input_of(e[2], radars, f"window heap[{i}]")
        _need(_number(e[0], f"window heap[{i}]") == item.time, f"window heap[{i}]: time is not the input's")
        heap.append((item.time, _integer(e[1], f"window heap[{i}] arrival"), item))
    heap.sort()
    newest = None if doc["newest"] is None else _number(doc["newest"], "window newest")
    horizon = _number(doc["horizon"], "window horizon", finite=False)
    _need(not math.isnan(horizon) and horizon < math.inf, "window horizon: below +inf expected")
    _need(all(newest is not None and horizon < x.time <= newest for x in queue + [h[2] for h in heap]),
          "window: inputs after the horizon and at most the newest time expected")
    win.queue, win.heap = deque(queue), heap
    win.arrivals = _integer(doc["arrivals"], "window arrivals")
    win.newest, win.horizon = newest, horizon
    recent = doc.get("recent", [] if newest is None else [newest])  # schema 2: its newest time stands for them
    recent = [_number(t, "window recent") for t in _list(recent, "window recent")]
    _need(len(recent) <= win.recent.maxlen and all(newest is not None and t <= newest for t in recent),
          f"window recent: at most {win.recent.maxlen} times, none after the newest, expected")
    win.recent.extend(recent)
    win.pushes = len(recent)
    win.recount()


def _load_admission(adm: Any, doc: Any, radars: frozenset) -> None:
    _need(isinstance(doc, dict) and set(doc) == {"keys", "keys_limit", "clock", "held"}, "admission: fields")
    held = [input_of(x, radars, f"admission held[{i}]") for i, x in enumerate(_list(doc["held"], "admission held"))]
    keys = {}
    for i, k in enumerate(_list(doc["keys"], "admission keys")):
        _need(isinstance(k, list) and len(k) == 5 and k[0] in ("p", "a", "m"), f"admission keys[{i}]: 5 fields")
        keys[tuple(k)] = _number(k[2], f"admission keys[{i}] time")
    adm.keys, adm.keys_limit = keys, _integer(doc["keys_limit"], "admission keys_limit", 1)
    clock = _dict(doc["clock"], "admission clock")
    _need(set(clock) == {"recent", "run"} and all(isinstance(clock[k], list) for k in clock), "admission clock")
    for k in ("recent", "run"):
        for t in clock[k]:
            _number(t, f"admission clock {k}")
    _need(len(held) == len(clock["run"]) and len(held) < adm.clock.config.step_after,
          "admission held: the inputs of the clock's run expected")
    adm.clock.load_state_dict(clock)
    adm.held = [(adm._key(i), i) for i in held]


# --- files -----------------------------------------------------------------------------------------

def save_manager(mgr: Any, path: Path | str) -> None:
    """Write ``mgr``'s meta and state document to ``path``, atomically."""
    meta = {"kind": "TrackManager", "schema": SCHEMA, "radars": list(mgr.radars.values()),
            "reference": list(mgr.reference), "config": mgr.config, "estimator": class_name(mgr.estimator),
            "associator": mgr.associator.name}
    try:
        payload = encode([meta, encode(state_document(mgr), "manager")], "manager")
    except (OverflowError, ValueError, TypeError) as exc:  # an unsupported type, an int beyond 64 bits
        raise SnapshotError(str(path), f"not written: {exc}") from None
    write_snapshot_file(path, payload)


def read_manager(path: Path | str) -> tuple[dict, bytes]:
    """(meta, state bytes) of a manager snapshot; :class:`SnapshotError` for anything else."""
    payload = read_snapshot_file(path)
    try:
        meta, blob = decode(payload)
        _need(isinstance(meta, dict) and meta.get("kind") == "TrackManager" and isinstance(blob, bytes),
              "the payload is not a TrackManager snapshot")
        _need(meta.get("schema") in READS, f"schema {meta.get('schema')!r}, this release reads {READS}")
        _need(set(meta) == {"kind", "schema", "radars", "reference", "config", "estimator", "associator"},
              "meta: fields")
        _need(isinstance(meta["radars"], list) and meta["radars"] and all(isinstance(r, Radar) for r in meta["radars"])
              and len({r.id for r in meta["radars"]}) == len(meta["radars"]), "meta radars: distinct radars expected")
        _floats(meta["reference"], 2, "meta reference")
        _need(isinstance(meta["config"], ManagerConfig), "meta config: a ManagerConfig expected")
        _need(isinstance(meta["estimator"], str) and isinstance(meta["associator"], str), "meta: plugin names")
    except Exception as exc:  # anything a crafted but well-checksummed payload can provoke in the decoder
        raise SnapshotError(str(path), f"cannot restore: {type(exc).__name__}: {exc}") from None
    return meta, blob


def restore_state(mgr: Any, meta: dict, blob: bytes, path: Path | str) -> Any:
    """``mgr`` (new, built from ``meta``) filled with the state in ``blob``; :class:`SnapshotError`
    naming ``path`` for a state that fails its checks or its plugins' own."""
    try:
        _need(class_name(mgr.estimator) == meta["estimator"], f"the estimator was {meta['estimator']}, this "
              f"manager makes {class_name(mgr.estimator)} (pass the estimator it was made with)")
        load_document(mgr, decode(blob))
    except SnapshotError:
        raise
    except Exception as exc:  # anything a crafted but well-checksummed file can provoke
        raise SnapshotError(str(path), f"cannot restore: {type(exc).__name__}: {exc}") from None
    return mgr

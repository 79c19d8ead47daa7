"""System tracks read from a CAT062 recording, to be assessed instead of the replay's own tracks.

* **Positions**: each update's I105 (WGS-84) projected into the assessment's system plane
  (:class:`radartracker.geometry.plane.SystemPlane`, where the reference lies), as ``radartracker score``
  does. I100 is in the sending system's own plane, which the recording does not name, so it is not used
  even where it would match. I185 (the velocity, which carries a position between updates) is taken as it
  is: between two stereographic planes a few degrees apart the axes turn by under a degree. An update
  without I105 or I185 is refused, naming the file, the record and the item.
* **Track identity**: a CAT062 track number (I040, 16 bits) names one track of its sender (I010 SAC/SIC)
  only while it lives: trackers reuse numbers once a track has ended. Each sender's number's updates, in time
  order, form one track until an update marked ended (I080 TSE), after which the next update starts a new
  track, or until the next update comes more than :attr:`SystemTrackConfig.max_gap_s` later (then it starts
  a new track too). A track lives from its first update to its TSE update, else to its last update (what
  the recording shows of it).
* **Latency**: the time from an update's time of applicability (I070) to its delivery. A recording holds
  the delivery time only as a pcap packet's capture time; raw blocks and FINAL files carry none, and
  CAT062 as the project writes it has no I290 (update ages), so there latency is not assessable.
"""

from __future__ import annotations

import math
from pathlib import Path

import attrs
import numpy as np

from radartracker.errors import InputError
from radartracker.geometry.plane import SystemPlane
from radartracker.io.asterix import DAY
from radartracker.io.asterix_reader import read_cat062
from radartracker.pipeline.evaluate import TrackHistory


@attrs.frozen
class SystemTrackConfig:
    """How a CAT062 recording's updates become tracks (module docstring).

    ``max_gap_s``: a track number's updates further apart than this are two tracks (60 s: longer than the
    replay's ``delete_after_s`` = 40 s, the longest a track of ours goes without an update, so none of ours
    is cut; shorter than a tracker keeps a freed number before reusing it). ``day_start``: the UTC midnight
    (seconds since 1970) of a raw or FINAL file's first record, whose I070 is a time of day; None (default):
    the midnight before the recording's first plot (a pcap's own packet times win either way).
    """

    max_gap_s: float = 60.0
    day_start: float | None = None


@attrs.frozen
class SystemTracks:
    """The tracks of a CAT062 recording: histories by track (numbered 0, 1, … in order of their first update),
    each track's CAT062 number, and each update's delivery latency (s; empty without delivery times:
    ``no_latency`` says why)."""

    source: str
    histories: dict[int, TrackHistory]
    numbers: dict[int, int]
    latency_s: np.ndarray
    no_latency: str


def read_system_tracks(path: Path | str, plane: SystemPlane, config: SystemTrackConfig | None = None,
                       first_plot: float = 0.0) -> SystemTracks:
    """The system tracks of the CAT062 recording ``path`` in ``plane`` (module docstring; ``first_plot``: the
    recording's first plot time, whose day a raw file's times of day fall on by default); an
    :class:`InputError` naming the file (and the update and item) when it has none that can be used."""
    config = config or SystemTrackConfig()
    day = config.day_start if config.day_start is not None else math.floor(first_plot / DAY) * DAY
    records = read_cat062(path, day_start=day)
    live = [r for r in records if not r["ended"]]
    if not live:
        raise InputError(f"{path}: no CAT062 track update with I010, I040, I070 and I080 (an ended track's record "
                         "alone is not an update)")
    for item, fields in (("I105 (WGS-84 position)", ("lat", "lon")), ("I185 (velocity)", ("vx_mps", "vy_mps"))):
        bad = [k for k, r in enumerate(records) if not r["ended"] and any(r[f] is None for f in fields)]
        if bad:
            more = f" and {len(bad) - 1} more" if len(bad) > 1 else ""
            raise InputError(f"{path}: CAT062 record {bad[0]} (track {records[bad[0]]['track_number']}){more}: "
                             f"field {item} missing")
    x, y = plane.to_plane(np.array([r["lat"] for r in live], float), np.array([r["lon"] for r in live], float))
    for r, xi, yi in zip(live, x.tolist(), y.tolist()):
        r["x_m"], r["y_m"] = xi, yi
    histories, numbers = split_tracks(records, config.max_gap_s)
    received = [r["received"] for r in live]
    if any(v is None for v in received):
        latency, why = np.zeros(0), ("the recording carries no delivery time (raw or FINAL blocks; only a pcap's "
                                     "packet times give one) and no I290 update ages")
    else:
        latency, why = np.array(received, float) - np.array([r["time"] for r in live], float), ""
    return SystemTracks(str(path), histories, numbers, latency, why)


def split_tracks(records: list[dict], max_gap_s: float) -> tuple[dict[int, TrackHistory], dict[int, int]]:
    """(histories by track, each track's CAT062 number) of decoded CAT062 records with plane ``x_m``, ``y_m``
    (module docstring, track identity): per sender (SAC/SIC) and number in time order (the last record wins at
    equal times; an ended record after the updates at its time), a new track after a TSE record or a gap over
    ``max_gap_s``."""
    per: dict[tuple[int, int, int], list[dict]] = {}
    for r in records:
        per.setdefault((r["sac"], r["sic"], r["track_number"]), []).append(r)
    pieces: list[tuple[int, list[dict], float | None]] = []
    for (_, _, number), recs in per.items():
        recs = sorted(recs, key=lambda r: (r["time"], r["ended"]))
        current: list[dict] = []
        for r in recs:
            if r["ended"]:
                if current:
                    pieces.append((number, current, r["time"]))
                current = []
                continue
            if current and r["time"] - current[-1]["time"] > max_gap_s:
                pieces.append((number, current, None))
                current = []
            current.append(r)
        if current:
            pieces.append((number, current, None))
    pieces.sort(key=lambda p: p[1][0]["time"])
    histories, numbers = {}, {}
    for k, (number, recs, end) in enumerate(pieces):
        at = {r["time"]: r for r in recs}  # the last record wins at equal times
        t = np.array(sorted(at), float)
        states = np.array([[at[v]["x_m"], at[v]["y_m"], at[v]["vx_mps"], at[v]["vy_mps"]] for v in t.tolist()],
                          float)
        histories[k] = TrackHistory(t, states, float(t[0]), float(t[-1]) if end is None else max(end, float(t[-1])))
        numbers[k] = number
    return histories, numbers


def within(tracks: SystemTracks, start: float, stop: float) -> None:
    """Refuse system tracks none of which lives within the recording's [``start``, ``stop``] (s): their times
    are on another day or clock (a raw CAT062 file's day: ``SystemTrackConfig.day_start``)."""
    lo = min((h.start for h in tracks.histories.values()), default=math.nan)
    hi = max((h.end for h in tracks.histories.values()), default=math.nan)
    if not (lo <= stop and hi >= start):
        raise InputError(f"{tracks.source}: field I070 (time of track information): the tracks span "
                         f"[{lo:.3f}, {hi:.3f}] s, outside the recording's [{start:.3f}, {stop:.3f}] s "
                         "(another day or clock?)")

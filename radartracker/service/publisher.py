"""System tracks out: CAT062 datagrams, one record per confirmed or coasting track.

Two kinds of publication (the service's ``--publish-mode`` chooses which it sends): *periodic* —
every confirmed or coasting track, every period (the full picture a display refreshes from) — and
*on update* — the tracks a frame of the tracker just updated, confirmed or put in coasting, sent as
soon as that frame is processed (ARTAS-style asynchronous output: the latency is the tracker's, not
the period's).

Each record carries the track's latest estimate at the time of its last update (I070 — not
extrapolated: a consumer extrapolates with I185 to its own display time), position in WGS-84
(I105) and in the system plane (I100), velocity (I185), flight level (I136), Mode 3/A (I060) and
Mode S address (I380/ADR) when known, I080 with CST set while coasting. A track that ends is sent
once more with TSE set, at the time of its deletion, with its last codes (after a restart: every
track confirmed in the checkpoint counts as published). Track numbers (I040) are the manager's
track ids modulo 65 535, in 1…65 535.
"""

from __future__ import annotations

import logging
import math
import socket
from collections import Counter
from collections.abc import Iterable

import numpy as np

from radartracker.service.codec import blocks, cat062_bytes
from radartracker.geometry.plane import SystemPlane
from radartracker.tracking.events import TrackEvent
from radartracker.tracking.manager import TrackManager

log = logging.getLogger(__name__)

UDP_PAYLOAD = 1472  # an Ethernet frame's UDP payload (1500 − IP and UDP headers): no IP fragments


def track_number(track_id: int) -> int:
    return (track_id - 1) % 65_535 + 1


def track_rows(mgr: TrackManager, ids: Iterable[int] | None = None) -> list[dict]:
    """The confirmed and coasting tracks (only those of ``ids`` if given) as the rows of ``/tracks``
    (one geodetic conversion for all)."""
    if ids is None:
        trs = mgr.confirmed_tracks()
    else:
        trs = [tr for tr in map(mgr.tracks.get, ids) if tr is not None and tr.status in ("confirmed", "coasting")]
    est = [tr.filter.estimate() for tr in trs]
    x = np.array([e[1] for e in est], float).reshape(-1, 4)
    lat, lon = mgr.plane.to_geodetic(x[:, 0], x[:, 1]) if len(trs) else (np.empty(0), np.empty(0))
    return [{"track_number": track_number(tr.id), "id": tr.id, "status": tr.status, "time": float(t),
             "lat": float(la), "lon": float(lo), "x_m": float(xi[0]), "y_m": float(xi[1]), "vx_mps": float(xi[2]),
             "vy_mps": float(xi[3]), "sd_x_m": math.sqrt(P[0, 0]), "sd_y_m": math.sqrt(P[1, 1]),
             "altitude_m": tr.altitude_m, "mode_3a": tr.mode_3a, "mode_s": tr.mode_s}
            for tr, (t, _, P), xi, la, lo in zip(trs, est, x, lat, lon)]


class Publisher:
    """Sends system tracks as CAT062 (SAC/SIC of this tracker: ``sac``, ``sic``)."""

    def __init__(self, sock: socket.socket, sac: int = 0, sic: int = 100, max_datagram: int = UDP_PAYLOAD) -> None:
        self.sock, self.sac, self.sic, self.max_datagram = sock, sac, sic, max_datagram
        self.counts: Counter[str] = Counter()
        self._published: dict[int, tuple] = {}  # track id → (Mode 3/A, Mode S) of tracks sent, to announce their end
        self.last_records = 0  # records of the latest full publication (the final one, after a stop)

    def remember(self, mgr: TrackManager) -> None:
        """Count the manager's confirmed tracks as published (a resumed service announces their end)."""
        self._published |= {tr.id: (tr.mode_3a, tr.mode_s) for tr in mgr.confirmed_tracks()}

    def _fits(self, x: float, y: float, vx: float, vy: float) -> bool:
        """Whether a state fits CAT062 (I100 ±4 194 km at 0.5 m, I185 ±8 192 m/s at 0.25 m/s); one that does
        not is counted ``cat062_records_out_of_range`` and not sent, never a failed publication."""
        if abs(x) < 4_194_000.0 and abs(y) < 4_194_000.0 and abs(vx) < 8_190.0 and abs(vy) < 8_190.0:
            return True
        if not self.counts["cat062_records_out_of_range"]:
            log.warning("a track state beyond CAT062's range (x %.0f m, y %.0f m) not sent; counted", x, y)
        self.counts["cat062_records_out_of_range"] += 1
        return False

    def publish(self, rows: list[dict], ended: list[TrackEvent], plane: SystemPlane, full: bool = True) -> int:
        """Send the tracks ``rows`` (:func:`track_rows`) and the ends of published tracks; returns the
        records sent. ``full``: a periodic publication (every track), else an on-update one."""
        rows = [r for r in rows if self._fits(r["x_m"], r["y_m"], r["vx_mps"], r["vy_mps"])]
        recs = [cat062_bytes(r["time"], self.sac, self.sic, r["track_number"], r["lat"], r["lon"], r["x_m"], r["y_m"],
                             r["vx_mps"], r["vy_mps"], r["altitude_m"], mode_3a=r["mode_3a"], mode_s=r["mode_s"],
                             coasting=r["status"] == "coasting") for r in rows]
        ends = [ev for ev in ended if ev.track in self._published and self._fits(*ev.state)]
        if ends:
            x = np.array([ev.state for ev in ends], float)
            lat, lon = plane.to_geodetic(x[:, 0], x[:, 1])
            recs += [cat062_bytes(ev.time, self.sac, self.sic, track_number(ev.track), float(la), float(lo), *ev.state,
                                  mode_3a=self._published[ev.track][0], mode_s=self._published[ev.track][1], ended=True)
                     for ev, la, lo in zip(ends, lat, lon)]
            for ev in ends:
                del self._published[ev.track]
        self._published |= {r["id"]: (r["mode_3a"], r["mode_s"]) for r in rows}
        if not recs and not full:  # only ends of tracks never published: nothing to send
            return 0
        for block in blocks(62, recs, self.max_datagram):
            try:
                self.sock.send(block)
                self.counts["cat062_datagrams_sent"] += 1
            except OSError:  # nobody listening (ICMP port unreachable) or a full buffer: counted, never fatal
                self.counts["cat062_datagrams_send_failed"] += 1
        self.counts["cat062_records"] += len(recs)
        if full:
            self.counts["publications"] += 1
            self.last_records = len(recs)
        else:
            self.counts["publications_on_update"] += 1
        return len(recs)

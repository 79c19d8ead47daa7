"""System tracks out: CAT062 datagrams, one record per confirmed or coasting track.

Each record carries the track's latest estimate at the time of its last update (I070 — not
extrapolated: a consumer extrapolates with I185 to its own display time), position in WGS-84
(I105) and in the system plane (I100), velocity (I185), flight level (I136), Mode 3/A (I060) and
Mode S address (I380/ADR) when known, I080 with CST set while coasting. A track that ends is sent
once more with TSE set, at the time of its deletion. Track numbers (I040) are the manager's track
ids modulo 65 535, in 1…65 535.
"""

from __future__ import annotations

import socket
from collections import Counter

from radartracker.service.codec import blocks, cat062_bytes
from radartracker.tracking.manager import ManagedTrack, TrackEvent, TrackManager

UDP_PAYLOAD = 1472  # an Ethernet frame's UDP payload (1500 − IP and UDP headers): no IP fragments


def track_number(track_id: int) -> int:
    return (track_id - 1) % 65_535 + 1


class Publisher:
    """Sends the manager's system tracks as CAT062 (SAC/SIC of this tracker: ``sac``, ``sic``)."""

    def __init__(self, sock: socket.socket, sac: int = 0, sic: int = 100, max_datagram: int = UDP_PAYLOAD) -> None:
        self.sock, self.sac, self.sic, self.max_datagram = sock, sac, sic, max_datagram
        self.counts: Counter[str] = Counter()
        self._published: set[int] = set()  # track ids sent at least once, to announce their end
        self.last_records = 0  # records of the latest publication (the final one, after a stop)

    def publish(self, mgr: TrackManager, ended: list[TrackEvent]) -> int:
        """Send every confirmed/coasting track and the ends of published tracks; returns the records sent."""
        recs = [self._record(mgr, tr) for tr in mgr.confirmed_tracks()]
        for ev in ended:
            if ev.track in self._published:
                self._published.discard(ev.track)
                recs.append(self._end_record(mgr, ev))
        self._published |= {tr.id for tr in mgr.confirmed_tracks()}
        for block in blocks(62, recs, self.max_datagram):
            try:
                self.sock.send(block)
                self.counts["cat062_datagrams_sent"] += 1
            except OSError:  # nobody listening (ICMP port unreachable) or a full buffer: counted, never fatal
                self.counts["cat062_datagrams_send_failed"] += 1
        self.counts["cat062_records"] += len(recs)
        self.counts["publications"] += 1
        self.last_records = len(recs)
        return len(recs)

    def _record(self, mgr: TrackManager, tr: ManagedTrack):
        t, x, _ = tr.filter.estimate()
        lat, lon = mgr.plane.to_geodetic(x[0], x[1])
        return cat062_bytes(t, self.sac, self.sic, track_number(tr.id), float(lat), float(lon), x[0], x[1], x[2], x[3],
                             tr.altitude_m, mode_3a=tr.mode_3a, mode_s=tr.mode_s, coasting=tr.status == "coasting")

    def _end_record(self, mgr: TrackManager, ev: TrackEvent):
        x = ev.state
        lat, lon = mgr.plane.to_geodetic(x[0], x[1])
        return cat062_bytes(ev.time, self.sac, self.sic, track_number(ev.track), float(lat), float(lon), *x,
                             ended=True)

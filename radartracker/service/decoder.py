"""Datagrams → plots and ADS-B reports, every datagram, block and record counted.

A datagram holds one or more ASTERIX data blocks. A datagram whose block lengths do not add up is
rejected whole (``datagrams_malformed``: its records cannot be counted); a block that does not
decode is ``blocks_undecodable``; blocks of categories other than 048 and 021 are
``blocks_other_category``. Blocks are read by :mod:`radartracker.service.codec` when their layout
allows, else by libasterix (the same values either way). Each CAT048/CAT021 record becomes a :class:`Plot` / :class:`AdsbReport`
or is counted under ``cat048_unknown_sac_sic``, ``cat048_invalid`` or ``cat021_invalid``.

Time: ASTERIX carries the UTC time of day only. Live data take the day from the receive clock —
t = D + tod with D the midnight that puts t nearest the receive time, right across midnight as long
as the clocks agree within 12 h (:class:`ReceiveClock`). A recording replayed onto the network can
be given its day instead (``day_start``), read like ``asterix-import`` does.
"""

from __future__ import annotations

import math
from collections import Counter

from radartracker.domain import AdsbReport, Plot
from radartracker.io.asterix import DAY, decode_block, decode_cat021, decode_cat048
from radartracker.io.asterix_reader import Clock
from radartracker.io.capture import blocks_in
from radartracker.service.codec import decode_block_fast


class ReceiveClock:
    """t = D + tod, D = DAY · round((t_received − tod) / DAY): the midnight nearest in time."""

    def __call__(self, tod: float, received: float) -> float:
        return math.floor((received - tod) / DAY + 0.5) * DAY + tod


class DayClock:
    """t = day_start + tod, a day added at each backwards wrap of the time of day (recordings)."""

    def __init__(self, day_start: float) -> None:
        self._clock = Clock(day_start)

    def __call__(self, tod: float, received: float) -> float:
        return self._clock(tod)


# What a record lacking a mandatory item or holding an impossible value raises while decoding or
# building the domain object: counted as an invalid record, never a crash of the service.
_BAD_RECORD = (ValueError, TypeError, AttributeError, KeyError)


class Decoder:
    """Turns datagrams into domain objects; :attr:`counts` holds the accounting (module notes)."""

    def __init__(self, sites: dict[tuple[int, int], str], clock: ReceiveClock | DayClock) -> None:
        self.sites, self.clock = sites, clock
        self.counts: Counter[str] = Counter()

    def decode(self, payload: bytes, received: float) -> list[Plot | AdsbReport]:
        """The plots and reports of one datagram received at ``received`` (s since 1970)."""
        c = self.counts
        try:
            blocks = list(blocks_in(payload, "datagram"))
        except ValueError:
            c["datagrams_malformed"] += 1
            return []
        c["datagrams_decoded"] += 1
        out: list[Plot | AdsbReport] = []
        for block in blocks:
            fast = decode_block_fast(block)
            if fast is not None:
                cat, dicts = fast
                recs = [(d, None) for d in dicts]
            else:
                try:
                    cat, raw = decode_block(block, "datagram")
                except ValueError:
                    c["blocks_undecodable"] += 1
                    continue
                recs = [(None, r) for r in raw]
            if cat == 48:
                c["cat048_records"] += len(recs)
                out += filter(None, (self._plot(d, r, received) for d, r in recs))
            elif cat == 21:
                c["cat021_records"] += len(recs)
                out += filter(None, (self._report(d, r, received) for d, r in recs))
            else:
                c["blocks_other_category"] += 1
        c["records_to_tracker"] += len(out)
        return out

    def _plot(self, d: dict | None, rec, received: float) -> Plot | None:
        try:
            d = d or decode_cat048(rec)
            radar = self.sites.get((d["sac"], d["sic"]))
            if radar is None:
                self.counts["cat048_unknown_sac_sic"] += 1
                return None
            alt = d["altitude_m"]
            return Plot(self.clock(d["tod"], received), radar, d["range_m"], d["azimuth_rad"],
                        None if math.isnan(alt) else alt, d["mode_s"], d["mode_3a"])
        except _BAD_RECORD:
            self.counts["cat048_invalid"] += 1
            return None

    def _report(self, d: dict | None, rec, received: float) -> AdsbReport | None:
        try:
            d = d or decode_cat021(rec)
            alt = d["altitude_m"]
            return AdsbReport(self.clock(d["tod"], received), d["icao24"], d["lat"], d["lon"],
                              None if math.isnan(alt) else alt, 8 if d["nacp"] is None else d["nacp"])
        except _BAD_RECORD:
            self.counts["cat021_invalid"] += 1
            return None

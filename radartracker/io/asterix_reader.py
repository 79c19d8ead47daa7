"""An ASTERIX recording (raw, FINAL or pcap; :mod:`radartracker.io.capture`) read into a
:class:`~radartracker.io.tables.ScenarioData` (CAT048 plots, CAT021 ADS-B) or into CAT062 track
updates; the records are decoded by :mod:`radartracker.io.asterix`.

Time: ASTERIX times are seconds of the UTC day. Reading adds ``day_start`` (seconds since 1970 of
the first day's midnight; from the first packet's time stamp for pcap) and a day each time the time
of day wraps back by more than half a day: t = D₀ + k · 86400 + tod (:class:`Clock`). A pcap packet's
capture time is when its plots were delivered (``PlotTable.received``; NaN in a raw or FINAL file).

Sites: CAT048 carries no radar site. The sites come from a sidecar ``<file>.radars.csv`` (the
scenario ``radars.csv`` columns plus ``sac`` and ``sic``), which
:func:`~radartracker.io.asterix.write_asterix` writes; each SAC/SIC names one radar.

Input accounting: every record is used or counted in ``ScenarioData.skipped`` under a named reason.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from radartracker.domain import Aircraft, Radar
from radartracker.errors import FormatError, InputError
from radartracker.io.asterix import (DAY, MissingItem, decode_block, decode_cat021, decode_cat048, decode_cat062,
                                     sidecar_of)
from radartracker.io.capture import iter_datablocks
from radartracker.io.csvblocks import Rows
from radartracker.io.scenario import read_radars
from radartracker.io.tables import RADAR_COLUMNS, AdsbTable, PlotTable, ScenarioData
from radartracker.progress import progress_bar

log = logging.getLogger(__name__)


class Clock:
    """Absolute time from time of day: day_start plus a day at each backwards wrap."""

    def __init__(self, day_start: float) -> None:
        self.base, self.last = day_start, None

    def __call__(self, tod: float) -> float:
        if self.last is not None and tod < self.last - DAY / 2:
            self.base += DAY
        self.last = tod
        return self.base + tod


def clocked_blocks(path: Path | str, bad: Counter | None,
                   day_start: float) -> Iterator[tuple[Clock, str, bytes, float | None]]:
    """(clock, where, data block, its packet's capture time or None) of each block of a recording, in file
    order.

    One :class:`Clock` serves the whole file; its first day is the midnight before the first packet's
    time stamp (pcap), else ``day_start``. ``bad``: as :func:`~radartracker.io.capture.iter_datablocks`.
    """
    clock = None
    for k, (stamp, block) in enumerate(iter_datablocks(path, bad)):
        if clock is None:
            clock = Clock(math.floor(stamp / DAY) * DAY if stamp is not None else day_start)
        yield clock, f"{path}: data block {k}", block, stamp


def read_sites(path: Path) -> tuple[list[Radar], dict[tuple[int, int], str]]:
    """Radar sites and the SAC/SIC → radar id map of a ``.radars.csv`` sidecar (each SAC/SIC once)."""
    radars = read_radars(path)
    rows = Rows(path, RADAR_COLUMNS + ("sac", "sic"))
    ids: dict[tuple[int, int], str] = {}
    first: dict[tuple[int, int], int] = {}
    for line, row in rows:
        key = tuple(int(rows.number(row, line, f, check=_byte)) for f in ("sac", "sic"))
        if key in ids:
            raise FormatError(rows.name, line, "sac/sic", f"SAC/SIC {key[0]}/{key[1]} already belongs to radar "
                              f"{ids[key]!r} on line {first[key]}")
        ids[key], first[key] = rows.text(row, "radar"), line
    return radars, ids


def _byte(v: float) -> str | None:
    return None if v == int(v) and 0 <= v <= 255 else "is not an integer 0..255"


def decoded_records(cat: int, recs: list, decode: Callable[[object], dict], skipped: Counter) -> Iterator[dict]:
    """Decoded records; those without an item we need are skipped and counted by item."""
    for r in recs:
        try:
            yield decode(r)
        except MissingItem as exc:
            key = f"asterix_cat{cat:03d}_records_without_I{exc.item}"
            if not skipped[key]:
                log.warning("skipping CAT%03d records without I%s (counted under %s)", cat, exc.item, key)
            skipped[key] += 1


def _first(rec: dict, seen: set[tuple], skipped: Counter, reason: str) -> bool:
    """False for a record equal to one read before (a redundant feed recorded twice), counted."""
    key = (reason, *sorted((k, v) for k, v in rec.items() if not (isinstance(v, float) and math.isnan(v))))
    if key in seen:
        skipped[reason] += 1
        return False
    seen.add(key)
    return True


def read_asterix(path: Path | str, *, radars: Path | str | None = None, day_start: float = 0.0,
                 skip_bad: bool = False) -> ScenarioData:
    """Read a CAT048/CAT021 recording (raw, FINAL or pcap) as a scenario (see the module notes).

    Skipped and counted in ``skipped`` (never an error): blocks of other categories, blocks the
    library cannot decode (other editions, damaged bytes), records without an item we need (e.g. a
    CAT048 track-only report without I040), ADS-B reports with an impossible position or a NACp
    of 0 (accuracy unknown) or above 11, records equal to one read before (used once). With
    ``skip_bad`` also framing that cannot be read (the rest of the file, or one pcap packet) and plots
    whose SAC/SIC the sidecar lacks; without it those are :class:`InputError` naming the file and
    byte. A recording with nothing usable is an error.
    """
    path = Path(path)
    sites_path = Path(radars) if radars is not None else sidecar_of(path)
    skipped: Counter = Counter()
    plots, adsb = _read_reports(path, day_start, skipped if skip_bad else None, skipped)
    site_list, ids, plots = _with_sites(path, sites_path, plots, skip_bad, skipped)
    if not plots and not adsb:
        raise InputError(f"{path}: no usable CAT048 plot or CAT021 report"
                         + (f" (skipped: {dict(sorted(skipped.items()))})" if skipped else ""))
    return _scenario(path.stem, plots, adsb, site_list, ids, skipped)


def _read_reports(path: Path, day_start: float, bad: Counter | None,
                  skipped: Counter) -> tuple[list[dict], list[dict]]:
    """The usable CAT048 plots and CAT021 reports of a recording, as decoded dicts with ``time``."""
    plots: list[dict] = []
    adsb: list[dict] = []
    seen: set[tuple] = set()
    # bytes of the file: the blocks, then the framing between them (FINAL, pcap) once all are read; the bar
    # shows on stderr once reading takes 2 s (off with --quiet): decoding is pure Python
    with progress_bar(total=path.stat().st_size, desc=f"read {path.name}", unit="B", unit_scale=True) as bar:
        for clock, where, block, stamp in clocked_blocks(path, bad, day_start):
            bar.update(len(block))
            try:
                cat, recs = decode_block(block, where)
            except InputError as exc:
                if not skipped["asterix_undecodable_blocks"]:
                    log.warning("skipping blocks that do not decode (counted): %s", exc)
                skipped["asterix_undecodable_blocks"] += 1
                continue
            if cat == 48:
                plots += _plots(recs, clock, stamp, seen, skipped)
            elif cat == 21:
                adsb += _adsb(recs, clock, seen, skipped)
            else:
                skipped[f"asterix_cat{cat:03d}_blocks"] += 1
        bar.update(bar.total - bar.n)
    return plots, adsb


def _plots(recs: list, clock: Clock, stamp: float | None, seen: set[tuple], skipped: Counter) -> list[dict]:
    """The CAT048 records of one block that decode and were not read before (a record delivered twice is
    one plot, delivered when first seen); ``received``: the block's capture time (NaN without one)."""
    out = []
    for p in decoded_records(48, recs, decode_cat048, skipped):
        p["time"] = clock(p["tod"])
        if _first(p, seen, skipped, "asterix_cat048_duplicate_records"):
            p["received"] = math.nan if stamp is None else stamp
            out.append(p)
    return out


def _adsb(recs: list, clock: Clock, seen: set[tuple], skipped: Counter) -> list[dict]:
    """The CAT021 records of one block that decode, hold a possible position and a usable NACp, and
    were not read before."""
    out = []
    for a in decoded_records(21, recs, decode_cat021, skipped):
        if not (-90.0 <= a["lat"] <= 90.0 and -180.0 <= a["lon"] <= 180.0):
            skipped["asterix_cat021_impossible_positions"] += 1
            continue
        if a["nacp"] is not None and not 1 <= a["nacp"] <= 11:  # 0: accuracy unknown; 12-15 undefined
            skipped["asterix_cat021_unusable_nacp"] += 1
            continue
        a["time"] = clock(a["tod"])
        if _first(a, seen, skipped, "asterix_cat021_duplicate_records"):
            out.append(a)
    return out


def _with_sites(path: Path, sites_path: Path, plots: list[dict], skip_bad: bool,
                skipped: Counter) -> tuple[list[Radar], dict[tuple[int, int], str], list[dict]]:
    """(sites, SAC/SIC → radar id, the plots of known sites): a sidecar is needed as soon as there are
    plots; a plot of a SAC/SIC the sidecar lacks is an error, or with ``skip_bad`` skipped and counted."""
    seen = sorted({(p["sac"], p["sic"]) for p in plots})
    if seen and not sites_path.exists():
        raise FileNotFoundError(
            f"{path}: CAT048 plots from SAC/SIC {', '.join(f'{a}/{b}' for a, b in seen)} but no radar sites: "
            f"write {sites_path} (columns {', '.join(RADAR_COLUMNS)}, sac, sic)")
    site_list, ids = read_sites(sites_path) if sites_path.exists() else ([], {})
    unknown = [f"{a}/{b}" for a, b in seen if (a, b) not in ids]
    if unknown and not skip_bad:
        raise FormatError(sites_path.name, None, "sac/sic", f"no radar with SAC/SIC {', '.join(unknown)} "
                          "(CAT048 plots carry them; --skip-bad skips and counts those plots)")
    if unknown:
        kept = [p for p in plots if (p["sac"], p["sic"]) in ids]
        skipped["asterix_cat048_unknown_sac_sic"] += len(plots) - len(kept)
        plots = kept
    return site_list, ids, plots


def _scenario(name: str, plots: list[dict], adsb: list[dict], site_list: list[Radar],
              ids: dict[tuple[int, int], str], skipped: Counter) -> ScenarioData:
    """The scenario of the decoded plots and reports. Reference: the mean of the sites, else of the
    ADS-B positions, else (0, 0); an ADS-B report without NACp counts as NACp 8."""
    return ScenarioData(
        reference=_reference(site_list, adsb),
        radars=site_list,
        plots=PlotTable.from_columns(**{
            "time": [p["time"] for p in plots], "radar": [ids[(p["sac"], p["sic"])] for p in plots],
            "range_m": [p["range_m"] for p in plots], "azimuth_rad": [p["azimuth_rad"] for p in plots],
            "altitude_m": [p["altitude_m"] for p in plots], "mode_s": [p["mode_s"] for p in plots],
            "mode_3a": [p["mode_3a"] for p in plots], "target": [None] * len(plots),
            "received": [p["received"] for p in plots]}),
        adsb=AdsbTable.from_columns(**{
            "time": [a["time"] for a in adsb], "icao24": [a["icao24"] for a in adsb],
            "lat": [a["lat"] for a in adsb], "lon": [a["lon"] for a in adsb],
            "altitude_m": [a["altitude_m"] for a in adsb],
            "nacp": [8 if a["nacp"] is None else a["nacp"] for a in adsb]}),
        aircraft=_aircraft(plots, adsb),
        name=name, skipped=dict(skipped),
    )


def _reference(site_list: list[Radar], adsb: list[dict]) -> tuple[float, float]:
    if site_list:
        return float(np.mean([r.lat for r in site_list])), float(np.mean([r.lon for r in site_list]))
    if adsb:
        return float(np.mean([a["lat"] for a in adsb])), float(np.mean([a["lon"] for a in adsb]))
    return 0.0, 0.0


def _aircraft(plots: list[dict], adsb: list[dict]) -> list[Aircraft]:
    """The aircraft of the ADS-B addresses and the plots' Mode S addresses; an aircraft's Mode 3/A code
    is the one its plots carry most often."""
    icaos = sorted({a["icao24"] for a in adsb} | {p["mode_s"] for p in plots if p["mode_s"]})
    equipped = {a["icao24"] for a in adsb}
    squawks: dict[str, Counter] = {}
    for p in plots:
        if p["mode_s"] and p["mode_3a"]:
            squawks.setdefault(p["mode_s"], Counter())[p["mode_3a"]] += 1
    return [Aircraft(i, adsb=i in equipped, mode_3a=squawks[i].most_common(1)[0][0] if i in squawks else None)
            for i in icaos]


def read_cat062(path: Path | str, *, day_start: float = 0.0) -> list[dict]:
    """The CAT062 system track updates of a recording (raw, FINAL or pcap), in file order, as
    :func:`~radartracker.io.asterix.decode_cat062` dicts with absolute ``time`` (see the module notes
    on time of day) and ``received``, the capture time of the record's packet (pcap; None in a raw or FINAL
    file); records of other categories, and records without I010, I040, I070 or I080, are skipped."""
    out: list[dict] = []
    for clock, where, block, stamp in clocked_blocks(path, None, day_start):
        cat, recs = decode_block(block, where)
        if cat == 62:
            for d in decoded_records(62, recs, decode_cat062, Counter()):
                d["time"], d["received"] = clock(d["tod"]), stamp
                out.append(d)
    return out

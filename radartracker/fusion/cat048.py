"""Local (radar) tracks over ASTERIX CAT048: what a radar head that tracks really sends.

A CAT048 track report carries I010 SAC/SIC, I140 time of day, I040 measured position (ρ, θ) of the
track, I090 flight level, I161 track number (12 bits), I200 calculated velocity (ground speed
2⁻¹⁴ NM/s, heading 360°/2¹⁶), I170 track status (CNF confirmed; TRE: the track ends with this report),
I070 Mode 3/A and I220 Mode S address. :func:`write_local_tracks` writes the local tracks of a
simulated run (and the ADS-B as CAT021); :func:`local_tracks_from_asterix` reads them back into
:class:`~radartracker.fusion.center.LocalTracks` for ``run(..., local_tracks=...)``.

Geometry: the position is the track's plane position, located at its altitude (I090, else the
manager's primary altitude) and seen from the radar (exactly as a plot, :class:`RadarFrame`); the
velocity is the plane velocity turned into ground speed and true heading at the track's position.

Covariance: CAT048 carries none. An imported track gets the documented default
P_pp = s² · J W Jᵀ (J = ∂p/∂(ρ, θ) at its position, W = diag(σ_r², σ_θ²) of its radar in the radar
sites file, s = ``position_sd_scale``) and P_vv = σ_v² I (σ_v = ``velocity_sd_mps``), no
position–velocity correlation. Track numbers are 12 bits: a number reused after the track-end report is
a new local track.
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import attrs
import numpy as np

from radartracker.errors import InputError
from radartracker.fusion.center import LocalReport, LocalTrackEnd, LocalTracks
from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.io.asterix import (CAT021, CAT048, NM, atomic_recording, cat021_record, cat048_record, datablocks,
                                     decode_block, decode_cat048, sac_sic_of, sidecar_of)
from radartracker.io.asterix_reader import Clock, clocked_blocks, decoded_records, read_asterix, read_sites
from radartracker.io.capture import iter_datablocks
from radartracker.io.tables import PlotTable, ScenarioData

EARTH_M = 6_371_008.8  # spherical radius for the 1-second heading step (the same both ways)
GSP_LSB = 2.0 ** -14  # NM/s


def local_track_record(time: float, sac: int, sic: int, track: int, range_m: float, azimuth_rad: float,
                       speed_mps: float, heading_rad: float, altitude_m: float | None = None,
                       mode_s: str | None = None, mode_3a: str | None = None, ended: bool = False):
    """One CAT048 track report (I161 track number, I200 velocity, I170 status)."""
    return cat048_record(time, sac, sic, range_m, azimuth_rad, altitude_m, mode_s, mode_3a, extra={
        "161": int(track) % 4096,
        "200": (("GSP", (min(speed_mps / NM, 65535 * GSP_LSB), "NM/s")),
                ("HDG", (math.degrees(heading_rad) % 360.0, "°"))),
        "170": ((0, 0, 0, 0, 0, None), (1, 0, 0, 0, 0, None)) if ended else ((0, 0, 0, 0, 0, None),),
    })


def _heading_step(plane: SystemPlane, x: float, y: float) -> tuple[float, float, np.ndarray, np.ndarray]:
    """(lat, lon) at plane (x, y) and the plane displacement of 1 m north and 1 m east from it."""
    lat, lon = (float(v) for v in plane.to_geodetic(x, y))
    north = np.array(plane.to_plane(lat + math.degrees(1.0 / EARTH_M), lon), float) - (x, y)
    dlon = math.degrees(1.0 / (EARTH_M * math.cos(math.radians(lat))))
    east = np.array(plane.to_plane(lat, lon + dlon), float) - (x, y)
    return lat, lon, north, east


def has_track_reports(path: Path | str, blocks: int = 50) -> bool:
    """Whether the first CAT048 records of a recording (within ``blocks`` data blocks) are track reports (I161)."""
    for k, (_, block) in enumerate(iter_datablocks(path, Counter())):
        if k >= blocks:
            break
        try:
            cat, recs = decode_block(block, f"{path}: data block {k}")
        except InputError:
            continue
        if cat == 48 and recs:
            return recs[0].get_item("161") is not None
    return False


def write_local_tracks(path: Path | str, data: ScenarioData, tracks: LocalTracks, *, default_altitude_m: float,
                       sac_sic: dict[str, tuple[int, int]] | None = None,
                       adsb_sac_sic: tuple[int, int] = (0, 200)) -> int:
    """``tracks`` as CAT048 track reports, ``data``'s ADS-B as CAT021 (raw blocks, in time order), the
    radar sites as ``<path>.radars.csv``; returns the number of records. A track's last report
    before its end carries TRE."""
    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{path} already exists")
    sac_sic = sac_sic or sac_sic_of(data)
    plane = SystemPlane(*data.reference)
    frames = {r.id: RadarFrame(r.lat, r.lon, r.height_m, plane) for r in data.radars}
    last = {}
    for k, r in enumerate(tracks.reports):
        last[(r.radar, r.track)] = k
    ended = {last[(e.radar, e.track)] for e in tracks.ends if (e.radar, e.track) in last}
    events = sorted([(r.time, 0, k) for k, r in enumerate(tracks.reports)]
                    + [(float(t), 1, i) for i, t in enumerate(data.adsb.time)])
    a = data.adsb
    with atomic_recording(path, data.radars, sac_sic) as fh:
        for time, cat, i in events:
            if cat == 0:
                r = tracks.reports[i]
                x, y, vx, vy = (float(v) for v in r.state)
                alt = default_altitude_m if r.altitude_m is None else r.altitude_m
                lat, lon, north, east = _heading_step(plane, x, y)
                # v = v_n·north + v_e·east (plane displacement per metre north/east): solve for (v_n, v_e)
                vn, ve = np.linalg.solve(np.column_stack([north, east]), [vx, vy])
                rho, theta, _ = frames[r.radar].polar(lat, lon, alt)
                rec = local_track_record(time, *sac_sic[r.radar], r.track, float(rho), float(theta),
                                         math.hypot(vn, ve), math.atan2(ve, vn), r.altitude_m, r.mode_s,
                                         r.mode_3a, ended=i in ended)
                fh.writelines(datablocks(CAT048, [rec]))
            else:
                fh.writelines(datablocks(CAT021, [cat021_record(a.time[i], *adsb_sac_sic, a.icao24[i], a.lat[i],
                                                                a.lon[i], a.altitude_m[i], int(a.nacp[i]))]))
    return len(events)


def local_tracks_from_asterix(path: Path | str, *, radars: Path | str | None = None, default_altitude_m: float = 6000.0,
                              position_sd_scale: float = 0.75, velocity_sd_mps: float = 10.0,
                              day_start: float = 0.0,
                              reference: tuple[float, float] | None = None,
                              skip_bad: bool = False) -> tuple[ScenarioData, LocalTracks]:
    """The CAT048 *track* reports (those with I161) of a recording as local tracks, and everything else
    (ADS-B, radar sites, reference; plots without I161 are left out and counted) as a scenario without
    plots. Covariance: the documented default of the module notes. Records without I200 are skipped
    and counted (``local_tracks_without_I200``). ``reference``: the system plane's centre (default: the
    mean of the radar sites, as :func:`~radartracker.io.asterix_reader.read_asterix`)."""
    path = Path(path)
    data = read_asterix(path, radars=radars, day_start=day_start, skip_bad=skip_bad)
    if reference is not None:
        data = attrs.evolve(data, reference=tuple(reference))
    _, ids = read_sites(Path(radars) if radars is not None else sidecar_of(path))
    reader = _TrackReader(data, ids, default_altitude_m, position_sd_scale, velocity_sd_mps)
    for clock, where, block, _ in clocked_blocks(path, Counter() if skip_bad else None, day_start):
        try:
            cat, recs = decode_block(block, where)
        except InputError:
            continue  # counted by read_asterix above (asterix_undecodable_blocks)
        if cat == 48:
            for rec in recs:
                reader.read(rec, clock)
    if not reader.reports:
        raise InputError(f"{path}: no CAT048 track report (I161 with I200)")
    reports = sorted(reader.reports, key=lambda r: r.time)
    ends = sorted(reader.ends, key=lambda e: e.time)
    empty = PlotTable.from_columns(time=[], radar=[], range_m=[], azimuth_rad=[], altitude_m=[], mode_s=[],
                                   mode_3a=[], target=[])
    return (ScenarioData(data.reference, data.radars, empty, data.adsb, aircraft=data.aircraft, name=data.name,
                         skipped={k: v for k, v in reader.skipped.items() if v}), LocalTracks(reports, ends))


class _TrackReader:
    """CAT048 track reports → :class:`LocalReport` and :class:`LocalTrackEnd`, one record at a time.

    A (radar, I161) pair is one local track until its TRE report; the number reused after it is a new
    local track. Every record that is not a usable track report is counted in :attr:`skipped`.
    """

    def __init__(self, data: ScenarioData, ids: dict[tuple[int, int], str], default_altitude_m: float,
                 position_sd_scale: float, velocity_sd_mps: float) -> None:
        self.plane = SystemPlane(*data.reference)
        self.frames = {r.id: RadarFrame(r.lat, r.lon, r.height_m, self.plane) for r in data.radars}
        self.radar_by_id, self.ids = data.radar_by_id, ids
        self.default_altitude_m = default_altitude_m
        self.position_sd_scale, self.velocity_sd_mps = position_sd_scale, velocity_sd_mps
        self.skipped: Counter[str] = Counter(data.skipped)
        self.reports: list[LocalReport] = []
        self.ends: list[LocalTrackEnd] = []
        self.number: dict[tuple[str, int], int] = {}  # (radar, I161) → our local track id
        self.next_id = 0

    def read(self, rec, clock: Clock) -> None:
        """One CAT048 record: a report of its local track, or counted."""
        i161, i200, i170 = rec.get_item("161"), rec.get_item("200"), rec.get_item("170")
        if i161 is None:
            self.skipped["asterix_cat048_plots_not_tracks"] += 1
            return
        if i200 is None:
            self.skipped["local_tracks_without_I200"] += 1
            return
        p = next(decoded_records(48, [rec], decode_cat048, self.skipped), None)  # None: counted by missing item
        if p is None:
            return
        if (p["sac"], p["sic"]) not in self.ids:
            self.skipped["local_tracks_unknown_sac_sic"] += 1
            return
        rid, trn = self.ids[(p["sac"], p["sic"])], i161.variation.get_item("TRN").variation.as_uint()
        if (rid, trn) not in self.number:
            self.next_id += 1
            self.number[(rid, trn)] = self.next_id
        tid, time = self.number[(rid, trn)], clock(p["tod"])
        alt = None if math.isnan(p["altitude_m"]) else p["altitude_m"]
        height = self.default_altitude_m if alt is None else alt
        xy, ok = self.frames[rid].to_plane(p["range_m"], p["azimuth_rad"], height)
        if not ok:
            self.skipped["local_tracks_impossible_position"] += 1
            return
        x, y = (float(v) for v in xy)
        vel = self._velocity(i200.variation, x, y)
        self.reports.append(LocalReport(time, rid, tid, np.array([x, y, vel[0], vel[1]]),
                                        self._covariance(rid, x, y, p["range_m"], height), alt,
                                        p["mode_s"], p["mode_3a"]))
        tre = i170 is not None and i170.variation.get_item("TRE") is not None and \
            i170.variation.get_item("TRE").variation.as_uint() == 1
        if tre:
            self.ends.append(LocalTrackEnd(time, rid, tid))
            del self.number[(rid, trn)]

    def _velocity(self, i200, x: float, y: float) -> np.ndarray:
        """Plane velocity of I200's ground speed and true heading: v = s (cos h · north + sin h · east)."""
        speed = i200.get_item("GSP").variation.content.as_quantity("NM/s") * NM
        hdg = math.radians(i200.get_item("HDG").variation.content.as_quantity("°"))
        _, _, north, east = _heading_step(self.plane, x, y)
        return speed * (math.cos(hdg) * north + math.sin(hdg) * east)

    def _covariance(self, rid: str, x: float, y: float, range_m: float, height_m: float) -> np.ndarray:
        """The documented default: P_pp = s² J W Jᵀ, P_vv = σ_v² I, no position–velocity correlation."""
        J = self.frames[rid].bias_jacobian(np.array([x, y]), range_m, height_m)
        P = np.zeros((4, 4))
        P[:2, :2] = self.position_sd_scale ** 2 * J @ self.radar_by_id[rid].W @ J.T
        P[2:, 2:] = np.eye(2) * self.velocity_sd_mps ** 2
        return P

"""Flights of the ``traffic`` library (``traffic.core.Traffic`` / ``Flight``) in, tracks out as a ``Traffic``.

``traffic`` is an optional extra (``pip install radartracker[traffic]``), imported only inside these functions.

* :func:`scenario_from_traffic`: each flight becomes an aircraft flying its recorded trajectory
  (:class:`~radartracker.simulation.simulator.RecordedTrajectory`, positions interpolated linearly), which
  the :class:`~radartracker.simulation.simulator.Simulator` turns into the truth, ADS-B reports (NACp noise
  about the recorded positions) and the plots of the radars given (with their biases and noise). Units at
  the edge: ``traffic``'s altitudes are feet, its times timestamps (UTC).
* :func:`traffic_from_tracks`: a run's track estimates (:meth:`RunResult.tracks_frame`, or an output
  table read back) as a ``Traffic`` of one flight per track (``flight_id`` the track id), in ``traffic``'s
  columns and units: ``timestamp``, ``latitude``, ``longitude``, ``altitude`` (ft), ``groundspeed`` (kt),
  ``track`` (degrees clockwise from true north), ``icao24`` (the Mode S address), ``squawk``.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

import numpy as np
from pyproj import Geod

from radartracker.domain import Aircraft, Radar
from radartracker.errors import InputError
from radartracker.geometry.plane import SystemPlane
from radartracker.io.tables import ScenarioData
from radartracker.simulation.simulator import RecordedTrajectory, SimAircraft, SimRadar, Simulator

if TYPE_CHECKING:
    import pandas as pd

log = logging.getLogger(__name__)
FT = 0.3048  # m
KT = 1852.0 / 3600.0  # m/s
_GEOD = Geod(ellps="WGS84")


def _seconds(timestamps: Any) -> np.ndarray:
    """Timestamps (naive ones taken as UTC) as float seconds since 1970-01-01 UTC."""
    import pandas as pd

    ts = pd.to_datetime(timestamps, utc=True)
    return ((ts - pd.Timestamp(0, tz="UTC")) / pd.Timedelta(seconds=1)).to_numpy(float)


def _squawk(value: Any) -> str | None:
    """A Mode 3/A code as four octal digits (``traffic`` keeps it as an integer, 1000 for 1000), or None."""
    text = f"{int(value):04d}" if isinstance(value, (int, np.integer)) else str(value or "").strip()
    return text if len(text) == 4 and set(text) <= set("01234567") else None


def _aircraft(flight, adsb: bool, nacp: int) -> Aircraft:
    data = flight.data
    squawk = data["squawk"].dropna() if "squawk" in data else []
    try:
        return Aircraft(str(flight.icao24), callsign=str(flight.callsign or ""),
                        mode_3a=_squawk(squawk.iloc[0]) if len(squawk) else None, adsb=adsb, nacp=nacp)
    except (TypeError, ValueError) as exc:
        raise InputError(f"flight {flight.icao24!r} {flight.callsign!r}: {exc}") from None


def _trajectory(flight, plane: SystemPlane) -> RecordedTrajectory | None:
    """The flight's airborne positions (strictly increasing times), or None if fewer than two."""
    d = flight.data.dropna(subset=["latitude", "longitude", "altitude"])
    if "onground" in d:
        d = d[~d["onground"].fillna(False).astype(bool)]
    t = _seconds(d["timestamp"])
    order = np.argsort(t, kind="stable")
    t = t[order]
    keep = np.concatenate([[True], np.diff(t) > 0]) if len(t) else np.zeros(0, bool)
    if keep.sum() < 2:
        return None
    cols = [d[c].to_numpy(float)[order][keep] for c in ("latitude", "longitude", "altitude")]
    return RecordedTrajectory.from_geodetic(plane, t[keep], cols[0], cols[1], cols[2] * FT)


def scenario_from_traffic(flights, radars: list[SimRadar | Radar], *, adsb_share: float = 1.0, nacp: int = 8,
                          seed: int = 1, reference: tuple[float, float] | None = None, name: str = "traffic",
                          ) -> ScenarioData:
    """A simulated scenario whose aircraft fly the flights of ``flights`` (a ``traffic`` ``Traffic`` or
    ``Flight``; one flight per Mode S address), seen by ``radars`` (a :class:`Radar` as an unbiased
    :class:`SimRadar`) over the flights' span; a share ``adsb_share`` of them (drawn with ``seed``) reports
    ADS-B of category ``nacp``. ``reference``: the system plane's centre (default: the mean position).
    A flight with fewer than two airborne positions is left out (logged)."""
    from traffic.core import Flight

    flights = [flights] if isinstance(flights, Flight) else list(flights)
    if not flights or not radars:
        raise InputError("scenario_from_traffic: no flight or no radar")
    if reference is None:
        reference = tuple(float(np.nanmean(np.concatenate([f.data[c].to_numpy(float) for f in flights])))
                          for c in ("latitude", "longitude"))
    plane = SystemPlane(*reference)
    equipped = np.random.default_rng([seed, 97]).random(len(flights)) < adsb_share
    aircraft: dict[str, SimAircraft] = {}
    for flight, adsb in zip(flights, equipped):
        ac, traj = _aircraft(flight, bool(adsb), nacp), _trajectory(flight, plane)
        if traj is None:
            log.warning("flight %s %s left out: fewer than two airborne positions", flight.icao24, flight.callsign)
            continue
        if ac.icao24 in aircraft:
            raise InputError(f"two flights of aircraft {ac.icao24}: the truth names an aircraft by its Mode S "
                             "address; give one flight per aircraft")
        aircraft[ac.icao24] = SimAircraft(ac, traj)
    if not aircraft:
        raise InputError("scenario_from_traffic: no flight has two airborne positions")
    sims = [r if isinstance(r, SimRadar) else SimRadar(r) for r in radars]
    t0 = min(a.trajectory.t_start for a in aircraft.values())
    t1 = max(a.trajectory.t_end for a in aircraft.values())
    return Simulator(reference, sims, list(aircraft.values()), t0, t1, seed=seed, name=name).run()


def traffic_from_tracks(tracks: pd.DataFrame, reference: tuple[float, float]):
    """The track estimates ``tracks`` (the columns of ``tracks.csv``: :meth:`RunResult.tracks_frame` or
    :func:`radartracker.pipeline.outputs.read_output`) as a ``traffic.core.Traffic``, one flight per track;
    ``reference`` is the run's system plane centre (``RunResult.data.reference``), which turns the plane
    velocity into a ground speed and a true course."""
    import pandas as pd
    from traffic.core import Traffic

    plane = SystemPlane(*reference)
    x, y = tracks["x_m"].to_numpy(float), tracks["y_m"].to_numpy(float)
    vx, vy = tracks["vx_mps"].to_numpy(float), tracks["vy_mps"].to_numpy(float)
    lat0, lon0 = plane.to_geodetic(x, y)
    lat1, lon1 = plane.to_geodetic(x + vx, y + vy)  # where the track is one second later
    course, _, metres = _GEOD.inv(lon0, lat0, lon1, lat1)
    frame = pd.DataFrame({
        "timestamp": pd.to_datetime(tracks["time"].to_numpy(float), unit="s", utc=True),
        "flight_id": tracks["track"].astype("int64").astype(str).to_numpy(),
        "icao24": tracks["mode_s"].to_numpy(object),
        "latitude": tracks["lat"].to_numpy(float), "longitude": tracks["lon"].to_numpy(float),
        "altitude": tracks["altitude_m"].to_numpy(float) / FT, "groundspeed": np.asarray(metres) / KT,
        "track": np.mod(course, 360.0), "squawk": tracks["mode_3a"].to_numpy(object)})
    return Traffic(frame)

"""Make ``scripts/data/switzerland_cruise.csv.gz``, the real flights of the ``cruise-real`` evaluation set.

Source: the ``switzerland`` sample of the `traffic` library (OpenSky Network state vectors every 10 s over
Switzerland on 1 August 2018, MIT licence; needs ``pip install traffic``). Kept: the flights between 09:00 and
10:00 UTC whose median altitude is FL350–FL390 (100 flights), in the columns of ``../shared/data``.

A state vector's position may be older than its time stamp (OpenSky reports the last position received):
flown as it is, such a track jumps along its path by up to ~1 km in 10 s (speeds of 100 and 350 m/s in
consecutive steps of an airliner at 230 m/s), a manoeuvre no aircraft flies, and simulated radars then
see it. So a position is dropped when the speed implied from the previous kept one differs from the
reported ground speed by 15 % or more (751 of 9 141 positions), as ``../shared/data`` dropped repeated ones.

    python scripts/make_cruise_set.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from radartracker.geometry.plane import SystemPlane

OUT = Path(__file__).resolve().parent / "data" / "switzerland_cruise.csv.gz"
KT = 1852.0 / 3600.0
COLUMNS = ["flight_id", "icao24", "callsign", "timestamp", "latitude", "longitude", "altitude", "groundspeed",
           "track", "vertical_rate"]


def consistent(t: np.ndarray, x: np.ndarray, y: np.ndarray, speed: np.ndarray, tolerance: float = 0.15) -> list[int]:
    """Indices of the positions kept: each one's speed from the previous kept position within ``tolerance``
    of the mean reported ground speed of the two."""
    keep = [0]
    for i in range(1, len(t)):
        j = keep[-1]
        v = np.hypot(x[i] - x[j], y[i] - y[j]) / (t[i] - t[j])
        ref = 0.5 * (speed[i] + speed[j])
        if abs(v - ref) < tolerance * ref:
            keep.append(i)
    return keep


def main() -> None:
    import pandas as pd
    from traffic.data.samples import switzerland

    df = switzerland.data
    start = pd.Timestamp("2018-08-01 09:00", tz="UTC")
    df = df[(df.timestamp >= start) & (df.timestamp < start + pd.Timedelta(hours=1))]
    df = df.dropna(subset=["latitude", "longitude", "altitude", "groundspeed"])
    median = df.groupby(["icao24", "callsign"]).altitude.median()
    df = df.set_index(["icao24", "callsign"]).loc[median[(median >= 35000) & (median <= 39000)].index].reset_index()
    df["flight_id"] = "ch-" + df["callsign"].str.strip() + "-" + df["icao24"]
    df["timestamp"] = ((df.timestamp - pd.Timestamp(0, tz="UTC")) // pd.Timedelta(seconds=1)).astype("int64")
    df = df.sort_values(["flight_id", "timestamp"])
    plane = SystemPlane(46.8, 8.2)
    kept = []
    for _, g in df.groupby("flight_id"):
        x, y = plane.to_plane(g.latitude.to_numpy(), g.longitude.to_numpy())
        kept.append(g.iloc[consistent(g.timestamp.to_numpy(float), x, y, g.groundspeed.to_numpy() * KT)])
    out = pd.concat(kept)
    out[COLUMNS].to_csv(OUT, index=False, float_format="%.6f")
    print(f"{OUT}: {out.flight_id.nunique()} flights, {len(out)} of {len(df)} positions")


if __name__ == "__main__":
    main()

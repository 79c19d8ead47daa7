"""Extract the small subset of real flights shipped inside the package for tests and scenarios.

Source: ../shared/data/real_flights.csv.gz (OpenSky Network state vectors, as distributed in the
sample files of the MIT-licensed `traffic` package). Keeps the Paris flights airborne within one
hour of 2021-10-07 and three calibration flights that manoeuvre hard. Run from the repository root.
"""

import argparse
import csv
import gzip
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real_flights.csv.gz"
TARGET = Path(__file__).resolve().parents[1] / "radartracker" / "data" / "flights_subset.csv.gz"
WINDOW = (1633612800.0, 1633616400.0)  # 2021-10-07 13:20–14:20 UTC
CALIBRATION = ("cal_toulouse-1", "cal_liege_sprimont-1", "cal_brussels_vor-1")


def main(source: Path = SOURCE) -> None:
    with gzip.open(source, "rt", newline="") as f:
        reader = csv.DictReader(f)
        fields = reader.fieldnames
        rows = list(reader)
    first, last = {}, {}
    for r in rows:
        t = float(r["timestamp"])
        first[r["flight_id"]] = min(first.get(r["flight_id"], t), t)
        last[r["flight_id"]] = max(last.get(r["flight_id"], t), t)
    keep = {f for f in first if f.startswith("paris-") and first[f] >= WINDOW[0] and last[f] <= WINDOW[1]}
    keep |= set(CALIBRATION)
    out = [r for r in rows if r["flight_id"] in keep]
    with gzip.open(TARGET, "wt", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, lineterminator="\n")
        w.writeheader()
        w.writerows(out)
    print(f"{len(keep)} flights, {len(out)} rows -> {TARGET}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("source", type=Path, nargs="?", default=SOURCE, help="real_flights.csv.gz")
    main(ap.parse_args().source)

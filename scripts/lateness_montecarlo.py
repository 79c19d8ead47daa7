"""Monte Carlo of the time-stamp lateness figure from a pcap capture (docs/assessment.md, "What each figure is").

The ``demo`` scenario's plots, each delivered a random delay after its time stamp (radar k: 0.3 + 0.4 k s plus
an exponential of mean 0.2 s), are written one pcap packet per plot in delivery order, read back as a user's
recording is (:func:`radartracker.io.asterix_reader.read_asterix`), and each radar's lateness figure (the 95th
percentile of delivery − time stamp with its order-statistic interval) is checked against the distribution's,
0.3 + 0.4 k + 0.2 ln 20 s. Prints how often the interval held it, beside the binomial 99 % band of a 95 %
interval.

    python scripts/lateness_montecarlo.py [--runs 200]
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import attrs
import numpy as np
from scipy.stats import binom

from radartracker.assessment import stats
from radartracker.assessment.assess import time_stamps
from radartracker.io.asterix import CAT048, cat048_record, datablocks, sac_sic_of, write_asterix
from radartracker.io.asterix_reader import read_asterix
from radartracker.io.capture import write_pcap
from radartracker.io.tables import AdsbTable
from radartracker.progress import progress_bar
from radartracker.simulation.scenarios import build_scenario

DAY = 1_700_006_400.0  # 2023-11-15 00:00 UTC: pcap times are since 1970
SCALE = 0.2  # s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    args = ap.parse_args()
    data = build_scenario("demo", seed=7, duration=300.0).run()
    data = attrs.evolve(data, adsb=AdsbTable.from_columns(time=[], icao24=[], lat=[], lon=[], altitude_m=[], nacp=[]))
    folder = Path(tempfile.mkdtemp())
    write_asterix(folder / "rec.ast", data)
    ids, p = sac_sic_of(data), data.plots
    rank = {r.id: k for k, r in enumerate(data.radars)}
    blocks = [next(datablocks(CAT048, [cat048_record(p.time[i], *ids[p.radar[i]], p.range_m[i], p.azimuth_rad[i],
                                                     p.altitude_m[i], p.mode_s[i], p.mode_3a[i])]))
              for i in range(len(p))]
    base = np.array([0.3 + 0.4 * rank[r] for r in p.radar])
    held = total = 0
    for seed in progress_bar(range(1, args.runs + 1), desc="runs"):
        delay = base + np.random.default_rng(seed).exponential(SCALE, len(p))
        path = folder / f"run{seed}.pcap"
        write_pcap(path, [(DAY + float(p.time[i] + delay[i]), blocks[i])
                          for i in np.argsort(p.time + delay, kind="stable")])
        (folder / f"run{seed}.pcap.radars.csv").write_bytes((folder / "rec.ast.radars.csv").read_bytes())
        back = read_asterix(path)
        for r in data.radars:
            e = stats.quantile(time_stamps(back.plots, r.id)[1], 0.95)
            true = 0.3 + 0.4 * rank[r.id] + SCALE * math.log(20.0)
            held += e.low <= true <= e.high
            total += 1
    band = binom.ppf([0.005, 0.995], total, 0.95)
    print(f"lateness p95: {held} of {total} intervals held the true value ({100 * held / total:.1f} %); "
          f"binomial 99 % band of a 95 % interval: {band[0]:.0f}-{band[1]:.0f}")


if __name__ == "__main__":
    main()

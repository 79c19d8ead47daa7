"""``asterix-import`` of a recording whose blocks arrive out of time order (radars' blocks interleaved as a
network delivers them) writes what ``replay`` reads: replaying the imported folder uses every plot that
replaying the recording directly uses."""

from __future__ import annotations

import json

import numpy as np

from radartracker.cli import main
from radartracker.io.asterix import CAT021, CAT048, atomic_recording, cat021_record, cat048_record, datablocks, sac_sic_of
from radartracker.simulation.scenarios import build_scenario


def _write_out_of_order(path, data):
    """Each radar's plots in blocks of 4, written in an order where a later block often comes first."""
    sac_sic = sac_sic_of(data)
    p, a = data.plots, data.adsb
    order = np.argsort(p.time, kind="stable")
    chunks = [order[i:i + 4] for i in range(0, len(order), 4)]
    rng = np.random.default_rng(7)
    for k in range(0, len(chunks) - 1, 2):  # swap neighbours: arrival order ≠ time order
        if rng.random() < 0.7:
            chunks[k], chunks[k + 1] = chunks[k + 1], chunks[k]
    with atomic_recording(path, data.radars, sac_sic) as fh:
        for chunk in chunks:
            fh.writelines(datablocks(CAT048, [cat048_record(p.time[i], *sac_sic[p.radar[i]], p.range_m[i],
                                                            p.azimuth_rad[i], p.altitude_m[i], p.mode_s[i],
                                                            p.mode_3a[i]) for i in chunk]))
        fh.writelines(datablocks(CAT021, [cat021_record(a.time[i], 0, 200, a.icao24[i], a.lat[i], a.lon[i],
                                                        a.altitude_m[i], int(a.nacp[i])) for i in range(len(a))]))
    arrival = np.concatenate(chunks)
    return int(np.sum(np.diff(p.time[arrival]) < 0))


def test_import_then_replay_uses_every_plot_the_direct_replay_uses(tmp_path, capsys):
    data = build_scenario("demo", seed=3, duration=120.0).run()
    inversions = _write_out_of_order(tmp_path / "rec.ast", data)
    assert inversions > 10  # the recording is really out of order
    assert main(["--quiet", "replay", str(tmp_path / "rec.ast"), "--out", str(tmp_path / "direct"),
                 "--estimator", "decoupled"]) == 0
    assert main(["--quiet", "asterix-import", str(tmp_path / "rec.ast"), "--out", str(tmp_path / "scen")]) == 0
    times = np.loadtxt(tmp_path / "scen" / "plots.csv", delimiter=",", skiprows=1, usecols=0)
    assert np.all(np.diff(times) >= 0)
    assert main(["--quiet", "replay", str(tmp_path / "scen"), "--out", str(tmp_path / "imported"),
                 "--estimator", "decoupled"]) == 0
    direct, imported = (json.loads((tmp_path / d / "summary.json").read_text()) for d in ("direct", "imported"))
    assert direct["counts"]["plots_used"] == len(data.plots)
    assert imported["counts"]["plots_used"] == direct["counts"]["plots_used"]
    assert not imported["skipped_input_rows"]

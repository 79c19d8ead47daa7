"""Time-stamp lateness from a pcap capture: each plot delivered a known random delay after its time stamp
(a constant per radar plus an exponential), captured packet by packet; the assessment's 95th percentile of
delivery − time stamp must hold the distribution's, base + scale · ln 20 (computed here, not by the product)."""

from __future__ import annotations

import math

import attrs
import numpy as np
import pytest

from radartracker.assessment.assess import AssessmentConfig, assess
from radartracker.assessment.profile import load_profile
from radartracker.assessment.reference import ReferenceConfig
from radartracker.io.asterix import CAT048, cat048_record, datablocks, sac_sic_of, write_asterix
from radartracker.io.asterix_reader import read_asterix
from radartracker.io.capture import write_pcap
from radartracker.io.tables import AdsbTable
from radartracker.simulation.scenarios import build_scenario

DAY = 1_700_006_400.0  # 2023-11-15 00:00 UTC
SCALE = 0.2  # s, the exponential part of every delay


def _base(k: int) -> float:
    return 0.3 + 0.4 * k  # s, radar k's constant part


@pytest.fixture(scope="module")
def captured(tmp_path_factory):
    """The demo scenario's plots as a pcap (one packet per plot, in delivery order) and as raw blocks, both read
    back, with the truth put back (ASTERIX carries none) so that the reference is the truth."""
    folder = tmp_path_factory.mktemp("lateness")
    data = build_scenario("demo", seed=7, duration=300.0).run()
    data = attrs.evolve(data, adsb=AdsbTable.from_columns(time=[], icao24=[], lat=[], lon=[], altitude_m=[], nacp=[]))
    write_asterix(folder / "rec.ast", data)  # the raw recording and its sites sidecar
    ids = sac_sic_of(data)
    rank = {r.id: k for k, r in enumerate(data.radars)}
    rng = np.random.default_rng(11)
    p = data.plots
    delay = np.array([_base(rank[r]) for r in p.radar]) + rng.exponential(SCALE, len(p))
    packets = [(DAY + float(p.time[i] + delay[i]),
                next(datablocks(CAT048, [cat048_record(p.time[i], *ids[p.radar[i]], p.range_m[i], p.azimuth_rad[i],
                                                       p.altitude_m[i], p.mode_s[i], p.mode_3a[i])])))
               for i in np.argsort(p.time + delay, kind="stable")]
    write_pcap(folder / "rec.pcap", packets)
    (folder / "rec.pcap.radars.csv").write_bytes((folder / "rec.ast.radars.csv").read_bytes())
    truth = attrs.evolve(data.truth, time=data.truth.time + DAY)
    pcap = attrs.evolve(read_asterix(folder / "rec.pcap"), truth=truth, truth_biases=data.truth_biases)
    raw = attrs.evolve(read_asterix(folder / "rec.ast"), truth=data.truth, truth_biases=data.truth_biases)
    return data, pcap, raw


def test_pcap_capture_times_are_each_plots_delivery(captured):
    data, pcap, raw = captured
    assert np.all(np.isnan(raw.plots.received))
    lateness = pcap.plots.received - pcap.plots.time
    assert len(pcap.plots) == len(data.plots) and np.all(lateness > 0.0)
    assert np.all(np.isfinite(lateness))


def test_lateness_holds_the_delay_distributions_95th_percentile(captured):
    data, pcap, _ = captured
    config = AssessmentConfig(reference=ReferenceConfig(reconstruct=False))
    a = assess(pcap, load_profile(), config, progress=False)
    rank = {r.id: k for k, r in enumerate(data.radars)}
    for r in a.radars:
        e = r.figures["timestamp_lateness_s"]
        true = _base(rank[r.radar]) + SCALE * math.log(20.0)  # exponential quantile: −scale · ln(1 − 0.95)
        assert e.low <= true <= e.high, (r.radar, e, true)
        assert e.high - e.low < 0.4 and e.n == int(np.sum(pcap.plots.radar == r.radar))
        assert r.figures["out_of_order_share"].value > 0.0  # delivered out of time-stamp order, so filed so


def test_lateness_not_assessable_without_delivery_times(captured):
    _, _, raw = captured
    a = assess(raw, load_profile(), AssessmentConfig(reference=ReferenceConfig(reconstruct=False)), progress=False)
    for r in a.radars:
        assert "timestamp_lateness_s" not in r.figures
        assert "pcap" in r.not_assessable["timestamp_lateness_s"]

"""Small valid inputs for the fuzz tests to damage: a scenario folder and an ASTERIX recording."""

import attrs
import numpy as np
import pytest

from radartracker.io.asterix import write_asterix
from radartracker.io.capture import write_pcap
from radartracker.io.scenario import write_scenario
from radartracker.io.tables import AdsbTable, PlotTable
from radartracker.simulation.scenarios import build_scenario


@pytest.fixture(scope="session")
def tiny_data():
    """The demo scenario cut to 10 plots and 5 ADS-B reports (a read takes milliseconds)."""
    data = build_scenario("demo", seed=3, duration=20.0).run()
    a = data.adsb
    return attrs.evolve(
        data, plots=data.plots.take(np.arange(10)),
        adsb=AdsbTable(*(getattr(a, f.name)[:5] for f in attrs.fields(AdsbTable))))


@pytest.fixture(scope="session")
def scenario_dir(tmp_path_factory, tiny_data):
    folder = tmp_path_factory.mktemp("fuzz") / "scenario"
    write_scenario(folder, tiny_data)
    return folder


@pytest.fixture(scope="session")
def recordings(tmp_path_factory, tiny_data):
    """{container: bytes} of the same recording (raw blocks, FINAL, pcap) and its sidecar path."""
    folder = tmp_path_factory.mktemp("fuzz_ast")
    write_asterix(folder / "rec.ast", tiny_data)
    raw = (folder / "rec.ast").read_bytes()
    blocks, off = [], 0
    while off < len(raw):
        n = int.from_bytes(raw[off + 1: off + 3], "big")
        blocks.append(raw[off: off + n])
        off += n
    final = b"".join(len(b + bytes(12)).to_bytes(2, "big") + bytes(6) + b + b"\xa5" * 4 for b in blocks)
    write_pcap(folder / "rec.pcap", [(1.7e9 + i, b) for i, b in enumerate(blocks)])
    return {"ast": raw, "ff": final, "pcap": (folder / "rec.pcap").read_bytes()}, folder / "rec.ast.radars.csv"

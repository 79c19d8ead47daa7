"""Real feeds: records without our items, categories and editions we do not read, damaged framing,
and sidecar mistakes — skipped and counted, or one clear error; never a traceback."""

from __future__ import annotations

import pytest

from radartracker.errors import FormatError, InputError
from radartracker.io.asterix import CAT021, CAT048, cat021_record, cat048_record, datablocks, write_asterix
from radartracker.io.asterix_reader import read_asterix
from radartracker.io.capture import write_pcap


@pytest.fixture(scope="module")
def scenario():
    from radartracker.simulation.scenarios import build_scenario

    return build_scenario("manoeuvres", seed=3, duration=60).run()


@pytest.fixture()
def rec(tmp_path, scenario):
    write_asterix(tmp_path / "rec.ast", scenario)
    return tmp_path / "rec.ast"


def _track_only(time: float):
    """A CAT048 report without I040 (a track-only report, as real feeds carry)."""
    return CAT048.cv_record.create({"010": (("SAC", 0), ("SIC", 1)), "140": (time % 86400.0, "s"),
                                    "020": ((2, 0, 0, 0, 0, None),), "070": (0, 0, 0, 0, ("MODE3A", "1234"))})


def _adsb_without_address(time: float):
    return CAT021.cv_record.create({"010": (("SAC", 0), ("SIC", 200)), "040": ((1, 0, 0, 0, None),),
                                    "071": (time % 86400.0, "s"), "131": (("LAT", (56.0, "°")), ("LON", (37.0, "°")))})


def test_records_without_our_items_are_skipped_and_counted(rec, scenario):
    extra = b"".join(datablocks(CAT048, [_track_only(10.0), cat048_record(11.0, 0, 1, 5e4, 1.0), _track_only(12.0)]))
    extra += b"".join(datablocks(CAT021, [_adsb_without_address(10.5)]))
    rec.write_bytes(rec.read_bytes() + extra)
    data = read_asterix(rec)
    assert data.skipped["asterix_cat048_records_without_I040"] == 2
    assert data.skipped["asterix_cat021_records_without_I080"] == 1
    assert len(data.plots) == len(scenario.plots) + 1 and len(data.adsb) == len(scenario.adsb)


def test_other_categories_and_undecodable_blocks_are_skipped_and_counted(rec, scenario):
    raw = rec.read_bytes()
    cat034 = bytes([34, 0, 8, 0xE0, 0, 1, 1, 0])  # a CAT034 service message block: a category we do not read
    cat062_other_edition = bytes([62, 0, 9, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF])  # does not decode as ed. 1.21
    cat048_damaged = bytearray(next(datablocks(CAT048, [cat048_record(5.0, 0, 1, 1000.0, 0.5)])))
    cat048_damaged[3] = 0xFF
    rec.write_bytes(cat034 + cat062_other_edition + bytes(cat048_damaged) + raw)
    data = read_asterix(rec)
    assert data.skipped == {"asterix_cat034_blocks": 1, "asterix_undecodable_blocks": 2}
    assert len(data.plots) == len(scenario.plots) and len(data.adsb) == len(scenario.adsb)


def test_damaged_framing_is_an_error_or_skipped_with_skip_bad(rec):
    whole = read_asterix(rec)
    raw = rec.read_bytes()
    rec.write_bytes(raw[:-5])
    with pytest.raises(InputError, match=r"rec\.ast: byte \d+: truncated data block"):
        read_asterix(rec)
    cut = read_asterix(rec, skip_bad=True)
    assert cut.skipped == {"asterix_unreadable_tails": 1}
    assert 0 < len(cut.plots) + len(cut.adsb) < len(whole.plots) + len(whole.adsb)


def test_pcap_packet_with_bad_payload_is_skipped_with_skip_bad(tmp_path, rec):
    blocks = list(datablocks(CAT048, [cat048_record(t, 0, 1, 5e4, 1.0) for t in (1.0, 2.0, 3.0)]))
    good = blocks[0]
    path = tmp_path / "x.pcap"
    write_pcap(path, [(1.0, good), (2.0, good + b"\x30\x00"), (3.0, good)])  # 2 stray bytes
    (tmp_path / "x.pcap.radars.csv").write_bytes((tmp_path / "rec.ast.radars.csv").read_bytes())
    with pytest.raises(InputError, match="packet at byte"):
        read_asterix(path)
    data = read_asterix(path, skip_bad=True)
    # the damaged packet's whole block is kept; the same block three times is three records, each used once
    assert data.skipped == {"asterix_malformed_packets": 1, "asterix_cat048_duplicate_records": 6}
    assert len(data.plots) == 3


def test_sidecar_mistakes(rec):
    sites = rec.with_name("rec.ast.radars.csv")
    lines = sites.read_text().splitlines(keepends=True)
    sites.write_bytes(b"\xef\xbb\xbf" + "".join(lines).encode())  # a BOM is fine
    assert len(read_asterix(rec).plots) > 0
    clash = lines[2].split(",")
    clash[-2:] = lines[1].rstrip("\n").split(",")[-2:]
    sites.write_text("".join(lines[:2] + [",".join(clash) + "\n"] + lines[3:]))
    with pytest.raises(FormatError, match=r"rec.ast.radars.csv line 3, field 'sac/sic': SAC/SIC 0/1 already belongs"):
        read_asterix(rec)
    sites.write_text("".join(lines[:2] + lines[3:]))  # radar of SIC 2 missing
    with pytest.raises(FormatError, match="no radar with SAC/SIC 0/2"):
        read_asterix(rec)
    data = read_asterix(rec, skip_bad=True)
    assert data.skipped["asterix_cat048_unknown_sac_sic"] > 0
    assert set(data.plots.radar) == {r.id for r in data.radars}


def test_nothing_usable_is_an_error(tmp_path):
    path = tmp_path / "only.ast"
    path.write_bytes(b"".join(datablocks(CAT048, [_track_only(1.0)])))
    with pytest.raises(InputError, match=r"only\.ast: no usable .*records_without_I040"):
        read_asterix(path)


def test_duplicate_records_are_used_once_and_counted(rec, scenario):
    """A redundant (dual-LAN) feed records every block twice: each record is used once."""
    raw = rec.read_bytes()
    rec.write_bytes(raw + raw)
    data = read_asterix(rec)
    assert len(data.plots) == len(scenario.plots) and len(data.adsb) == len(scenario.adsb)
    assert data.skipped == {"asterix_cat048_duplicate_records": len(scenario.plots),
                            "asterix_cat021_duplicate_records": len(scenario.adsb)}

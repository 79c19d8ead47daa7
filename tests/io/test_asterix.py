"""ASTERIX CAT048/CAT021 import/export and CAT062 export.

Oracles: the simulator's own plots and reports (independent of the codec) compared to what comes
back, within each item's resolution; and a second, independent decoder (``asterix4py``, its own
XML item definitions) reading the bytes we wrote.
"""

from __future__ import annotations

import math

import asterix4py  # test-only dependency: the independent decoder
import numpy as np
import pytest

from radartracker.io.asterix import (CAT021, CAT048, CAT062, FL_M, NM, cat021_record, cat048_record, cat062_record, datablocks, decode_block, decode_cat062, write_asterix, write_cat062)
from radartracker.io.asterix_reader import read_asterix
from radartracker.io.capture import iter_datablocks, write_pcap
from radartracker.cli import main

RHO_RES, THETA_RES = NM / 256, 2 * math.pi / 2**16  # I048/040
TIME_RES, FL_RES = 1 / 128, FL_M / 4                 # I048/140, I048/090, I021/071, I021/145
LATLON_RES = 180 / 2**30                             # I021/131


@pytest.fixture(scope="module")
def scenario():
    from radartracker.simulation.scenarios import build_scenario

    return build_scenario("manoeuvres", seed=3, duration=120).run()


def _by_time(table):
    return np.argsort(table.time, kind="stable")


def _assert_same_plots(orig, back):
    o = _by_time(orig.plots)
    assert len(back.plots) == len(orig.plots) > 0
    p, q = orig.plots, back.plots
    assert np.all(np.abs(q.time - p.time[o]) <= TIME_RES / 2 + 1e-9)
    assert np.all(np.abs(q.range_m - p.range_m[o]) <= RHO_RES / 2 + 1e-6)
    dth = np.angle(np.exp(1j * (q.azimuth_rad - p.azimuth_rad[o])))
    assert np.all(np.abs(dth) <= THETA_RES / 2 + 1e-12)
    has = ~np.isnan(p.altitude_m[o])
    assert np.array_equal(has, ~np.isnan(q.altitude_m))
    assert np.all(np.abs(q.altitude_m[has] - p.altitude_m[o][has]) <= FL_RES / 2 + 1e-6)
    assert list(q.radar) == list(p.radar[o])
    assert list(q.mode_s) == list(p.mode_s[o]) and list(q.mode_3a) == list(p.mode_3a[o])


def test_write_read_round_trip_within_resolution(tmp_path, scenario):
    n = write_asterix(tmp_path / "rec.ast", scenario)
    assert n == len(scenario.plots) + len(scenario.adsb)
    back = read_asterix(tmp_path / "rec.ast")
    _assert_same_plots(scenario, back)
    a, b = scenario.adsb, back.adsb
    o = _by_time(a)
    assert len(b) == len(a) > 0
    assert np.all(np.abs(b.time - a.time[o]) <= TIME_RES / 2 + 1e-9)
    assert np.all(np.abs(b.lat - a.lat[o]) <= LATLON_RES / 2 + 1e-12)
    assert np.all(np.abs(b.lon - a.lon[o]) <= LATLON_RES / 2 + 1e-12)
    assert np.all(np.abs(b.altitude_m - a.altitude_m[o]) <= FL_RES / 2 + 1e-6)
    assert list(b.icao24) == list(a.icao24[o]) and list(b.nacp) == list(a.nacp[o])
    assert [(r.id, r.lat, r.lon) for r in back.radars] == [
        (r.id, pytest.approx(r.lat, abs=1e-8), pytest.approx(r.lon, abs=1e-8)) for r in scenario.radars]


def test_independent_decoder_reads_our_bytes(tmp_path, scenario):
    write_asterix(tmp_path / "rec.ast", scenario)
    p, a = scenario.plots, scenario.adsb
    op, oa = iter(_by_time(p)), iter(_by_time(a))
    n48 = n21 = 0
    for _, block in iter_datablocks(tmp_path / "rec.ast"):
        for rec in asterix4py.AsterixParser(block).get_result().values():
            if rec["cat"] == 48:
                i = next(op)
                assert abs(rec["040"]["RHO"] * NM - p.range_m[i]) <= RHO_RES / 2 + 1e-6
                assert abs(math.radians(rec["040"]["THETA"]) - p.azimuth_rad[i]) <= THETA_RES / 2 + 1e-12
                assert abs(rec["140"]["ToD"] - p.time[i]) <= TIME_RES / 2 + 1e-9
                assert rec["220"]["ACAddr"].lower() == p.mode_s[i]
                assert rec["070"]["Mode3A"] == p.mode_3a[i]
                assert rec["020"]["TYP"] == 5
                n48 += 1
            else:
                assert rec["cat"] == 21
                i = next(oa)
                assert abs(rec["131"]["Lat"] - a.lat[i]) <= LATLON_RES / 2 + 1e-12
                assert abs(rec["131"]["Lon"] - a.lon[i]) <= LATLON_RES / 2 + 1e-12
                assert rec["080"]["TAddr"] == int(a.icao24[i], 16)
                assert rec["090"]["NACp"] == a.nacp[i] and rec["040"]["ATP"] == 1
                assert abs(rec["145"]["FL"] * FL_M - a.altitude_m[i]) <= FL_RES / 2 + 1e-6
                n21 += 1
    assert n48 == len(p) and n21 == len(a)


def test_known_bytes_of_one_plot():
    # I040: RHO = round(54 NM × 256) = 0x3600, THETA = round(90° / 360° × 2^16) = 0x4000 (ICD arithmetic)
    block = next(datablocks(CAT048, [cat048_record(1.0, 7, 9, 54 * NM, math.pi / 2)]))
    assert block[0] == 48 and int.from_bytes(block[1:3], "big") == len(block)
    assert bytes.fromhex("0709") in block  # I010: SAC 7, SIC 9
    assert bytes.fromhex("36004000") in block
    assert bytes.fromhex("000080") in block  # I140: 1 s × 128


def test_cat062_from_tracks_decodes(tmp_path):
    rec = cat062_record(43210.5, 0, 100, 12, 55.75, 37.62, 1234.5, -987.0, 210.25, -33.5, 9000.0)
    block = next(datablocks(CAT062, [rec]))
    cat, recs = decode_block(block, "test")
    d = decode_cat062(recs[0])
    assert cat == 62 and d["track_number"] == 12 and d["tod"] == 43210.5
    assert d["x_m"] == 1234.5 and d["y_m"] == -987.0 and d["vx_mps"] == 210.25 and d["vy_mps"] == -33.5
    assert abs(d["lat"] - 55.75) <= 180 / 2**25 and abs(d["altitude_m"] - 9000.0) <= FL_RES / 2
    other = asterix4py.AsterixParser(block).get_result()[1]
    assert other["040"]["TrkN"] == 12 and other["100"] == {"X": 1234.5, "Y": -987.0}


def test_cat062_from_a_replay(tmp_path, scenario):
    from radartracker.pipeline.config import RunConfig
    from radartracker.pipeline.run import run
    result = run(scenario, RunConfig(association="labels", estimator="decoupled"), progress=False)
    numbers = write_cat062(tmp_path / "tracks.ast", result)
    got = [decode_cat062(r) for _, b in iter_datablocks(tmp_path / "tracks.ast") for r in decode_block(b, "t")[1]]
    assert len(got) == len(result.tracks) > 0
    assert [g["track_number"] for g in got] == [numbers[k] for k in result.tracks.track.tolist()]
    assert np.all(np.abs(np.array([g["x_m"] for g in got]) - result.tracks.state[:, 0]) <= 0.25 + 1e-9)


def test_pcap_and_final_containers(tmp_path, scenario):
    write_asterix(tmp_path / "rec.ast", scenario)
    blocks = [b for _, b in iter_datablocks(tmp_path / "rec.ast")]
    day = 1_700_006_400.0  # 2023-11-15 00:00 UTC
    write_pcap(tmp_path / "rec.pcap", [(day + 1.0 + k, b) for k, b in enumerate(blocks)])
    (tmp_path / "rec.pcap.radars.csv").write_bytes((tmp_path / "rec.ast.radars.csv").read_bytes())
    back = read_asterix(tmp_path / "rec.pcap")
    ref = read_asterix(tmp_path / "rec.ast")
    np.testing.assert_array_equal(back.plots.time, ref.plots.time + day)  # the date comes from the capture
    np.testing.assert_array_equal(back.plots.range_m, ref.plots.range_m)
    final = b"".join(len(b + bytes(12)).to_bytes(2, "big") + bytes(6) + b + b"\xa5" * 4 for b in blocks)
    (tmp_path / "rec.ff").write_bytes(final)
    got = read_asterix(tmp_path / "rec.ff", radars=tmp_path / "rec.ast.radars.csv")
    np.testing.assert_array_equal(got.plots.range_m, ref.plots.range_m)
    np.testing.assert_array_equal(got.adsb.lat, ref.adsb.lat)


def test_time_of_day_wraps_to_the_next_day(tmp_path):
    recs = [cat021_record(t, 0, 1, "abcdef", 50.0, 8.0) for t in (86399.0, 86399.5, 86400.25, 86401.0)]
    (tmp_path / "adsb.ast").write_bytes(b"".join(datablocks(CAT021, recs)))
    got = read_asterix(tmp_path / "adsb.ast", day_start=86400.0 * 3)
    np.testing.assert_array_equal(got.adsb.time, 86400.0 * 3 + np.array([86399.0, 86399.5, 86400.25, 86401.0]))


def test_bad_files_give_clear_errors(tmp_path, scenario):
    write_asterix(tmp_path / "rec.ast", scenario)
    raw = (tmp_path / "rec.ast").read_bytes()
    (tmp_path / "cut.ast").write_bytes(raw[:-5])
    with pytest.raises(ValueError, match=r"cut\.ast: byte \d+: truncated data block"):
        read_asterix(tmp_path / "cut.ast", radars=tmp_path / "rec.ast.radars.csv")
    (tmp_path / "empty.ast").write_bytes(b"")
    with pytest.raises(ValueError, match="empty file"):
        read_asterix(tmp_path / "empty.ast")
    (tmp_path / "nosites.ast").write_bytes(raw)
    with pytest.raises(FileNotFoundError, match=r"SAC/SIC 0/1.*nosites\.ast\.radars\.csv"):
        read_asterix(tmp_path / "nosites.ast")
    (tmp_path / "ng.pcap").write_bytes(b"\x0a\x0d\x0d\x0a" + bytes(20))
    with pytest.raises(ValueError, match="pcapng"):
        read_asterix(tmp_path / "ng.pcap")
    bad = bytearray(next(datablocks(CAT048, [cat048_record(1.0, 0, 1, 1000.0, 0.5)])))
    bad[3] = 0xFF  # an FSPEC announcing items that are not there
    (tmp_path / "garbled.ast").write_bytes(bytes(bad))
    with pytest.raises(ValueError, match=r"garbled\.ast: no usable .*'asterix_undecodable_blocks': 1"):
        read_asterix(tmp_path / "garbled.ast", radars=tmp_path / "rec.ast.radars.csv")
    with pytest.raises(FileExistsError):
        write_asterix(tmp_path / "rec.ast", scenario)


def test_cli_import_export(tmp_path, scenario):
    from radartracker.io.scenario import read_scenario, write_scenario

    write_scenario(tmp_path / "scen", scenario)
    assert main(["asterix-export", str(tmp_path / "scen"), "--out", str(tmp_path / "x.ast")]) == 0
    assert main(["asterix-import", str(tmp_path / "x.ast"), "--out", str(tmp_path / "back")]) == 0
    back = read_scenario(tmp_path / "back")
    _assert_same_plots(read_scenario(tmp_path / "scen"), back)
    assert main(["asterix-import", str(tmp_path / "x.ast"), "--out", str(tmp_path / "back")]) == 2
    # replay reads the ASTERIX recording directly (read_scenario dispatches on the suffix)
    assert main(["replay", str(tmp_path / "x.ast"), "--out", str(tmp_path / "rep")]) == 0
    assert (tmp_path / "rep" / "tracks.csv").read_text().count("\n") > 1

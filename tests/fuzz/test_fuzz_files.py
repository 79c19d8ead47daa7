""".new4/.plt tracks and triangulation bearings/stations files, damaged: read or a RadarTrackerError."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from radartracker.io.recording import TrackPoints, read_new4, read_plt, write_new4, write_plt
from radartracker_plugins.triangulation import io as tio

from tests.fuzz.mutations import apply, mutations, works_or_refuses
from tests.fuzz.test_fuzz_tables import TRICKY
from tests.plugins.test_triangulation_cli import _rows, _write_bearings, _write_stations

FUZZ = settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz_files")
    pts = TrackPoints(1.7e9 + np.arange(5.0), 56.0 + 0.01 * np.arange(5), 37.0 + 0.01 * np.arange(5),
                      np.array([1000.0, np.nan, 1020.0, 1030.0, 1040.0]))
    write_new4(d / "t.new4", pts)
    write_plt(d / "t.plt", pts)
    frame = _write_stations(d / "stations.csv")
    times = np.arange(0.0, 20.0, 2.0)
    pos = np.array([[1000.0 + 100.0 * t, 2000.0, 3000.0] for t in times])
    _write_bearings(d / "bearings.csv", _rows(frame, list(frame.stations), times, pos, "M", np.random.default_rng(2)))
    return {name: (d / name).read_bytes() for name in ("t.new4", "t.plt", "stations.csv", "bearings.csv")}, d


def _bearings(path, skip_bad):
    return tio.read_bearings(path, skip_bad=skip_bad)


READERS = {"t.new4": read_new4, "t.plt": read_plt, "stations.csv": tio.read_stations, "bearings.csv": _bearings}


@given(name=st.sampled_from(sorted(READERS)), edits=st.data(), skip_bad=st.booleans())
@FUZZ
def test_damaged_bytes(files, name, edits, skip_bad):
    bufs, d = files
    path = d / f"m_{name}"
    path.write_bytes(apply(bufs[name], edits.draw(mutations(len(bufs[name])))))
    args = (path, skip_bad) if name == "bearings.csv" else (path,)
    assert works_or_refuses(READERS[name], *args) in ("read", "refused")


@given(name=st.sampled_from(sorted(READERS)), data=st.data())
@FUZZ
def test_tricky_fields(files, name, data):
    bufs, d = files
    lines = bufs[name].decode().splitlines(keepends=True)
    sep = "\t" if name.endswith(".new4") else ","
    for _ in range(data.draw(st.integers(1, 3))):
        k = data.draw(st.integers(0, len(lines) - 1))
        fields = lines[k].rstrip("\n").split(sep)
        fields[data.draw(st.integers(0, len(fields) - 1))] = data.draw(TRICKY)
        lines[k] = sep.join(fields) + "\n"
    path = d / f"f_{name}"
    path.write_text("".join(lines))
    args = (path, False) if name == "bearings.csv" else (path,)
    assert works_or_refuses(READERS[name], *args) in ("read", "refused")


@pytest.fixture(scope="module")
def recording(tmp_path_factory, tiny_data):
    from radartracker.io.recording import write_scenario_recording

    folder = tmp_path_factory.mktemp("fuzz_rec") / "rec"
    write_scenario_recording(folder, tiny_data)
    return folder


@given(name=st.sampled_from(["plots_ads.txt", "tracks.txt", "plots.txt"]), edits=st.data())
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_damaged_recording_converts_or_refuses(recording, name, edits):
    """The seed's conversion program on a recording with one damaged file: every line accounted."""
    import shutil

    from radartracker.io.convert import ConvertOptions, convert

    work = recording.parent / "work"
    shutil.rmtree(work, ignore_errors=True)
    shutil.copytree(recording, work / "rec")
    buf = (work / "rec" / name).read_bytes()
    (work / "rec" / name).write_bytes(apply(buf, edits.draw(mutations(len(buf)))))
    opts = ConvertOptions(AZN_TRACKS_MIN_MEASUR=1, TRACKS_MIN_MEASUR=1)
    assert works_or_refuses(convert, work / "rec", work / "new", opts) in ("read", "refused")

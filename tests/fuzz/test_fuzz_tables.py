"""Scenario folders with damaged CSV tables and scenario.json: read (every row usable) or a
RadarTrackerError, never a traceback."""

from __future__ import annotations

import json
import shutil

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from radartracker.io.scenario import read_scenario

from tests.fuzz.mutations import apply, mutations, works_or_refuses

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
TABLES = ("radars.csv", "plots.csv", "adsb.csv", "truth.csv", "truth_biases.csv")
TRICKY = st.one_of(
    st.sampled_from(["", " ", "nan", "NaN", "inf", "-inf", "1e400", "-1e-400", "-0", "0x10", "1_000", "٣", "360",
                     "359.99999999999999", "-90.0000001", "180.0000001", "\"", "\"a,b\"", ",", "\ufeff1", "12345g",
                     "0000", "7777", "8888", "ABCDEF", "abcdeg"]),
    st.floats().map(repr), st.integers().map(str), st.text(max_size=8))
JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=6),
                    lambda kids: st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=6), kids, max_size=4),
                    max_leaves=12)


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz_tables")


def _copy(src, work):
    dst = work / "s"
    shutil.rmtree(dst, ignore_errors=True)
    shutil.copytree(src, dst)
    return dst


@given(name=st.sampled_from(TABLES + ("scenario.json",)), edits=st.data(), skip_bad=st.booleans())
@FUZZ
def test_damaged_bytes(scenario_dir, work, name, edits, skip_bad):
    folder = _copy(scenario_dir, work)
    buf = (folder / name).read_bytes()
    (folder / name).write_bytes(apply(buf, edits.draw(mutations(len(buf)))))
    assert works_or_refuses(read_scenario, folder, skip_bad=skip_bad) in ("read", "refused")


@given(name=st.sampled_from(TABLES), data=st.data(), skip_bad=st.booleans())
@FUZZ
def test_tricky_field_values_and_line_edits(scenario_dir, work, name, data, skip_bad):
    """A field replaced by a tricky value, or a line duplicated, dropped, moved or blanked."""
    folder = _copy(scenario_dir, work)
    lines = (folder / name).read_text().splitlines(keepends=True)
    for _ in range(data.draw(st.integers(1, 3))):
        k = data.draw(st.integers(0, len(lines) - 1))
        action = data.draw(st.sampled_from(("field", "field", "duplicate", "drop", "move", "blank")))
        if action == "field":
            fields = lines[k].rstrip("\n").split(",")
            fields[data.draw(st.integers(0, len(fields) - 1))] = data.draw(TRICKY)
            lines[k] = ",".join(fields) + "\n"
        elif action == "duplicate":
            lines.insert(k, lines[k])
        elif action == "drop" and len(lines) > 1:
            del lines[k]
        elif action == "move":
            lines.insert(data.draw(st.integers(0, len(lines))), lines.pop(k))
        else:
            lines.insert(k, "\n")
    (folder / name).write_text("".join(lines))
    assert works_or_refuses(read_scenario, folder, skip_bad=skip_bad) in ("read", "refused")


@given(doc=st.one_of(JSON, st.fixed_dictionaries({"name": JSON, "reference": JSON, "aircraft": JSON}),
                     st.fixed_dictionaries({"reference": st.fixed_dictionaries({"lat": JSON, "lon": JSON})}),
                     st.fixed_dictionaries({"aircraft": st.lists(st.dictionaries(
                         st.sampled_from(["icao24", "callsign", "mode_3a", "adsb", "nacp", "transponder", "x"]),
                         JSON, max_size=6), max_size=3)})))
@FUZZ
def test_any_scenario_json(scenario_dir, work, doc):
    folder = _copy(scenario_dir, work)
    (folder / "scenario.json").write_text(json.dumps(doc))
    assert works_or_refuses(read_scenario, folder) in ("read", "refused")

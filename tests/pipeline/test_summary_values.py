"""summary.json's values are strict JSON: every non-finite float null, numpy scalars plain, keys text."""

import json
import math
from collections import Counter

import numpy as np

from radartracker.pipeline.result import strict


def test_strict_values():
    value = {"a": 1.5, 2: [np.float64(2.5), np.nan, (np.int64(3), True, None, "s")], "b": -0.0,
             "c": {"d": -np.inf, "e": np.float32(0.5), "f": math.inf}, "g": Counter(x=1), "h": [], "i": {}}
    out = strict(value)
    assert out == {"a": 1.5, "2": [2.5, None, [3, True, None, "s"]], "b": -0.0,
                   "c": {"d": None, "e": 0.5, "f": None}, "g": {"x": 1}, "h": [], "i": {}}
    assert [type(v) for v in out["2"][2]] == [int, bool, type(None), str] and type(out["2"][0]) is float
    assert type(out["c"]["e"]) is float and type(out["g"]) is dict
    assert json.dumps(out, allow_nan=False) == (
        '{"a": 1.5, "2": [2.5, null, [3, true, null, "s"]], "b": -0.0, "c": {"d": null, "e": 0.5, "f": null}, '
        '"g": {"x": 1}, "h": [], "i": {}}')


def test_the_observability_report_is_made_once_and_each_summary_is_a_copy():
    from radartracker.pipeline.config import RunConfig
    from radartracker.pipeline.run import run
    from radartracker.simulation.scenarios import build_scenario

    result = run(build_scenario("demo", seed=3, duration=120.0).run(), RunConfig(association="manager"), progress=False)
    first = result.summary()
    assert first["observability"]["radars"] and first["observability"] == strict(result.coupling.report())
    first["observability"]["radars"].clear()  # a caller's change to its summary is its own
    assert result.summary()["observability"] == strict(result.coupling.report())  # the oracle: a report made now
    assert result.observability is result.observability

"""What a document's ``before:``/``after:`` directives may call: the context a fragment of the docs assumes
(files a reader would have, a plugin the guide describes), made in the document's scratch folder.

* ``sh(line)``: run a command line as a ```sh line would (its status must be 0); returns its stdout.
* ``install_forgetting()``: the plugin guide's ``forgetting`` estimator, completed (it is
  ``tests/test_kit_thirdparty.py``'s), installed as pip would: ``radartracker.estimators`` / ``forgetting``.
* ``write_capture(scenario, path)``: a CAT062 recording of the TrackManager's tracks of a scenario folder,
  what ``serve`` publishes and ``radartracker score`` takes.
* ``example_bearings(sites)``: bearings of one target (its ``target`` ``"1"``, 8 km up, between the sites,
  6 epochs) from direction finders ``{id: (lat, lon, height_m)}`` with σ 1 mrad.
* ``write_bearings(stations_csv, bearings_csv)``: three stations and such bearings in the files of
  ``radartracker triangulate`` (docs/formats.md, "Triangulation files").
* ``requires(module)``: skip the rest of the document, with the reason, where ``module`` (an optional extra's,
  such as ``traffic.core``) is not installed; CI installs the extras, so there it runs.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.docs import commands

SIGMA_RAD = 1e-3


class DocFailure(AssertionError):
    """A block of a document did not run as written."""


def sh(line: str, cwd: Path) -> str:
    out = ""
    for text in commands.split_line(line):
        status, out, err = commands.run(commands.runnable(text, {}), cwd)
        if status != 0:
            raise DocFailure(f"`{text}` exited with {status}:\n{err[-3000:]}")
    return out


def install_forgetting(cwd: Path, monkeypatch) -> None:
    from tests.plugin_install import install
    from tests.test_kit_thirdparty import PLUGIN

    monkeypatch.delitem(sys.modules, "docs_forgetting", raising=False)  # so that the test's end removes it
    install(cwd / ".plugins", monkeypatch, "docs_forgetting", PLUGIN,
            "[radartracker.estimators]\nforgetting = docs_forgetting:Forgetting\n")


def write_capture(scenario: str, path: str, cwd: Path) -> None:
    from radartracker.io.asterix import write_cat062
    from radartracker.io.scenario import read_scenario
    from radartracker.pipeline.config import RunConfig
    from radartracker.pipeline.run import run

    result = run(read_scenario(cwd / scenario), RunConfig(association="manager"), progress=False)
    write_cat062(cwd / path, result)


def example_bearings(sites: dict[str, tuple[float, float, float]]) -> list:
    from radartracker_plugins.triangulation import DirectionFinder, TriangulationFrame
    from radartracker_plugins.triangulation.simulate import noisy_bearings, true_bearings

    frame = TriangulationFrame([DirectionFinder(k, *v, SIGMA_RAD, SIGMA_RAD) for k, v in sites.items()])
    ids = list(sites) * 6
    times = np.repeat(np.arange(6.0), len(sites))
    target = frame.enu(np.mean([v[0] for v in sites.values()]) + 0.05, np.mean([v[1] for v in sites.values()]),
                       8000.0)
    truth = true_bearings(frame, ids, np.tile(target, (len(ids), 1)))
    return noisy_bearings(frame, ids, times, truth, np.random.default_rng(1))


def write_bearings(stations_csv: str, bearings_csv: str, cwd: Path) -> None:
    sites = {"df0": (50.0, 7.0, 120.0), "df1": (50.3, 7.4, 150.0), "df2": (49.8, 7.5, 90.0)}
    sigma_deg = math.degrees(SIGMA_RAD)
    rows = [f"{k},{lat},{lon},{h},{sigma_deg},{sigma_deg}" for k, (lat, lon, h) in sites.items()]
    (cwd / stations_csv).write_text("id,lat_deg,lon_deg,height_m,sigma_azimuth_deg,sigma_elevation_deg\n"
                                    + "\n".join(rows) + "\n")
    lines = [f"{b.time},{b.station},{math.degrees(b.azimuth_rad)!r},{math.degrees(b.elevation_rad)!r},{b.target}"
             for b in example_bearings(sites)]
    (cwd / bearings_csv).write_text("time_s,station,azimuth_deg,elevation_deg,target\n" + "\n".join(lines) + "\n")


def requires(module: str) -> None:
    pytest.importorskip(module, reason=f"{module} is not installed (an optional extra of radartracker)")


def namespace(cwd: Path, monkeypatch) -> dict:
    """A document's Python namespace, with the helpers above bound to its scratch folder."""
    return {
        "__name__": "__docs__",
        "sh": lambda line: sh(line, cwd),
        "install_forgetting": lambda: install_forgetting(cwd, monkeypatch),
        "write_capture": lambda scenario, path: write_capture(scenario, path, cwd),
        "example_bearings": example_bearings,
        "write_bearings": lambda stations_csv, bearings_csv: write_bearings(stations_csv, bearings_csv, cwd),
        "requires": requires,
    }

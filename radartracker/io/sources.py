"""One door for every input source: a scenario folder or an ASTERIX recording (guessed by name)."""

from __future__ import annotations

from pathlib import Path

from radartracker.io.scenario import read_scenario
from radartracker.io.tables import ScenarioData

ASTERIX_SUFFIXES = (".ast", ".pcap", ".ff", ".final")


def read_source(path: Path | str, *, skip_bad: bool = False) -> ScenarioData:
    """Read a scenario folder (docs/formats.md) or an ASTERIX recording file."""
    path = Path(path)
    if path.suffix.lower() in ASTERIX_SUFFIXES:
        from radartracker.io.asterix_reader import read_asterix  # lazy: libasterix takes seconds to import
        return read_asterix(path, skip_bad=skip_bad)
    return read_scenario(path, skip_bad=skip_bad)

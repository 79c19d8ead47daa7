"""Distributed surveillance (seed 004): one tracker per radar, local tracks fused into system tracks."""

from __future__ import annotations

from typing import Any

__all__ = ["local_tracks_from_asterix"]


def __getattr__(name: str) -> Any:
    # lazy: the CAT048 reader pulls in libasterix's generated module (seconds to import), which a replay
    # of CSV files never needs, yet every CLI start imports this package (pipeline.config → fusion.center)
    if name == "local_tracks_from_asterix":
        from radartracker.fusion.cat048 import local_tracks_from_asterix
        return local_tracks_from_asterix
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

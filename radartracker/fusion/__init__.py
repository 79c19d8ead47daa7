"""Distributed surveillance (seed 004): one tracker per radar, local tracks fused into system tracks."""

from radartracker.fusion.cat048 import local_tracks_from_asterix

__all__ = ["local_tracks_from_asterix"]

"""Conversions to and from other air-traffic libraries (optional extras: ``pip install radartracker[traffic]``)."""

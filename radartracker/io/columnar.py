"""Plain blocks of plots.csv and adsb.csv converted column by column (placeholder: row by row)."""

from __future__ import annotations


def plots(reader, text):
    return None


def adsb(reader, text):
    return None

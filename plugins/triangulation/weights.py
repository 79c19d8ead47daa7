"""Weight matrices W for the least-squares estimate (seed 001 eq. 3.1).

W is block-diagonal with one 2×2 block per bearing (bearings are independent), taken from the
bearing's station: W = I needs no error model at all; a weights file gives each station its own
block. Only ratios between blocks matter (a common scale does not move the estimate).

Weights file (CSV, one row per station): ``station,w_azimuth,w_elevation[,w_cross]`` — the block
[[w_azimuth, w_cross], [w_cross, w_elevation]], positive semi-definite, any consistent unit.
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from pathlib import Path

import attrs
import numpy as np

from radartracker.api import FormatError, InputError

from ._lsq import BearingSet


@attrs.frozen
class StationWeights:
    """Per-station 2×2 weight blocks; stations not listed get ``default`` (None: refused)."""

    blocks: Mapping[str, np.ndarray] = attrs.field(factory=dict)
    default: np.ndarray | None = None

    @classmethod
    def identity(cls) -> StationWeights:
        """W = I: the plain least-squares estimate, which needs no error model."""
        return cls({}, np.eye(2))

    def for_bearings(self, bs: BearingSet) -> np.ndarray:
        """The blocks W_n of every bearing, (N, 2, 2)."""
        W = np.empty((len(bs), 2, 2))
        for station, idx in bs.groups:
            block = self.blocks.get(station, self.default)
            if block is None:
                raise InputError(f"weights: no weight block for station {station!r}")
            W[idx] = block
        return W


def read_weights(path: str | Path) -> StationWeights:
    """Read a weights file (module docstring); errors name file, line and field."""
    path = Path(path)
    blocks: dict[str, np.ndarray] = {}
    try:
        with path.open(newline="", encoding="utf-8-sig") as f:
            reader = csv.DictReader(f)
            missing = {"station", "w_azimuth", "w_elevation"} - set(reader.fieldnames or ())
            if missing:
                raise FormatError(path.name, 1, None, f"missing column(s) {', '.join(sorted(missing))}")
            for line, row in enumerate(reader, start=2):
                station = (row.get("station") or "").strip()
                if not station:
                    raise FormatError(path.name, line, "station", "empty")
                if station in blocks:
                    raise FormatError(path.name, line, "station", f"{station!r} appears twice")
                values = []
                for field in ("w_azimuth", "w_elevation", "w_cross"):
                    text = (row.get(field) or "").strip() if field in row else "0"
                    try:
                        v = float(text or "0")
                    except ValueError:
                        raise FormatError(path.name, line, field, f"{text!r} is not a number") from None
                    if not np.isfinite(v):
                        raise FormatError(path.name, line, field, f"{text!r} is not finite")
                    values.append(v)
                a, e, c = values
                block = np.array([[a, c], [c, e]])
                if np.linalg.eigvalsh(block)[0] < 0:
                    raise FormatError(path.name, line, None, "the weight block is not positive semi-definite")
                blocks[station] = block
    except UnicodeDecodeError:
        raise FormatError(path.name, 1, None, "not a UTF-8 text file") from None
    if not blocks:
        raise FormatError(path.name, 1, None, "no stations")
    return StationWeights(blocks)

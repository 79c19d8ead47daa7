"""biases.png stays readable with many radars: small multiples in a bounded grid, every radar drawn."""

import math
import struct
from types import SimpleNamespace

import numpy as np
import pytest

from radartracker.pipeline import figures


def _result(n: int) -> SimpleNamespace:
    """What plot_biases reads of a RunResult: n radars' bias estimates over 10 minutes, and their truth."""
    radars = [f"R{i:02d}" for i in range(n)]
    t = np.arange(0.0, 600.0, 10.0)
    time = np.tile(t, n)
    value = np.stack([50.0 + 10.0 * np.exp(-time / 100.0), np.full_like(time, 1e-3)], axis=-1)
    cov = np.zeros((len(time), 2, 2))
    cov[:, 0, 0], cov[:, 1, 1] = 100.0 * np.exp(-time / 100.0) + 1.0, 1e-8
    return SimpleNamespace(final_biases=dict.fromkeys(radars),
                           biases=SimpleNamespace(time=time, radar=np.repeat(np.array(radars, object), len(t)),
                                                  value=value, cov=cov),
                           data=SimpleNamespace(truth_biases={r: (50.0, 1e-3) for r in radars}, name="many"),
                           estimator_name="stub")


def _png_size(path) -> tuple[int, int]:
    """(width, height) in pixels, from the PNG's IHDR chunk (bytes 16 to 24: two big-endian 32-bit numbers)."""
    return struct.unpack(">II", path.read_bytes()[16:24])


@pytest.fixture()
def drawn(monkeypatch):
    """The figures plot_biases saves, kept open to be looked at."""
    kept = []
    save = figures.save
    monkeypatch.setattr(figures, "save", lambda fig, path, dpi=110: (kept.append(fig), save(fig, path, dpi)))
    return kept


def test_28_radars_make_a_bounded_grid_with_every_radar(tmp_path, drawn):
    """Before: one row of 56 panels, 12 320 × 660 px. Now at most 6 cells a row and 24 in (2640 px at 110 dpi)
    high; each radar's range and azimuth panels are drawn and titled."""
    figures.plot_biases(_result(28), tmp_path / "biases.png")
    width, height = _png_size(tmp_path / "biases.png")
    assert width <= 6 * 3.2 * 110 + 1 and height <= 24 * 110 + 1
    assert 0.5 <= width / height <= 2.0  # neither a strip nor a column
    shown = [ax for ax in drawn[0].axes if ax.axison]
    assert len(shown) == 2 * 28
    titled = {ax.get_title().split(":")[0] for ax in shown if "range" in ax.get_title()}
    assert titled == {f"R{i:02d}" for i in range(28)}


@pytest.mark.parametrize("n", [1, 4, 7])
def test_few_radars_fill_rows_of_at_most_six(tmp_path, drawn, n):
    figures.plot_biases(_result(n), tmp_path / "biases.png")
    shown = [ax for ax in drawn[0].axes if ax.axison]
    assert len(shown) == 2 * n
    columns = {round(ax.get_position().x0, 3) for ax in shown}
    assert len(columns) == min(n, 6)
    rows = {round(ax.get_position().y0, 3) for ax in shown}
    assert len(rows) == 2 * math.ceil(n / 6)

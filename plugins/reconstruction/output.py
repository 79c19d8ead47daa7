"""Per-aircraft output of a reconstruction: track CSV and OziExplorer ``.plt``, segments, hypotheses, figure.

Folder ``<out>/<key>/``:

* ``track.csv`` — the geometric track: time (s UTC), x, y (m, system plane), lat, lon (deg),
  altitude (m), heading (deg clockwise from north), speed (m/s), segment index, and the quality
  flags of the point's segment (:mod:`.quality`): ``segment_chi2`` (Σ d² / 2n of its plots) and
  ``pinned`` (``u``, ``w``, ``uw`` when its control sits at a bound, else empty);
* ``track.plt`` — the same track for OziExplorer (:func:`radartracker.recording.write_plt`);
* ``segments.csv`` — the control track: segment, t_start, t_end, u, w (m/s²), first/last grid point;
* ``hypotheses.csv`` — every hypothesis ranked: rank, segments, weight (NLL), score (BIC), normalised
  χ², parameters, evaluations, origin (segmentation, split or merge);
* ``figure.png`` — plots, reconstruction and truth (when known) in the plane; u and w over time.

Every file is written atomically (``atomic_open``/``atomic_path``: a temporary file beside it, flushed,
then renamed), so a killed run leaves complete files or none.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from radartracker.api import SystemPlane, TrackPoints, atomic_open, atomic_path, write_plt
from radartracker_plugins.reconstruction.config import ReconstructionConfig
from radartracker_plugins.reconstruction.hypotheses import Reconstruction
from radartracker_plugins.reconstruction.quality import pinned_segments, segment_chi2
from radartracker_plugins.reconstruction.weight import TrackWeight


def _safe(key: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in key) or "aircraft"


def write_reconstruction(rec: Reconstruction, plane: SystemPlane, out: Path, truth=None,
                         figure: bool = True, cfg: ReconstructionConfig | None = None) -> Path:
    """Write ``rec`` into ``out/<key>/`` and return that folder (``cfg``: the bounds for the pinned flags)."""
    folder = Path(out) / _safe(rec.key)
    folder.mkdir(parents=True, exist_ok=False)
    g = rec.geo
    lat, lon = plane.to_geodetic(g.x, g.y)
    chi2 = segment_chi2(rec, TrackWeight(rec.plots))
    pins = pinned_segments(rec, cfg or ReconstructionConfig())
    pin = ["u" * int(a) + "w" * int(b) for a, b in zip(pins["u"], pins["w"])]
    with atomic_open(folder / "track.csv", "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["time", "x_m", "y_m", "lat", "lon", "altitude_m", "heading_deg", "speed_mps", "segment",
                     "segment_chi2", "pinned"])
        for row in zip(g.time, g.x, g.y, lat, lon, g.h, np.degrees(np.mod(g.phi, 2 * np.pi)), g.v, g.segment):
            k = int(row[8])
            wr.writerow([f"{row[0]:.3f}", f"{row[1]:.2f}", f"{row[2]:.2f}", f"{row[3]:.7f}", f"{row[4]:.7f}",
                         f"{row[5]:.1f}", f"{row[6]:.3f}", f"{row[7]:.3f}", k, f"{chi2[k]:.3f}", pin[k]])
    write_plt(folder / "track.plt", TrackPoints(g.time, lat, lon, g.h), name=rec.key)  # atomic itself
    with atomic_open(folder / "segments.csv", "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["segment", "t_start", "t_end", "u_mps2", "w_mps2", "first_point", "last_point"])
        for k, s in enumerate(g.control):
            wr.writerow([k, f"{s.t_start:.3f}", f"{s.t_end:.3f}", f"{s.u:.5f}", f"{s.w:.5f}",
                         s.geo_span.start, s.geo_span.stop - 1])
    with atomic_open(folder / "hypotheses.csv", "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["rank", "segments", "weight", "score", "chi2", "parameters", "evaluations", "origin"])
        for r, h in enumerate(rec.hypotheses, 1):
            wr.writerow([r, len(h.control), f"{h.weight:.3f}", f"{h.score:.3f}", f"{h.chi2:.4f}", h.n_params, h.nfev,
                         h.origin])
    if figure:
        plot_reconstruction(rec, folder / "figure.png", truth)
    return folder


def plot_reconstruction(rec: Reconstruction, path: Path, truth=None) -> None:
    """Figure: plane view (plots, reconstruction, truth) and the controls u, w over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    g, pt = rec.geo, rec.plots
    fig, (ax, au) = plt.subplots(1, 2, figsize=(13, 5.5), gridspec_kw={"width_ratios": [1.2, 1]})
    ax.plot(pt.z[:, 0] / 1e3, pt.z[:, 1] / 1e3, ".", ms=2.5, color="0.6", label="plots")
    if truth is not None:
        ax.plot(truth[1][:, 0] / 1e3, truth[1][:, 1] / 1e3, "-", lw=2.5, color="tab:green", alpha=0.5, label="truth")
    ax.plot(g.x / 1e3, g.y / 1e3, "-", lw=1.0, color="tab:blue", label="reconstruction")
    sw = np.array([s.geo_span.start for s in g.control])
    ax.plot(g.x[sw] / 1e3, g.y[sw] / 1e3, "k|", ms=8, label="switches")
    ax.set_xlabel("x east (km)")
    ax.set_ylabel("y north (km)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{rec.key}: {len(g.control)} segments")
    t0 = g.control.t_start
    ts = np.array([[s.t_start, s.t_end] for s in g.control]).ravel() - t0
    au.step(ts, np.repeat(g.control.u, 2), where="post", label="u (lateral)")
    au.step(ts, np.repeat(g.control.w, 2), where="post", label="w (longitudinal)")
    au.set_xlabel("time since start (s)")
    au.set_ylabel("control (m/s²)")
    au.grid(alpha=0.3)
    au.legend(fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)

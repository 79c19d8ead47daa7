"""Quality flags of a reconstruction: how well it explains the plots, and whether the bounds held it.

* **Normalised residual χ²** of the selected track: χ²_ν = Σ_i d_i² / (2n − p), d_i² the squared
  Mahalanobis distance of plot i under its R_i (:mod:`.weight`), p the parameters. About 1 when the
  model and the stated plot noise hold; > 1 when the track misses the plots (or R understates the
  noise), < 1 when R overstates it. Per segment: Σ_{i∈k} d_i² / 2n_k (in ``track.csv``).
* **Controls pinned at their bounds**: segments whose |u| or |w| sits within 1 % of ``max_u`` /
  ``max_w`` — the optimiser wanted more, so the flown manoeuvre is probably harder than the bound.
* **Verdict** in plain language: ``plausible``, or why not. The thresholds are practical, not a
  χ² test (with 2n ≈ 10³ degrees of freedom any real model error is "significant"): a χ²_ν
  above :data:`CHI2_IMPLAUSIBLE` (residuals twice the stated noise), or pinned controls with a
  χ²_ν above :data:`CHI2_PINNED` (residuals 1.4× the noise).
"""

from __future__ import annotations

import numpy as np

from radartracker_plugins.reconstruction.config import ReconstructionConfig
from radartracker_plugins.reconstruction.hypotheses import Reconstruction
from radartracker_plugins.reconstruction.integrate import sample
from radartracker_plugins.reconstruction.weight import TrackWeight

CHI2_IMPLAUSIBLE = 4.0
CHI2_PINNED = 2.0
PIN_FRACTION = 0.99
_NAMES = {"u": ("lateral", "--max-u"), "w": ("longitudinal", "--max-w")}


def segment_chi2(rec: Reconstruction, weight: TrackWeight) -> np.ndarray:
    """Per segment of the selected track: Σ d² / 2n over its plots (NaN for a segment without plots)."""
    ct, t = rec.control, rec.plots.t
    d2 = weight.distances2(sample(ct, t)[:, :2])
    seg = ct.segment_index(t)
    out = np.full(len(ct), np.nan)
    for k in range(len(ct)):
        sel = seg == k
        if sel.any():
            out[k] = d2[sel].sum() / (2 * sel.sum())
    return out


def pinned_segments(rec: Reconstruction, cfg: ReconstructionConfig) -> dict[str, np.ndarray]:
    """Boolean per segment, for "u" and "w": the control sits at its bound."""
    ct = rec.control
    return {"u": np.abs(ct.u) >= PIN_FRACTION * cfg.max_u, "w": np.abs(ct.w) >= PIN_FRACTION * cfg.max_w}


def assess(rec: Reconstruction, cfg: ReconstructionConfig) -> dict:
    """Quality of ``rec``: χ²_ν, pinned controls, verdict, and warnings (one line each) naming the flight."""
    ct = rec.control
    chi2 = float(rec.best.chi2)
    pins, warnings, pinned_info = pinned_segments(rec, cfg), [], []
    dur = np.array([s.duration for s in ct])
    for c, mask in pins.items():
        if not mask.any():
            continue
        bound = cfg.max_u if c == "u" else cfg.max_w
        name, flag = _NAMES[c]
        secs = float(dur[mask].sum())
        pinned_info.append({"control": c, "bound_mps2": bound, "segments": int(mask.sum()), "seconds": round(secs, 1),
                            "fraction_of_flight": round(secs / float(dur.sum()), 3)})
        warnings.append(f"{rec.key}: {name} control {c} pinned at its bound {bound:g} m/s² in {int(mask.sum())} of "
                        f"{len(ct)} segments ({secs:.0f} s of {dur.sum():.0f} s); the aircraft may manoeuvre harder "
                        f"than {flag} {bound:g} allows")
    reasons = []
    if chi2 > CHI2_IMPLAUSIBLE:
        reasons.append(f"the track misses the plots by {np.sqrt(chi2):.1f} times their stated noise (χ²_ν {chi2:.1f})")
    elif pinned_info and chi2 > CHI2_PINNED:
        reasons.append(f"controls pinned at their bounds and residuals {np.sqrt(chi2):.1f} times the plot noise "
                       f"(χ²_ν {chi2:.1f})")
    if reasons and pinned_info:
        reasons.append("raise " + " and ".join(_NAMES[p["control"]][1] for p in pinned_info))
    elif reasons:
        reasons.append("check the plot noise (R) and the radar biases, or the input's association")
    verdict = "plausible" if not reasons else "implausible: " + "; ".join(reasons)
    return {"chi2": round(chi2, 3), "pinned": pinned_info, "plausible": not reasons, "verdict": verdict,
            "warnings": warnings}


def truth_error(rec: Reconstruction, truth: tuple[np.ndarray, np.ndarray]) -> dict:
    """Horizontal error (m) of the selected track against the truth (times, positions) at the plot times."""
    t = rec.plots.t
    tt, pos = truth
    inside = (t >= tt[0]) & (t <= tt[-1])
    if not inside.any():
        return {}
    t = t[inside]
    ref = np.column_stack([np.interp(t, tt, pos[:, 0]), np.interp(t, tt, pos[:, 1])])
    e = np.hypot(*(sample(rec.control, t)[:, :2] - ref).T)
    return {"median_m": round(float(np.median(e)), 1), "p90_m": round(float(np.percentile(e, 90)), 1),
            "rmse_m": round(float(np.sqrt(np.mean(e**2))), 1), "max_m": round(float(e.max()), 1)}

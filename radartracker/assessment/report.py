"""``report.html``: one self-contained page a person reads — the verdicts against the profile, every
radar's figures with their 95 % intervals, and the figures drawn (matplotlib, Agg), each embedded as a
base64 PNG: the bias estimates with ±1.96 σ against the profile's limits, the biases over the run, and per
radar its Pd by range, azimuth and altitude, its Pd map and its error histograms with the normal density of the
measured σ; its Pd by elevation with the measured cone of silence, its coverage diagram (the detection range
achieved per azimuth sector against the configured range) and its plots per scan; and its error scatter, range
against azimuth error with the fitted sensor errors removed, with the 95 % ellipse of their covariance and,
dashed, the one its stated σ's give (:mod:`radartracker.assessment.ellipse`)."""

from __future__ import annotations

import base64
import html
import io
import math

import numpy as np

from radartracker.assessment.assess import Assessment
from radartracker.assessment.ellipse import ellipse_points
from radartracker.assessment.profile import INDICATORS
from radartracker.assessment.radar import RadarAssessment
from radartracker.progress import progress_bar

_STYLE = """body{font-family:sans-serif;margin:2em;max-width:1200px}table{border-collapse:collapse;margin:1em 0}
td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}th{background:#eee}td.t{text-align:left}
.pass{background:#c8f0c8}.fail{background:#f5c0c0}.inconclusive{background:#f7e9b0}img{max-width:100%}"""


def _figure() -> tuple:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _png(fig) -> str:
    """The figure as an ``<img>`` of an embedded PNG (and the figure closed)."""
    plt = _figure()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return f'<img alt="figure" src="data:image/png;base64,{base64.b64encode(buf.getvalue()).decode()}">'


def _fmt(x: float) -> str:
    if x is None or not math.isfinite(x):
        return "–"
    return f"{x:.4g}"


def _table(header: list[str], rows: list[list[str]], classes: list[str] | None = None) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join(f'<tr class="{c}">' + "".join(f'<td class="{"t" if j == 0 else ""}">{html.escape(v)}</td>'
                                               for j, v in enumerate(r)) + "</tr>"
                   for r, c in zip(rows, classes or [""] * len(rows)))
    return f"<table><tr>{head}</tr>{body}</table>"


def bias_figure(a: Assessment, plt) -> str:
    """Each radar's estimated range and azimuth bias with ±1.96 σ, the profile's limits dashed."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.2))
    names = [r.radar for r in a.radars]
    for ax, key in zip(axes, ("range_bias_m", "azimuth_bias_deg")):
        est = [r.figures[key] for r in a.radars]
        v = np.array([e.value for e in est])
        ax.errorbar(np.arange(len(v)), v, yerr=[v - [e.low for e in est], [e.high for e in est] - v], fmt="o",
                    capsize=4)
        for c in a.profile.criteria:
            if c.indicator == key:
                for s in (1, -1):
                    ax.axhline(s * c.threshold, ls="--", color="r", lw=0.8)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xticks(np.arange(len(v)), names)
        ax.set_title(f"{INDICATORS[key][0]} ({INDICATORS[key][1]}), 95 %")
    return _png(fig)


def bias_history_figure(a: Assessment, plt) -> str:
    """The joint estimator's biases over the replay with their ±1.96 σ bands (the axes fitted to the run's second
    half: the prior's σ of the first seconds would flatten the rest)."""
    b = a.result.biases
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.2))
    t0 = float(b.time.min()) if len(b.time) else 0.0
    settled: list[list[float]] = [[], []]  # the second half's values: the limits of the axes, not the prior's σ
    for rid in np.unique(b.radar.astype(str)).tolist():
        sel = b.radar.astype(str) == rid
        t = b.time[sel] - t0
        for ax, j, scale in ((axes[0], 0, 1.0), (axes[1], 1, math.degrees(1.0))):
            v, sd = b.value[sel, j] * scale, np.sqrt(np.abs(b.cov[sel, j, j])) * scale
            ax.plot(t, v, label=rid)
            ax.fill_between(t, v - 1.96 * sd, v + 1.96 * sd, alpha=0.2)
            settled[j] += (v[len(v) // 2:] - 1.96 * sd[len(v) // 2:]).tolist() + (v[len(v) // 2:]
                                                                                + 1.96 * sd[len(v) // 2:]).tolist()
    for ax, values in zip(axes, settled):
        if values:
            lo, hi = min(values + [0.0]), max(values + [0.0])
            ax.set_ylim(lo - 0.3 * (hi - lo), hi + 0.3 * (hi - lo))
    axes[0].set_title("range bias over the replay (m)")
    axes[1].set_title("azimuth bias over the replay (deg)")
    for ax in axes:
        ax.set_xlabel("s from the first estimate")
    axes[0].legend(fontsize=7)
    return _png(fig)


def radar_figures(r: RadarAssessment, plt) -> str:
    """Pd by range, azimuth and altitude (Wilson 95 %), the Pd map, and the error histograms of one radar."""
    fig, axes = plt.subplots(2, 3, figsize=(15, 7.5))
    axes = axes.ravel()
    for ax, variable, label in ((axes[0], "range_km", "slant range (km)"), (axes[1], "azimuth_deg", "azimuth (deg)"),
                                (axes[2], "altitude_m", "altitude (m)")):
        rows = [b for b in r.pd_bins if b["variable"] == variable]
        mid = np.array([(b["bin_low"] + b["bin_high"]) / 2 for b in rows])
        pd = np.array([b["pd"] for b in rows])
        if len(rows):
            ax.errorbar(mid, pd, yerr=[pd - [b["ci_low"] for b in rows], [b["ci_high"] for b in rows] - pd], fmt="o-",
                        capsize=3)
        ax.set_ylim(0, 1.05)
        ax.set_xlabel(label)
        ax.set_title(f"{r.radar}: Pd by {label.split(' (')[0]}")
    ex = r.expected
    if len(ex["x"]):
        hb = axes[3].hexbin(ex["x"] / 1e3, ex["y"] / 1e3, C=ex["detected"].astype(float), gridsize=20,
                            reduce_C_function=np.mean, vmin=0, vmax=1, cmap="RdYlGn")
        fig.colorbar(hb, ax=axes[3])
    axes[3].set_title(f"{r.radar}: Pd map (system plane x, y km)")
    axes[3].set_aspect("equal")
    for ax, key, unit in ((axes[4], "range_m", "m"), (axes[5], "azimuth_deg", "deg")):
        e = r.residuals[key]
        if len(e) > 1:
            ax.hist(e, bins=40, density=True)
            m, s = float(np.mean(e)), float(np.std(e, ddof=1))
            x = np.linspace(m - 4 * s, m + 4 * s, 200)
            ax.plot(x, np.exp(-0.5 * ((x - m) / s) ** 2) / (s * math.sqrt(2 * math.pi)), "r")
        ax.set_title(f"{r.radar}: {key.split('_')[0]} error, bias removed ({unit})")
    fig.tight_layout()
    return _png(fig)


def coverage_figures(r: RadarAssessment, plt) -> str:
    """Pd by elevation (all crossings, Wilson 95 %) with the measured cone of silence and its interval; the
    coverage diagram (polar, north up, clockwise): per azimuth sector the detection range achieved, its upper
    bound outlined, the configured range dashed; the plots of each antenna revolution."""
    fig = plt.figure(figsize=(15, 4.2))
    ax = fig.add_subplot(1, 3, 1)
    rows = [b for b in r.pd_bins if b["variable"] == "elevation_deg"]
    if rows:
        mid, pd = np.array([(b["bin_low"] + b["bin_high"]) / 2 for b in rows]), np.array([b["pd"] for b in rows])
        ax.errorbar(mid, pd, yerr=[pd - [b["ci_low"] for b in rows], [b["ci_high"] for b in rows] - pd], fmt="o-",
                    capsize=3)
    cone = r.figures.get("cone_of_silence_deg")
    if cone is not None:
        ax.axvline(cone.value, color="r", label=f"measured cone {cone.value:.1f}°")
        ax.axvspan(cone.low, cone.high, color="r", alpha=0.2)
        ax.legend(fontsize=7)
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("elevation (deg)")
    ax.set_title(f"{r.radar}: Pd by elevation (cone of silence)")
    polar = fig.add_subplot(1, 3, 2, projection="polar")
    polar.set_theta_zero_location("N")
    polar.set_theta_direction(-1)
    judged = [s for s in r.coverage if math.isfinite(s["range_km"])]
    if judged:
        mid = np.radians([(s["azimuth_low"] + s["azimuth_high"]) / 2 for s in judged])
        width = np.radians([s["azimuth_high"] - s["azimuth_low"] for s in judged])
        polar.bar(mid, [s["range_high_km"] for s in judged], width=width, fill=False, edgecolor="g")
        polar.bar(mid, [s["range_km"] for s in judged], width=width, color="g", alpha=0.5, label="achieved")
    if r.coverage:
        ring = np.linspace(0, 2 * math.pi, 200)
        polar.plot(ring, np.full(200, r.coverage[0]["configured_range_km"]), "r--", label="configured")
        polar.legend(fontsize=7, loc="lower left")
    polar.set_title(f"{r.radar}: detection range per sector (km)")
    ax = fig.add_subplot(1, 3, 3)
    ax.plot(np.arange(len(r.scan_counts)), r.scan_counts, lw=0.8)
    ax.set_xlabel("antenna revolution")
    ax.set_title(f"{r.radar}: plots per scan")
    fig.tight_layout()
    return _png(fig)


def ellipse_figure(r: RadarAssessment, plt) -> str:
    """The error scatter of one radar (module docstring): its sampled residuals, the 95 % ellipse of the
    measured covariance (solid) and of the stated σ's (dashed), both about the residuals' mean; empty axes, and
    why, without a fit."""
    fig, ax = plt.subplots(figsize=(6.5, 5))
    e = r.ellipse
    if e is None:
        ax.text(0.5, 0.5, "no sensor-error fit: too few matched plots", ha="center", transform=ax.transAxes)
    else:
        ax.scatter(e.points[:, 0], e.points[:, 1], s=4, alpha=0.4, label=f"{len(e.points)} of {e.n} plots")
        sd, stated = np.sqrt(np.diag(e.cov)), np.sqrt(np.diag(e.stated))
        for cov, style, what, (s_r, s_a) in ((e.cov, "r-", "measured", sd), (e.stated, "k--", "stated", stated)):
            ring = ellipse_points(e.mean, cov)
            ax.plot(ring[:, 0], ring[:, 1], style, label=f"95 % {what}: σ_r {s_r:.3g} m, σ_θ {s_a:.3g}°")
        c = r.figures["range_azimuth_correlation"]
        ax.set_title(f"{r.radar}: errors, sensor errors removed; r = {_fmt(c.value)} [{_fmt(c.low)}, "
                     f"{_fmt(c.high)}]", fontsize=9)
        ax.legend(fontsize=7)
    ax.set_xlabel("range error (m)")
    ax.set_ylabel("azimuth error (deg)")
    fig.tight_layout()
    return _png(fig)


def render(a: Assessment, *, progress: bool = True) -> str:
    """The whole page (module docstring)."""
    plt = _figure()
    verdicts = a.verdicts()
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Assessment of {html.escape(a.scenario)}"
             f"</title><style>{_STYLE}</style></head><body>",
             f"<h1>Surveillance assessment: {html.escape(a.scenario)}</h1>",
             f"<p>Reference: <b>{html.escape(a.reference)}</b>; biases by the joint estimator "
             f"<b>{html.escape(a.result.estimator_name)}</b>; profile <b>{html.escape(a.profile.name)}</b> "
             f"({html.escape(a.profile.source)}). Intervals at 95 %. A verdict is <i>pass</i> when the whole "
             "interval meets the rule, <i>fail</i> when none of it does, <i>inconclusive</i> otherwise.</p>",
             "<h2>Verdicts</h2>",
             _table(["radar", "indicator", "value", "95 % interval", "rule", "verdict", "standard"],
                    [[v["radar"], v["indicator"], _fmt(v["value"]), f"[{_fmt(v['ci_low'])}, {_fmt(v['ci_high'])}]",
                      v["rule"], v["verdict"], v["standard"] + (f" ({v['note']})" if v["note"] else "")]
                     for v in verdicts], [v["verdict"].replace(" ", "-") for v in verdicts]),
             "<h2>Biases</h2>", bias_figure(a, plt), bias_history_figure(a, plt)]
    for r in progress_bar(a.radars, desc="report figures", unit="radar", disable=not progress):
        rows = [[INDICATORS[k][0], INDICATORS[k][1], _fmt(e.value), _fmt(e.low), _fmt(e.high), str(e.n), e.method]
                for k, e in r.figures.items()]
        rows += [[INDICATORS[k][0], INDICATORS[k][1], "–", "–", "–", "0", f"not assessable: {why}"]
                 for k, why in r.not_assessable.items()]
        fitted = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in r.components.items()) or "not fitted"
        parts += [f"<h2>Radar {html.escape(r.radar)} ({r.kind.upper()}; bias observability: "
                  f"{html.escape(r.observability)})</h2>",
                  f"<p>Sensor errors against the reference: {html.escape(fitted)}.</p>",
                  _table(["figure", "unit", "value", "95 % low", "95 % high", "n", "interval"], rows),
                  radar_figures(r, plt), coverage_figures(r, plt), ellipse_figure(r, plt)]
    rows = [[INDICATORS[k][0], INDICATORS[k][1], _fmt(e.value), _fmt(e.low), _fmt(e.high), str(e.n), e.method]
            for k, e in a.system.items()]
    rows += [[INDICATORS[k][0], INDICATORS[k][1], "–", "–", "–", "0", f"not assessable: {why}"]
             for k, why in a.system_not_assessable.items()]
    parts += [f"<h2>System tracks (ESASSP indicators; tracks: {html.escape(a.system_source)})</h2>",
              _table(["figure", "unit", "value", "95 % low", "95 % high", "n", "interval"], rows),
              "</body></html>"]
    return "\n".join(parts)

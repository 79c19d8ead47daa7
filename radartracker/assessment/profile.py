"""Profiles: what each figure is judged against, and by which standard (docs/assessment.md, "Profiles").

A profile is a TOML (or JSON) file: ``name``, ``description`` and a list ``criteria``, each with
``indicator`` (a name of :data:`INDICATORS`), ``rule`` (``below``: value < threshold; ``abs_below``:
|value| < threshold; ``above``: value > threshold), ``threshold`` (in the indicator's unit),
``radar_kind`` (``any``, ``ssr``, ``psr``: the radars it applies to; ``system``: the system tracks),
``standard`` (the document that sets it) and an optional ``note``. The default,
``radartracker/data/assessment-eurocontrol-1997.toml``, holds the 1997 EUROCONTROL radar standard and
ESASSP's 5 NM figures.

A figure is judged on its 95 % interval: **pass** when the whole interval meets the rule, **fail** when
none of it does, **inconclusive** when the threshold lies inside it (the sample cannot tell).
"""

from __future__ import annotations

import json
import math
import tomllib
from importlib.resources import files
from pathlib import Path

import attrs

from radartracker.assessment.stats import Estimate
from radartracker.errors import ConfigurationError

#: every figure of the assessment: name → (what it is, unit; a share is a probability in [0, 1])
INDICATORS: dict[str, tuple[str, str]] = {
    "range_bias_m": ("range bias (joint estimator)", "m"),
    "azimuth_bias_deg": ("azimuth bias (joint estimator)", "deg"),
    "range_bias_vs_reference_m": ("range offset against the reference (fit with gain and time offset)", "m"),
    "azimuth_bias_vs_reference_deg": ("azimuth offset against the reference (fit with time offset)", "deg"),
    "range_gain_ppm": ("range gain against the reference", "ppm"),
    "time_offset_ms": ("time-stamp offset against the reference", "ms"),
    "range_sigma_m": ("random range error σ", "m"),
    "azimuth_sigma_deg": ("random azimuth error σ", "deg"),
    "range_azimuth_correlation": ("correlation of the random range and azimuth errors", "1"),
    "pd": ("probability of detection", "share"),
    "cone_of_silence_deg": ("cone of silence, measured (elevation above which Pd drops)", "deg"),
    "detection_range_km": ("detection range achieved (farthest slant range with Pd ≥ the stated level)", "km"),
    "coverage_share": ("share of the configured coverage achieved (area, judged sectors)", "share"),
    "plots_per_scan": ("plots per scan", "plots"),
    "false_plots_per_scan": ("false plots per scan", "plots"),
    "split_plot_share": ("split plots (share of sweeps)", "share"),
    "reflection_share": ("reflections (share of sweeps)", "share"),
    "mode_3a_validity": ("Mode 3/A validity", "share"),
    "mode_3a_correctness": ("Mode 3/A correctness", "share"),
    "mode_c_validity": ("Mode C validity", "share"),
    "mode_c_correctness": ("Mode C correctness", "share"),
    "mode_s_correctness": ("Mode S address correctness", "share"),
    "out_of_order_share": ("plots out of time order", "share"),
    "timestamp_jitter_s": ("time stamp − antenna time, σ", "s"),
    "timestamp_lateness_s": ("time-stamp lateness (delivery − time stamp), 95th percentile", "s"),
    "position_rmse_m": ("system tracks: horizontal position RMS error", "m"),
    "probability_of_update": ("system tracks: probability of update", "share"),
    "breaks_per_flight_hour": ("system tracks: breaks per flight hour", "1/h"),
    "multiple_share_of_time": ("system tracks: multiple tracks (share of time)", "share"),
    "false_tracks": ("system tracks: false tracks", "tracks"),
    "initiation_delay_p95_s": ("system tracks: initiation delay, 95th percentile", "s"),
    "latency_p95_s": ("system tracks: latency (time of applicability to delivery), 95th percentile", "s"),
}
RULES = ("below", "abs_below", "above")
KINDS = ("any", "ssr", "psr", "system")
DEFAULT_PROFILE = "assessment-eurocontrol-1997.toml"


@attrs.frozen
class Criterion:
    """One rule of a profile (module docstring)."""

    indicator: str
    rule: str
    threshold: float
    radar_kind: str
    standard: str
    note: str = ""

    def applies(self, kind: str) -> bool:
        """Whether it judges a radar of ``kind`` (``ssr``, ``psr``) or the system tracks (``system``)."""
        return self.radar_kind == kind or (self.radar_kind == "any" and kind != "system")

    def judge(self, e: Estimate) -> str:
        """``pass``, ``fail`` or ``inconclusive`` (module docstring); ``not assessed`` without a value."""
        if not math.isfinite(e.value):
            return "not assessed"
        lo, hi = e.low, e.high
        if self.rule == "abs_below":
            lo, hi = (0.0 if lo <= 0.0 <= hi else min(abs(lo), abs(hi))), max(abs(lo), abs(hi))
        if self.rule == "above":
            return "pass" if lo > self.threshold else "fail" if hi <= self.threshold else "inconclusive"
        return "pass" if hi < self.threshold else "fail" if lo >= self.threshold else "inconclusive"

    def text(self) -> str:
        """The rule as a person reads it: ``|x| < 100``."""
        sign = {"below": "< ", "abs_below": "|x| < ", "above": "> "}[self.rule]
        return f"{sign}{self.threshold:g}"


@attrs.frozen
class Profile:
    """A named list of criteria, and the file it came from."""

    name: str
    description: str
    criteria: tuple[Criterion, ...]
    source: str

    def for_kind(self, kind: str) -> list[Criterion]:
        return [c for c in self.criteria if c.applies(kind)]


def load_profile(path: Path | str | None = None) -> Profile:
    """The profile in ``path`` (TOML, or JSON by its suffix); the shipped default when ``None``. A bad file is
    a ConfigurationError naming the file, the line and the field."""
    if path is None:
        text, where = (files("radartracker") / "data" / DEFAULT_PROFILE).read_text(encoding="utf-8"), DEFAULT_PROFILE
    else:
        try:
            text, where = Path(path).read_text(encoding="utf-8"), str(path)
        except (OSError, UnicodeDecodeError) as exc:
            raise ConfigurationError(f"--profile {path}: cannot be read ({exc})") from exc
    try:
        doc = json.loads(text) if where.endswith(".json") else tomllib.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ConfigurationError(f"{where}: not a valid profile file: {exc}") from exc
    if not isinstance(doc.get("name"), str) or not isinstance(doc.get("criteria"), list) or not doc["criteria"]:
        raise ConfigurationError(f"{where}: line 1: a profile needs a text 'name' and a non-empty list 'criteria'")
    return Profile(doc["name"], str(doc.get("description", "")),
                   tuple(_criterion(c, i, text, where) for i, c in enumerate(doc["criteria"])), where)


def _criterion(c: object, i: int, text: str, where: str) -> Criterion:
    """Criterion ``i`` of a profile, checked field by field."""
    def bad(field: str, why: str) -> ConfigurationError:
        return ConfigurationError(f"{where}: line {_line_of(text, i, field)}: criteria[{i}].{field}: {why}")

    if not isinstance(c, dict):
        raise bad("indicator", "each criterion must be a table of fields")
    checks = {"indicator": (lambda v: v in INDICATORS, f"one of {', '.join(INDICATORS)}"),
              "rule": (lambda v: v in RULES, f"one of {', '.join(RULES)}"),
              "radar_kind": (lambda v: v in KINDS, f"one of {', '.join(KINDS)}"),
              "standard": (lambda v: isinstance(v, str) and v.strip(), "the name of the standard that sets it"),
              "threshold": (lambda v: isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v),
                            "a finite number")}
    for field, (ok, expected) in checks.items():
        if field not in c:
            raise bad(field, "missing")
        if not ok(c[field]):
            raise bad(field, f"expected {expected}, got {c[field]!r}")
    return Criterion(c["indicator"], c["rule"], float(c["threshold"]), c["radar_kind"], c["standard"],
                     str(c.get("note", "")))


def _line_of(text: str, index: int, field: str) -> int:
    """The line (from 1) of ``field`` in the ``index``-th criterion of a TOML or JSON profile's text: the
    first line naming the field after the block's start; the block's start when the field is absent."""
    lines = text.splitlines()
    blocks = [n for n, line in enumerate(lines) if line.strip() == "[[criteria]]"]
    if not blocks:  # JSON: the list's objects, each from a line opening "{" after the line naming "criteria"
        first = next((n for n, line in enumerate(lines) if '"criteria"' in line), 0)
        blocks = [n for n in range(first + 1, len(lines)) if lines[n].strip().startswith("{")]
    start = blocks[min(index, len(blocks) - 1)] if blocks else 0
    end = blocks[index + 1] if index + 1 < len(blocks) else len(lines)
    for n in range(start, end):
        key = lines[n].strip().lstrip('"')
        if key.startswith(field) and key[len(field):].lstrip('"').lstrip().startswith(("=", ":")):
            return n + 1
    return start + 1

"""The system tracks' figures: the ESASSP indicators of :mod:`radartracker.pipeline.indicators` against the
assessment's reference, each with its 95 % interval (:mod:`radartracker.assessment.stats`).

The tracks are the replay's own or a CAT062 recording's (:mod:`radartracker.assessment.systracks`); either
way :func:`radartracker.pipeline.evaluate.track_metrics` assigns them to the reference aircraft on a 2 s grid,
an aircraft being observed from its first matched plot (any radar) plus the confirmation grace
(``radartracker.pipeline.result.GRACE_S``) to its last. Consecutive grid samples of one aircraft are
correlated (a track off by 300 m stays off for a while); the aircraft are taken as independent. So:

* horizontal position RMS error √(Σ d² / N) over the assigned (aircraft, track, grid time) pairs: the
  bootstrap over the aircraft (each aircraft's Σ d² and N drawn together);
* multiple tracks, the share of the observed grid times at which an aircraft has a second track within c:
  the bootstrap over the aircraft, or where no aircraft ever had one, Clopper–Pearson's bound for m aircraft
  none of which had one;
* probability of update, updated / expected update intervals (8 s): Wilson, or Clopper–Pearson when either
  count is 5 or less, over the intervals (they are taken as independent; an aircraft whose track is lost for
  a while misses several in a row, so the interval is somewhat too narrow);
* breaks per flight hour: Garwood's exact Poisson interval of the breaks over the observed flight hours;
* false tracks (against the truth only: against ADS-B, a track on an aircraft that does not broadcast looks
  false): Garwood's exact Poisson interval of the count;
* initiation delay and latency, 95th percentiles: the order-statistic interval over the aircraft's delays
  and over the updates' latencies (the latter correlated in time too).
"""

from __future__ import annotations

import attrs
import numpy as np

from radartracker.assessment import stats
from radartracker.assessment.reference import Reference
from radartracker.assessment.stats import Estimate
from radartracker.assessment.tally import RadarTally, merge_spans
from radartracker.pipeline.evaluate import GridSpec, TrackHistory, track_metrics
from radartracker.pipeline.result import observed_spans

SYSTEM_FIGURES = ("position_rmse_m", "probability_of_update", "breaks_per_flight_hour", "multiple_share_of_time",
                  "false_tracks", "initiation_delay_p95_s", "latency_p95_s")
REPLAY_LATENCY = ("the replay's tracks carry their plots' times and are not delivered anywhere; a CAT062 "
                  "recording captured as pcap gives it (--system-tracks)")


@attrs.frozen
class SystemAssessment:
    """The system tracks' figures, the ones not assessable and why, and where the tracks came from
    (``replay`` or the CAT062 file)."""

    source: str
    figures: dict[str, Estimate]
    not_assessable: dict[str, str]


def assess_system(histories: dict[int, TrackHistory], reference: Reference, tallies: dict[str, RadarTally],
                  source: str, latency_s: np.ndarray, no_latency: str) -> SystemAssessment:
    """The figures of the module docstring for the tracks ``histories`` (from ``source``); ``latency_s``: each
    update's latency, or empty with ``no_latency`` the reason."""
    spans: dict[str, tuple[float, float]] = {}
    for t in tallies.values():  # each aircraft's first and last matched plot, over every radar
        spans = merge_spans(spans, t.spans)
    spans = dict(sorted(spans.items()))
    observed = observed_spans(spans)
    missing = {}
    if reference.kind != "truth":
        missing["false_tracks"] = "against ADS-B, a track on an aircraft that does not broadcast looks false"
    if len(latency_s):
        figures = {"latency_p95_s": stats.quantile(latency_s, 0.95)}
    else:
        figures, missing["latency_p95_s"] = {}, no_latency
    if not observed or not histories:
        return SystemAssessment(source, figures, missing | {k: "no aircraft observed or no system track" for k in
                                                            SYSTEM_FIGURES if k not in missing and k not in figures})
    grid = GridSpec(min(lo for lo, _ in observed.values()), max(hi for _, hi in observed.values()), 2.0)
    m = track_metrics(histories, reference.paths(), observed, grid, first_seen={k: lo for k, (lo, _) in spans.items()},
                      samples=True)
    s, q = m["samples"], m["indicators"]
    figures |= {
        "position_rmse_m": stats.bootstrap_ratio(s["sq_sum_m2"], s["pairs"], root=True),
        "probability_of_update": stats.proportion(int(s["updated"].sum()), int(s["expected"].sum())),
        "breaks_per_flight_hour": stats.rate(m["breaks"], q["flight_hours"], n=len(observed)),
        "multiple_share_of_time": stats.share_of_units(s["multiple"], s["observed"]),
        "initiation_delay_p95_s": stats.quantile(s["delays_s"], 0.95),
    }
    if "false_tracks" not in missing:
        figures["false_tracks"] = stats.rate(m["false_tracks"], 1.0, n=m["confirmed_tracks"])
    return SystemAssessment(source, {k: figures[k] for k in SYSTEM_FIGURES if k in figures}, missing)

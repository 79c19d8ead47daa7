"""The assessment of a scenario: every radar's figures and the system tracks' indicators, judged by a profile.

1. The reference (:func:`radartracker.assessment.reference.build_reference`): truth, else validated ADS-B and,
   when asked (``ReferenceConfig.reconstruct``), after the replay the reconstruction of the other aircraft with
   its bias estimates removed (:func:`~radartracker.assessment.reference.add_reconstructed`).
2. The replay the project already has (:func:`radartracker.pipeline.run.run`): its joint bias estimator
   gives each radar's Δr̂, Δθ̂ with their σ, and its coupling graph their observability; its tracks are the
   system tracks, unless a CAT062 recording's are given (``system_tracks``:
   :mod:`radartracker.assessment.systracks`, read and checked before the replay).
3. Each radar's plots matched to the reference (:mod:`radartracker.assessment.matching`) a time slice at a
   time, in this process or on Dask (:mod:`radartracker.assessment.slices`), the slices' sums added
   (:mod:`radartracker.assessment.tally`), and its figures made from them (:mod:`radartracker.assessment.radar`).
4. The system tracks against the same reference: the ESASSP indicators of
   :func:`radartracker.pipeline.evaluate.track_metrics` (:mod:`radartracker.pipeline.indicators`), an
   aircraft being observed from its first matched plot plus the confirmation grace to its last, each with
   its 95 % interval (:mod:`radartracker.assessment.system`).
5. Every figure judged by the profile's criteria (:meth:`Criterion.judge`).
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import attrs
import numpy as np

from radartracker.assessment import stats
from radartracker.assessment.grouping import plot_groups
from radartracker.assessment.matching import MatchConfig
from radartracker.assessment.profile import INDICATORS, Profile
from radartracker.assessment.radar import RadarAssessment, RadarConfig, assess_radar
from radartracker.assessment.reference import (Reference, ReferenceConfig, add_reconstructed, build_reference,
                                               reconstructor)
from radartracker.assessment.slices import SliceConfig, tally_radars
from radartracker.assessment.stats import Estimate
from radartracker.assessment.system import REPLAY_LATENCY, assess_system
from radartracker.assessment.systracks import SystemTrackConfig, read_system_tracks, within
from radartracker.assessment.tally import RadarTally
from radartracker.cluster import dask_client
from radartracker.io.tables import PlotTable, ScenarioData
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.result import RunResult, strict
from radartracker.pipeline.run import run


@attrs.frozen
class AssessmentConfig:
    """The settings of an assessment: the replay's, the reference's, the gate's, the radar figures', how the
    work is split into time slices and where it runs, and how a CAT062 recording's updates become tracks."""

    run: RunConfig = attrs.field(factory=RunConfig)
    reference: ReferenceConfig = attrs.field(factory=ReferenceConfig)
    match: MatchConfig = attrs.field(factory=MatchConfig)
    radar: RadarConfig = attrs.field(factory=RadarConfig)
    slices: SliceConfig = attrs.field(factory=SliceConfig)
    system: SystemTrackConfig = attrs.field(factory=SystemTrackConfig)


@attrs.define
class Assessment:
    """What :func:`assess` found: per radar, the system tracks' figures, the profile and the replay it used;
    where the system tracks came from (``replay`` or a CAT062 file) and their figures that are not assessable;
    the aircraft a reconstruction did not give a reference, and why (``reference_left_out``)."""

    scenario: str
    reference: str
    profile: Profile
    radars: list[RadarAssessment]
    system: dict[str, Estimate]
    result: RunResult
    system_source: str = "replay"
    system_not_assessable: dict[str, str] = attrs.field(factory=dict)
    reference_left_out: dict[str, str] = attrs.field(factory=dict)

    def verdicts(self) -> list[dict]:
        """One row per (radar or ``system``, criterion that applies): the figure, its interval, the rule, the
        verdict and the standard."""
        rows = []
        subjects = [(r.radar, r.kind, r.figures) for r in self.radars] + [("system", "system", self.system)]
        for name, kind, figures in subjects:
            for c in self.profile.for_kind(kind):
                e = figures.get(c.indicator, stats.missing(""))
                rows.append({"radar": name, "indicator": c.indicator, "value": e.value, "ci_low": e.low,
                             "ci_high": e.high, "rule": c.text(), "verdict": c.judge(e), "standard": c.standard,
                             "note": c.note})
        return rows

    def indicator_rows(self) -> list[dict]:
        """Every figure of every radar and of the system tracks, one row each (``indicators.csv``)."""
        rows = []
        for r in self.radars:
            for name, e in r.figures.items():
                rows.append({"radar": r.radar, "indicator": name, **e.as_dict(), "reference": self.reference,
                             "note": ""})
            for name, why in r.not_assessable.items():
                rows.append({"radar": r.radar, "indicator": name, **stats.missing("").as_dict(),
                             "reference": self.reference, "note": f"not assessable: {why}"})
        note = f"ESASSP indicators of radartracker.pipeline.indicators; tracks: {self.system_source}"
        for name, e in self.system.items():
            rows.append({"radar": "system", "indicator": name, **e.as_dict(), "reference": self.reference,
                         "note": note})
        for name, why in self.system_not_assessable.items():
            rows.append({"radar": "system", "indicator": name, **stats.missing("").as_dict(),
                         "reference": self.reference, "note": f"not assessable: {why}"})
        return rows

    def summary(self) -> dict:
        """``assessment.json``: strict JSON (NaN as null)."""
        verdicts = self.verdicts()
        return strict({
            "scenario": self.scenario, "reference": self.reference, "reference_left_out": self.reference_left_out,
            "estimator": self.result.estimator_name,
            "profile": {"name": self.profile.name, "source": self.profile.source},
            "confidence_level": stats.LEVEL,
            "units": {k: u for k, (_, u) in INDICATORS.items()},
            "radars": {r.radar: {"kind": r.kind, "observability": r.observability, "components": r.components,
                                 "figures": {k: e.as_dict() for k, e in r.figures.items()},
                                 "not_assessable": r.not_assessable, "coverage": r.coverage,
                                 "verdicts": {v["indicator"]: v["verdict"] for v in verdicts if v["radar"] == r.radar}}
                       for r in self.radars},
            "system": {"source": self.system_source,
                       "figures": {k: e.as_dict() for k, e in self.system.items()},
                       "not_assessable": self.system_not_assessable,
                       "verdicts": {v["indicator"]: v["verdict"] for v in verdicts if v["radar"] == "system"}},
            "verdict_counts": dict(Counter(v["verdict"] for v in verdicts)),
        })


def assess(data: ScenarioData, profile: Profile, config: AssessmentConfig | None = None, *,
           progress: bool = True, system_tracks: Path | str | None = None) -> Assessment:
    """The assessment of ``data`` (module docstring), its plots matched and summed a time slice at a time
    (:mod:`radartracker.assessment.slices`: in this process, or on Dask by ``config.slices``); the system tracks
    scored are those of the CAT062 recording ``system_tracks`` if given, else the replay's."""
    config = config or AssessmentConfig()
    reference = build_reference(data, config.reference)
    if config.reference.reconstruct:
        reconstructor(config.reference)  # an unknown plugin is refused before the replay
    recorded = None
    if system_tracks is not None:  # a bad file is refused before the replay
        start, stop = float(np.min(data.plots.time, initial=np.inf)), float(np.max(data.plots.time, initial=-np.inf))
        recorded = read_system_tracks(system_tracks, reference.plane, config.system,
                                      start if math.isfinite(start) else 0.0)
        within(recorded, start, stop)
    result = run(data, config.run, progress=progress)
    biases = {r.id: (result.final_biases[r.id].range_m, result.final_biases[r.id].azimuth_rad) for r in data.radars}
    with dask_client(config.slices.workers, config.slices.scheduler, quiet=not progress) as client:
        if config.reference.reconstruct and reference.kind != "truth":  # its flights on the slices' cluster
            estimates = {rid: (np.asarray(b.bias, float)[:2], np.asarray(b.cov, float)[:2, :2])
                         for rid, b in result.final_biases.items()}
            groups = plot_groups(data, reference, result.histories(), biases, config.match)
            reference = add_reconstructed(reference, data, estimates, config.reference, progress,
                                          None if client is None else client.get_executor(), groups)
        tallies = tally_radars(data, reference, biases, config.match, config.radar.mode_c_tolerance_ft,
                               config.slices, progress=progress, client=client)
    codes = reference_codes(reference, tallies)
    observability = result.observability["radars"]
    radars = [assess_radar(radar, tallies.get(radar.id, RadarTally()), time_stamps(data.plots, radar.id),
                           result.final_biases[radar.id], observability.get(radar.id, {}), codes,
                           reference.kind, config.radar)
              for radar in data.radars]
    if recorded is None:
        system = assess_system(result.histories(), reference, tallies, "replay", np.zeros(0), REPLAY_LATENCY)
    else:
        system = assess_system(recorded.histories, reference, tallies, recorded.source, recorded.latency_s,
                               recorded.no_latency)
    return Assessment(data.name, reference.kind, profile, radars, system.figures, result, system.source,
                      system.not_assessable, reference.left_out)


def time_stamps(plots: PlotTable, radar: str) -> tuple[int, np.ndarray]:
    """The plots of ``radar`` out of time order in the file, and each one's lateness (delivery − time stamp, s;
    NaN where the recording does not say when it was delivered)."""
    mine = plots.radar == radar
    return out_of_order(plots.time[mine]), plots.received[mine] - plots.time[mine]


def out_of_order(t: np.ndarray) -> int:
    """The plots stamped earlier than a plot before them in the file (``t``: one radar's, in file order)."""
    return int((t[1:] < np.maximum.accumulate(t)[:-1]).sum()) if len(t) > 1 else 0


def reference_codes(reference: Reference, tallies: dict[str, RadarTally]) -> dict[str, str]:
    """Each reference aircraft's Mode 3/A code: the scenario's aircraft list's, else the code most of its
    matched plots (all radars) carry."""
    votes: dict[str, Counter] = {}
    for t in tallies.values():
        for (key, code), n in t.mode_3a.items():
            if code is not None:
                votes.setdefault(key, Counter())[code] += n
    out = {k: v.most_common(1)[0][0] for k, v in votes.items()}
    out.update({k: t.mode_3a for k, t in reference.tracks.items() if t.mode_3a is not None})
    return out

"""The public plugin API: the one module a plugin imports (docs/plugins.md, docs/api.md).

Estimator plugins implement :class:`Estimator`; motion-model plugins implement :class:`TrackFilter`;
a plugin may add a CLI command (entry-point group ``radartracker.commands``). Everything a plugin
needs from the core is re-exported here; if something is missing, this module grows — plugins never
reach into the core's internals.

Importing this module costs nothing: each name but the errors is imported from the core on first use
(:func:`lazy_exports`), so that a plugin module that registers a CLI command can import it at its top
and ``radartracker --help`` still starts without numpy, numba or scipy. The block under
``TYPE_CHECKING`` is what type checkers and editors read; :data:`_EXPORTS` is what runs (a test keeps
the two equal).
"""

from typing import TYPE_CHECKING

from radartracker.errors import (ConfigurationError, FormatError, GeometryError, InputError, NumericalError, PluginError,
                                 RadarTrackerError)
from radartracker.lazy import lazy_exports

if TYPE_CHECKING:
    from radartracker.cluster import dask_client
    from radartracker.compiled import kernel
    from radartracker.domain import Aircraft, AdsbReport, BiasState, Plot, Radar, nacp_sigma_m
    from radartracker.estimation.base import (AircraftEstimate, Estimator, EstimatorConfig, Innovation,
                                              PlaneMeasurement, require_new_radar, validated_prior)
    from radartracker.estimation.bound import ComponentBound
    from radartracker.estimation.kalman import SingularInnovation, correct, gain, nis, symmetrize
    from radartracker.estimation.measurement import convert_plots, fill_altitudes, plot_keys
    from radartracker.estimation.motion import MotionModel
    from radartracker.estimation.screening import bias_correct_into, position_d2
    from radartracker.estimation.sensor import BiasComponent, EXTRA_PRIOR_SD, SensorModel
    from radartracker.estimation.state import StateCheck
    from radartracker.geometry.kinematics import propagate
    from radartracker.geometry.plane import RadarFrame, SystemPlane
    from radartracker.io.atomic import (atomic_open, atomic_path, prepare_output_folder, removed_if_failed,
                                        replace_outputs, write_text)
    from radartracker.io.csvblocks import read_text
    from radartracker.io.recording import TrackPoints, read_new4, write_plt
    from radartracker.io.scenario import read_radars, read_scenario
    from radartracker.io.tables import ScenarioData
    from radartracker.simulation.simulator import KinematicTrajectory, Leg, SimAircraft, SimRadar, Simulator
    from radartracker.tracking.association import (ALTITUDE_GATE, AltitudeTrack, altitude_d2, assign, assign_tiers,
                                                    candidate_pairs, gate_costs)
    from radartracker.tracking.associators import (NEW_TRACK, REFUSED, Association, AssociationSettings, Associator,
                                                   RadarPlots)
    from radartracker.tracking.filters import MotionConfig, TrackFilter
    from radartracker.tracking.frame import Prediction
    from radartracker.tracking.track import Track

_EXPORTS = {
    "radartracker.cluster": ("dask_client",),
    "radartracker.compiled": ("kernel",),
    "radartracker.domain": ("Aircraft", "AdsbReport", "BiasState", "Plot", "Radar", "nacp_sigma_m"),
    "radartracker.estimation.base": ("AircraftEstimate", "Estimator", "EstimatorConfig", "Innovation",
                                     "PlaneMeasurement", "require_new_radar", "validated_prior"),
    "radartracker.estimation.bound": ("ComponentBound",),
    "radartracker.estimation.kalman": ("SingularInnovation", "correct", "gain", "nis", "symmetrize"),
    "radartracker.estimation.measurement": ("convert_plots", "fill_altitudes", "plot_keys"),
    "radartracker.estimation.motion": ("MotionModel",),
    "radartracker.estimation.screening": ("bias_correct_into", "position_d2"),
    "radartracker.estimation.sensor": ("BiasComponent", "EXTRA_PRIOR_SD", "SensorModel"),
    "radartracker.estimation.state": ("StateCheck",),
    "radartracker.geometry.kinematics": ("propagate",),
    "radartracker.geometry.plane": ("RadarFrame", "SystemPlane"),
    "radartracker.io.atomic": ("atomic_open", "atomic_path", "prepare_output_folder", "removed_if_failed",
                               "replace_outputs", "write_text"),
    "radartracker.io.csvblocks": ("read_text",),
    "radartracker.io.recording": ("TrackPoints", "read_new4", "write_plt"),
    "radartracker.io.scenario": ("read_radars", "read_scenario"),
    "radartracker.io.tables": ("ScenarioData",),
    "radartracker.simulation.simulator": ("KinematicTrajectory", "Leg", "SimAircraft", "SimRadar", "Simulator"),
    "radartracker.tracking.association": ("ALTITUDE_GATE", "AltitudeTrack", "altitude_d2", "assign", "assign_tiers",
                                          "candidate_pairs", "gate_costs"),
    "radartracker.tracking.associators": ("NEW_TRACK", "REFUSED", "Association", "AssociationSettings", "Associator",
                                          "RadarPlots"),
    "radartracker.tracking.filters": ("MotionConfig", "TrackFilter"),
    "radartracker.tracking.frame": ("Prediction",),
    "radartracker.tracking.track": ("Track",),
}

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = sorted([
    "ConfigurationError", "FormatError", "GeometryError", "InputError", "NumericalError", "PluginError",
    "RadarTrackerError", "lazy_exports", *(name for names in _EXPORTS.values() for name in names),
])

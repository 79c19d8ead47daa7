"""The public plugin API: the one module a plugin imports (docs/plugins.md, docs/api.md).

Estimator plugins implement :class:`Estimator`; motion-model plugins implement :class:`TrackFilter`;
a plugin may add a CLI command (entry-point group ``radartracker.commands``). Everything a plugin
needs from the core is re-exported here; if something is missing, this module grows — plugins never
reach into the core's internals.
"""

from radartracker.compiled import kernel
from radartracker.domain import Aircraft, AdsbReport, BiasState, Plot, Radar, nacp_sigma_m
from radartracker.errors import (ConfigurationError, FormatError, GeometryError, InputError, NumericalError, PluginError,
                                 RadarTrackerError)
from radartracker.estimation.base import (AircraftEstimate, Estimator, EstimatorConfig, Innovation, PlaneMeasurement,
                                          validated_prior)
from radartracker.estimation.kalman import SingularInnovation, correct, gain, nis, symmetrize
from radartracker.estimation.measurement import convert_plots, fill_altitudes, plot_keys
from radartracker.estimation.motion import MotionModel
from radartracker.estimation.screening import bias_correct_into, position_d2
from radartracker.estimation.state import StateCheck
from radartracker.geometry.kinematics import propagate
from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.io.atomic import atomic_open, atomic_path, prepare_output_folder, replace_outputs, write_text
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

__all__ = [
    "AdsbReport", "Aircraft", "AircraftEstimate", "BiasState", "ConfigurationError", "Estimator", "EstimatorConfig",
    "FormatError", "GeometryError", "Innovation", "InputError", "MotionConfig", "MotionModel", "NumericalError",
    "PlaneMeasurement", "Plot", "PluginError", "Radar", "RadarFrame", "RadarTrackerError", "ScenarioData",
    "SimAircraft", "SimRadar", "Simulator", "SingularInnovation", "SystemPlane", "TrackFilter", "TrackPoints",
    "convert_plots", "correct", "fill_altitudes", "gain", "nacp_sigma_m", "nis", "plot_keys", "propagate",
    "read_new4", "read_radars", "read_scenario", "symmetrize", "validated_prior", "write_plt",
    "bias_correct_into", "position_d2",
    "atomic_open", "atomic_path", "prepare_output_folder", "write_text", "replace_outputs", "read_text",
    "KinematicTrajectory", "Leg",
    "ALTITUDE_GATE", "AltitudeTrack", "Association", "AssociationSettings", "Associator", "NEW_TRACK", "Prediction",
    "REFUSED", "RadarPlots", "Track", "altitude_d2", "assign", "assign_tiers", "candidate_pairs", "gate_costs",
    "StateCheck", "kernel",
]

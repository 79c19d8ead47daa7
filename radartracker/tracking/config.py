"""The TrackManager's settings (:class:`ManagerConfig`) and the choice of its default plugins."""

from __future__ import annotations

import attrs

from radartracker.estimation.base import EstimatorConfig
from radartracker.estimation.motion import MotionModel
from radartracker.estimation.screening import ScreeningConfig
from radartracker.clock import ClockConfig
from radartracker.tracking.filters import MotionConfig
from radartracker.tracking.height import HeightConfig

@attrs.frozen
class ManagerConfig:
    """Settings of the TrackManager, stage by stage (docs/tracking.md says what each stage does).

    Admission: ``reorder_window_s``, ``reorder_capacity``, ``clock``. Frames: ``frame_s``. Association:
    ``associator`` (a ``radartracker.associators`` plugin), ``gate`` (χ²₂ 99.9 %), ``search_radius_m``,
    ``new_track_exclusion`` (χ²₂ 1 − 10⁻⁶: no tentative track this close to a confirmed one),
    ``primary_altitude_m`` and its spread ``primary_altitude_sd_m`` (the height a plot without Mode C is
    converted at) and ``height`` (the height of tracks without altitude, estimated from the slant ranges:
    :mod:`radartracker.tracking.height`). Life cycle: ``confirm_m`` of ``confirm_n``, ``delete_after_s``, ``max_tracks``,
    ``merge_distance_m`` (tracks on one aircraft: :mod:`radartracker.tracking.duplicates`).
    Screening: ``screening``.
    Plugins: ``estimator`` with ``estimator_config`` / ``estimator_options``, ``motion_model`` with
    ``motion`` / ``motion_options``.
    """

    estimator: str = "coupled-sparse"  # exact, and its cost per plot does not grow with the traffic
    # aircraft turn: the estimator's CV model needs process noise, or it explains a turn by biases
    estimator_config: EstimatorConfig = attrs.field(factory=lambda: EstimatorConfig(motion=MotionModel(5.0)))
    motion_model: str = "imm"  # chosen by measurement: docs/tracking.md, "Association of primary-only traffic"
    # the motion model's settings; None: its config_class() defaults, with q from estimator_config (motion_q)
    motion: MotionConfig | None = None
    motion_options: dict[str, str] = attrs.field(factory=dict)  # KEY=VALUE settings applied on top of ``motion``
    estimator_options: dict[str, str] = attrs.field(factory=dict)  # KEY=VALUE options of the estimator plugin
    associator: str = "gnn"
    gate: float = 13.82
    confirm_m: int = 3
    confirm_n: int = 5
    delete_after_s: float = 40.0
    reorder_window_s: float = 2.0
    # the most inputs the reordering window holds: 20 s of national traffic (5,000 inputs/s), ten times
    # the replay's window; only a flood sharing one time stamp fills it (TrackManager._overfull: the
    # flood's newest input is dropped, or the oldest leaves early once the stream has moved on)
    reorder_capacity: int = attrs.field(default=100_000, validator=attrs.validators.ge(1))
    # the most live tracks: five times national traffic (2,000 aircraft); a measurement that would start one
    # more is counted *_track_capacity (a flood of plausible plots cannot grow the memory without bound)
    max_tracks: int = attrs.field(default=10_000, validator=attrs.validators.ge(1))
    frame_s: float = 0.5
    primary_altitude_m: float = 6000.0
    primary_altitude_sd_m: float = 3500.0
    height: HeightConfig = attrs.field(factory=HeightConfig)
    search_radius_m: float = 25_000.0
    new_track_exclusion: float = 27.63
    # a lost (coasting) track this close to a track being confirmed, with a velocity that agrees, is the
    # same aircraft: the older number takes over (tracking/duplicates.py)
    merge_distance_m: float = attrs.field(default=2500.0, validator=attrs.validators.gt(0.0))
    screening: ScreeningConfig = attrs.field(factory=ScreeningConfig)
    clock: ClockConfig = attrs.field(factory=ClockConfig)


"""Every setting of a run, as one value that ``config.json`` records and reads back.

:class:`RunConfig` is what a user chooses (``None`` = "the default"); :func:`resolve` turns it into
the *effective* configuration for one scenario — association, estimator and motion model named,
every default filled in — which the run uses and writes to ``config.json``. Reading that file back
(:func:`read_config`) and running again reproduces the run exactly (docs/formats.md).

Numbers are validated when the configuration is built: a non-finite or out-of-range value raises
:class:`ConfigurationError` naming the option.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import attrs

from radartracker.errors import ConfigurationError
from radartracker.estimation.base import EstimatorConfig
from radartracker.estimation.screening import ScreeningConfig
from radartracker.fusion.center import FusionConfig
from radartracker.io.tables import ScenarioData
from radartracker.registry import FilterFactory, load_motion_model, make_filter_factory, option_fields
from radartracker.clock import ClockConfig
from radartracker.settings import ARCHITECTURES, ASSOCIATIONS, DEFAULT_Q, check_number
from radartracker.tracking.config import ManagerConfig

CONFIG_FORMAT = "radartracker-run-config"
CONFIG_VERSION = 2


def _str_dict(value: Mapping[str, Any] | None) -> dict[str, str]:
    return {str(k): str(v) for k, v in (value or {}).items()}


def _q(inst: Any, attr: attrs.Attribute, value: float) -> None:
    check_number("--q", value, lo=0.0)


def _association(inst: Any, attr: attrs.Attribute, value: str) -> None:
    if value not in ASSOCIATIONS:
        raise ConfigurationError(f"association: {value!r} is not one of {', '.join(ASSOCIATIONS)}")


def _architecture(inst: Any, attr: attrs.Attribute, value: str) -> None:
    if value not in ARCHITECTURES:
        raise ConfigurationError(f"--architecture: {value!r} is not one of {', '.join(ARCHITECTURES)}")


def _optional_positive(option: str):
    def check(inst: Any, attr: attrs.Attribute, value: float | None) -> None:
        if value is not None:
            check_number(option, value, lo=0.0, lo_open=True)
    return check


def _values(obj: Any, exclude: tuple[str, ...] = ()) -> dict[str, Any]:
    """The settings of an attrs config as plain values: numbers, text, flags, and nested configs as dicts."""
    out: dict[str, Any] = {}
    for f in attrs.fields(type(obj)):
        v = getattr(obj, f.name)
        if f.name in exclude or not f.init:
            continue
        if isinstance(v, (bool, int, float, str)):
            out[f.name] = v
        elif attrs.has(type(v)) and (nested := _values(v)):
            out[f.name] = nested
    return out


def _typed_overrides(what: str, defaults: dict[str, Any], given: Mapping[str, Any]) -> dict[str, Any]:
    """``given`` checked against ``defaults``: known names, the default's type, numbers finite and ≥ 0."""
    out: dict[str, Any] = {}
    for name, value in given.items():
        if name not in defaults:
            raise ConfigurationError(f"{what}: unknown setting {name!r}; known: {', '.join(sorted(defaults))}")
        d = defaults[name]
        if isinstance(d, dict):
            if not isinstance(value, Mapping):
                raise ConfigurationError(f"{what}.{name}: expected a mapping of settings, got {value!r}")
            out[name] = _typed_overrides(f"{what}.{name}", d, value)
        elif isinstance(d, bool):
            if not isinstance(value, bool):
                raise ConfigurationError(f"{what}.{name}: expected true or false, got {value!r}")
            out[name] = value
        elif isinstance(d, str):
            out[name] = str(value)
        else:
            out[name] = check_number(f"{what}.{name}", value, lo=0.0, integer=isinstance(d, int))
    return out


def _merged(defaults: dict[str, Any], given: dict[str, Any]) -> dict[str, Any]:
    return {k: _merged(v, given.get(k, {})) if isinstance(v, dict) else given.get(k, v) for k, v in defaults.items()}


def _evolved(what: str, obj: Any, values: dict[str, Any]) -> Any:
    """``obj`` with ``values`` (nested dicts for nested configs); a refused value is a ConfigurationError."""
    changes = {k: _evolved(f"{what}.{k}", getattr(obj, k), v) if isinstance(v, dict) else v for k, v in values.items()}
    try:
        return attrs.evolve(obj, **changes)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"{what}: {exc}") from None


_FROM_RUN = ("estimator", "estimator_config", "motion_model", "motion", "motion_options", "estimator_options",
             "primary_altitude_m", "screening", "clock", "associator")  # set from the run's own settings, not from ``manager``
MANAGER_SETTINGS = _values(ManagerConfig(), exclude=_FROM_RUN)
ESTIMATOR_SETTINGS = _values(EstimatorConfig(), exclude=("motion",))
SCREENING_SETTINGS = _values(ScreeningConfig())
CLOCK_SETTINGS = _values(ClockConfig())


@attrs.frozen
class RunConfig:
    """Every setting of one run (``None``: the default, filled in by :func:`resolve`).

    ``association``: ``manager`` (the TrackManager with the associator ``associator``, default ``gnn``),
    ``labels`` (the same TrackManager with the ``labels`` associator: plots by truth label, for evaluation)
    or ``auto`` (labels when every plot carries one). ``estimator`` /
    ``motion_model``: plugin names with their ``KEY=VALUE`` options; ``associator``: the TrackManager's
    associator plugin (default ``gnn``). ``q`` (m²/s³): the aircraft
    white-acceleration density, for the estimator and the track filters alike. ``default_altitude_m``:
    the altitude assumed for a plot whose aircraft never reports one. ``bias_log_interval_s``: the
    least time between two rows of one radar in ``biases.csv``. ``estimator_config`` / ``manager``:
    overrides of :class:`EstimatorConfig` / :class:`ManagerConfig` numbers; ``screening`` / ``clock``:
    of :class:`ScreeningConfig` (innovation gates) and :class:`ClockConfig` (robust stream clock), on
    both associations. Settings of a path not taken are
    refused, never silently ignored.
    """

    association: str = attrs.field(default="auto", validator=_association)
    estimator: str | None = None
    estimator_options: dict[str, str] = attrs.field(factory=dict, converter=_str_dict)
    motion_model: str | None = None
    motion_options: dict[str, str] = attrs.field(factory=dict, converter=_str_dict)
    associator: str | None = None
    q: float = attrs.field(default=DEFAULT_Q, converter=float, validator=_q)
    default_altitude_m: float | None = attrs.field(default=None)
    bias_log_interval_s: float = attrs.field(default=1.0, validator=_optional_positive("bias_log_interval_s"))
    skip_bad: bool = False
    estimator_config: dict[str, float] = attrs.field(factory=dict)
    manager: dict[str, Any] = attrs.field(factory=dict)
    screening: dict[str, Any] = attrs.field(factory=dict)
    clock: dict[str, Any] = attrs.field(factory=dict)
    architecture: str = attrs.field(default="central", validator=_architecture)
    fusion: dict[str, float] = attrs.field(factory=dict)

    def __attrs_post_init__(self) -> None:
        if self.default_altitude_m is not None:
            check_number("default_altitude_m", self.default_altitude_m)
        _typed_overrides("estimator_config", ESTIMATOR_SETTINGS, self.estimator_config)
        _typed_overrides("manager", MANAGER_SETTINGS, self.manager)
        _typed_overrides("screening", SCREENING_SETTINGS, self.screening)
        _typed_overrides("clock", CLOCK_SETTINGS, self.clock)

    def estimator_settings(self) -> EstimatorConfig:
        """The :class:`EstimatorConfig` of this run (motion model of density ``q``)."""
        from radartracker.estimation.motion import MotionModel

        values = _typed_overrides("estimator_config", ESTIMATOR_SETTINGS, self.estimator_config)
        return _evolved("estimator_config", EstimatorConfig(motion=MotionModel(self.q)), values)

    def fusion_settings(self) -> FusionConfig:
        """The fusion centre of the distributed architecture (``fusion`` overrides of :class:`FusionConfig`)."""
        known = {f.name for f in attrs.fields(FusionConfig)}
        if unknown := sorted(set(self.fusion) - known):
            raise ConfigurationError(f"fusion: unknown setting(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
        values = {k: check_number(f"fusion.{k}", v) for k, v in self.fusion.items()}
        try:
            return FusionConfig(**values)
        except ValueError as exc:
            raise ConfigurationError(f"fusion: {exc}") from None

    def screening_settings(self) -> ScreeningConfig:
        """The innovation screening of this run (both associations)."""
        return _evolved("screening", ScreeningConfig(), _typed_overrides("screening", SCREENING_SETTINGS, self.screening))

    def clock_settings(self) -> ClockConfig:
        """The robust stream clock of this run (both associations)."""
        return _evolved("clock", ClockConfig(), _typed_overrides("clock", CLOCK_SETTINGS, self.clock))

    def manager_settings(self) -> ManagerConfig:
        """The :class:`ManagerConfig` of this run (estimator and motion model are passed as built objects)."""
        values = _typed_overrides("manager", MANAGER_SETTINGS, self.manager)
        base = ManagerConfig(estimator=self.estimator or ManagerConfig().estimator,
                             estimator_config=self.estimator_settings(),
                             motion_model=self.motion_model or ManagerConfig().motion_model,
                             associator=self.associator or ManagerConfig().associator,
                             primary_altitude_m=default_altitude() if self.default_altitude_m is None
                             else self.default_altitude_m,
                             screening=self.screening_settings(), clock=self.clock_settings())
        return _evolved("manager", base, values)

    def to_json(self) -> str:
        """``config.json``: format, version and every setting."""
        return json.dumps({"format": CONFIG_FORMAT, "version": CONFIG_VERSION, "settings": attrs.asdict(self)},
                          indent=1, allow_nan=False) + "\n"


def default_altitude() -> float:
    """The altitude assumed for plots without one, on both paths (ManagerConfig holds the value)."""
    return ManagerConfig().primary_altitude_m


def resolve(config: RunConfig, data: ScenarioData, estimator_name: str) -> RunConfig:
    """The effective configuration for ``data``: every choice named, every default written out.

    Settings of the path not taken raise :class:`ConfigurationError` (an ``--associator`` with the labelled
    association, fusion settings without the distributed architecture).
    """
    association = config.association
    if config.architecture == "distributed":  # one TrackManager per radar: never by labels
        if association == "labels":
            raise ConfigurationError("--architecture distributed tracks each radar with the TrackManager; "
                                     "it cannot associate by truth labels")
        association = "manager"
    elif config.fusion:
        raise ConfigurationError(f"fusion settings {sorted(config.fusion)} need --architecture distributed")
    if association == "auto":
        association = "labels" if data.plots.has_truth_labels else "manager"
    if association == "labels":
        if config.associator not in (None, "labels"):
            raise ConfigurationError(f"--associator {config.associator}: --association labels associates by "
                                     "truth label; use --association manager")
        associator = "labels"
    else:
        associator = config.associator or ManagerConfig().associator
    manager = _merged(MANAGER_SETTINGS, _typed_overrides("manager", MANAGER_SETTINGS, config.manager))
    motion = config.motion_model or ManagerConfig().motion_model
    return attrs.evolve(
        config, association=association, estimator=estimator_name, motion_model=motion, associator=associator,
        manager=manager, default_altitude_m=default_altitude() if config.default_altitude_m is None
        else float(config.default_altitude_m),
        estimator_config=_merged(ESTIMATOR_SETTINGS, _typed_overrides("estimator_config", ESTIMATOR_SETTINGS,
                                                                      config.estimator_config)),
        screening=_merged(SCREENING_SETTINGS, _typed_overrides("screening", SCREENING_SETTINGS, config.screening)),
        clock=_merged(CLOCK_SETTINGS, _typed_overrides("clock", CLOCK_SETTINGS, config.clock)),
        fusion=attrs.asdict(config.fusion_settings()) if config.architecture == "distributed" else {})


def read_config(path: Path | str) -> RunConfig:
    """A :class:`RunConfig` from a ``config.json`` written by an earlier run."""
    from radartracker.io.limits import read_json

    path = Path(path)
    doc = read_json(path)  # bounded: depth, number sizes, file size; errors name the file and line
    if not isinstance(doc, dict) or doc.get("format") != CONFIG_FORMAT:
        raise ConfigurationError(f"{path}: not a radartracker run configuration (no \"format\": \"{CONFIG_FORMAT}\")")
    if doc.get("version") != CONFIG_VERSION:
        raise ConfigurationError(f"{path}: configuration version {doc.get('version')!r}; this release reads "
                                 f"{CONFIG_VERSION}")
    settings = dict(doc.get("settings") or {})
    known = {f.name for f in attrs.fields(RunConfig)}
    if unknown := sorted(set(settings) - known):
        raise ConfigurationError(f"{path}: unknown setting(s) {', '.join(unknown)}")
    try:
        return RunConfig(**settings)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"{path}: {exc}") from None


def motion_factory(cfg: RunConfig) -> FilterFactory:
    """The track-filter factory of ``cfg``: its motion model, with ``q`` set from the run unless the
    motion options set it (when the model has a ``q`` setting)."""
    cls = load_motion_model(cfg.motion_model)
    options = dict(cfg.motion_options)
    if "q" in option_fields(cls.config_class) and "q" not in options:
        options["q"] = repr(cfg.q)
    return make_filter_factory(cfg.motion_model, options)

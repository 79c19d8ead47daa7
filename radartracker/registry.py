"""Plugin discovery: estimators, reconstructors and motion models are found through
``importlib.metadata`` entry points; the built-in plugins register themselves the same way a third
party would."""

from __future__ import annotations

from collections.abc import Iterable
from importlib.metadata import entry_points
from typing import Any

from radartracker.estimation.base import Estimator, EstimatorConfig
from radartracker.tracking.filters import TrackFilter

ESTIMATOR_GROUP = "radartracker.estimators"
RECONSTRUCTOR_GROUP = "radartracker.reconstructors"
MOTION_GROUP = "radartracker.motion_models"

def _group(group: str) -> dict[str, Any]:
    return {ep.name: ep for ep in entry_points(group=group)}


def _load(group: str, name: str, what: str, base: type | None = None) -> Any:
    """Load entry point ``name`` of ``group``; a clear error lists what is installed."""
    eps = _group(group)
    if name not in eps:
        known = ", ".join(sorted(eps)) or "none"
        raise ValueError(f"unknown {what} {name!r}; installed: {known}")
    obj = eps[name].load()
    if base is not None and not (isinstance(obj, type) and issubclass(obj, base)):
        raise TypeError(f"entry point {name!r} does not name a {base.__name__} subclass: {obj!r}")
    return obj


def available_estimators() -> list[str]:
    """Names of the installed estimator plugins."""
    return sorted(_group(ESTIMATOR_GROUP))


def load_estimator(name: str) -> type[Estimator]:
    """The estimator class registered under ``name``."""
    return _load(ESTIMATOR_GROUP, name, "estimator", Estimator)


def available_reconstructors() -> list[str]:
    """Names of the installed reconstructor plugins."""
    return sorted(_group(RECONSTRUCTOR_GROUP))


def load_reconstructor(name: str) -> Any:
    """The reconstructor registered under ``name``."""
    return _load(RECONSTRUCTOR_GROUP, name, "reconstructor")


def available_motion_models() -> list[str]:
    """Names of the installed track motion-model plugins."""
    return sorted(_group(MOTION_GROUP))


def load_motion_model(name: str) -> type[TrackFilter]:
    """The track-filter class registered under ``name``."""
    return _load(MOTION_GROUP, name, "motion model", TrackFilter)


def make_estimator(name: str, config: EstimatorConfig | None, radars: Iterable[str]) -> Estimator:
    """Instantiate estimator ``name`` and register ``radars`` with it."""
    est = load_estimator(name)(config)
    for r in radars:
        est.add_radar(r)
    return est

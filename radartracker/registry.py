"""Plugin discovery and construction: estimators, reconstructors and motion models are found through
``importlib.metadata`` entry points (the built-in plugins register themselves the same way a third
party would) and built with their typed options.

A plugin declares its options as an attrs class — an estimator in ``options_class``, a motion model
in ``config_class`` (a :class:`MotionConfig`) — and :func:`parse_options` turns ``KEY=VALUE`` strings
into it from the fields' annotations: ``float``, ``int``, ``bool`` (true/false/yes/no/on/off/1/0),
``str``, ``X | None`` (``none`` for None), ``tuple[float, ...]`` (``1,2,3``) and
``tuple[tuple[float, ...], ...]`` (rows separated by ``;``: ``0.9,0.1;0.2,0.8``).
"""

from __future__ import annotations

import math
import os
import types
import typing
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import attrs

from radartracker.domain import Radar
from radartracker.entrypoints import installed
from radartracker.errors import ConfigurationError, SnapshotError
from radartracker.estimation.base import Estimator, EstimatorConfig
from radartracker.tracking.associators import AssociationSettings, Associator
from radartracker.tracking.config import ManagerConfig
from radartracker.tracking.events import TrackEvent
from radartracker.tracking.filters import MotionConfig, TrackFilter
from radartracker.tracking.manager import TrackManager
from radartracker.tracking.schema import read_manager, restore_state

ESTIMATOR_GROUP = "radartracker.estimators"
RECONSTRUCTOR_GROUP = "radartracker.reconstructors"
MOTION_GROUP = "radartracker.motion_models"
ASSOCIATOR_GROUP = "radartracker.associators"
# exact estimators first, the scalable one before the dense one (docs/estimators.md); decoupled is a last resort
PREFERRED_ESTIMATORS = ("coupled-sparse", "coupled", "blom", "decoupled")


def _load(group: str, name: str, what: str, base: type | None = None) -> Any:
    """Load entry point ``name`` of ``group``; a clear error lists what is installed."""
    eps = installed(group)
    if name not in eps:
        known = ", ".join(sorted(eps)) or "none"
        raise ConfigurationError(f"unknown {what} {name!r}; installed: {known}")
    obj = eps[name].load()
    if base is not None and not (isinstance(obj, type) and issubclass(obj, base)):
        raise ConfigurationError(f"entry point {name!r} does not name a {base.__name__} subclass: {obj!r}")
    return obj


def available_estimators() -> list[str]:
    """Names of the installed estimator plugins."""
    return sorted(installed(ESTIMATOR_GROUP))


def load_estimator(name: str) -> type[Estimator]:
    """The estimator class registered under ``name``."""
    return _load(ESTIMATOR_GROUP, name, "estimator", Estimator)


def default_estimator() -> str:
    """The best installed estimator plugin: the first of ``PREFERRED_ESTIMATORS`` that is installed."""
    names = available_estimators()
    return next((n for n in PREFERRED_ESTIMATORS if n in names), names[0] if names else PREFERRED_ESTIMATORS[0])


def available_associators() -> list[str]:
    """Names of the installed associator plugins."""
    return sorted(installed(ASSOCIATOR_GROUP))


def load_associator(name: str) -> type[Associator]:
    """The associator class registered under ``name``."""
    return _load(ASSOCIATOR_GROUP, name, "associator", Associator)


def available_reconstructors() -> list[str]:
    """Names of the installed reconstructor plugins."""
    return sorted(installed(RECONSTRUCTOR_GROUP))


def load_reconstructor(name: str) -> Any:
    """The reconstructor registered under ``name``."""
    return _load(RECONSTRUCTOR_GROUP, name, "reconstructor")


def available_motion_models() -> list[str]:
    """Names of the installed track motion-model plugins."""
    return sorted(installed(MOTION_GROUP))


def load_motion_model(name: str) -> type[TrackFilter]:
    """The track-filter class registered under ``name``."""
    return _load(MOTION_GROUP, name, "motion model", TrackFilter)


# --- options ----------------------------------------------------------------------------------------

def parse_key_values(items: Iterable[str], what: str = "option") -> dict[str, str]:
    """``["k=v", ...]`` (as given to ``--estimator-option``) as a dict; a later key wins."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ConfigurationError(f"{what} {item!r}: expected KEY=VALUE")
        out[key.strip()] = value.strip()
    return out


def parse_value(text: str, tp: Any) -> Any:
    """``text`` converted to the annotation ``tp`` (see the module docstring); TypeError if unsupported."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if type(None) in args and text.strip().lower() in ("none", "null", ""):
            return None
        rest = [a for a in args if a is not type(None)]
        if len(rest) != 1:
            raise TypeError(f"cannot read {tp} from text")
        return parse_value(text, rest[0])
    if tp is bool:
        low = text.strip().lower()
        if low in ("true", "yes", "on", "1"):
            return True
        if low in ("false", "no", "off", "0"):
            return False
        raise ValueError(f"expected true or false, got {text!r}")
    if tp is float:
        value = float(text.strip())
        if not math.isfinite(value):
            raise ValueError(f"{text!r} is not finite")
        return value
    if tp in (int, str):
        return int(text.strip()) if tp is int else text
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
        sep = ";" if typing.get_origin(args[0]) is tuple else ","
        return tuple(parse_value(part, args[0]) for part in text.split(sep) if part.strip())
    raise TypeError(f"cannot read {tp} from text")


def option_fields(cls: type) -> dict[str, attrs.Attribute]:
    """The settable options of an attrs options class, by name (types resolved)."""
    try:
        attrs.resolve_types(cls)
    except Exception as exc:  # an annotation naming something its module does not define
        raise ConfigurationError(f"options class {cls.__qualname__}: annotations cannot be resolved: {exc}") from None
    return {a.name: a for a in attrs.fields(cls) if a.init}


def parse_options(owner: str, cls: type, options: Mapping[str, str] | None, base: Any = None) -> Any:
    """An instance of the options class ``cls`` from ``KEY=VALUE`` strings, on top of ``base``
    (an instance of ``cls``; default its defaults). ``owner`` names the plugin in errors: an unknown
    key or a bad value is a :class:`ConfigurationError` naming the plugin, the key and the valid keys."""
    fields = option_fields(cls)
    valid = ", ".join(sorted(fields)) or "none"
    values: dict[str, Any] = {}
    for key, text in (options or {}).items():
        if key not in fields:
            raise ConfigurationError(f"{owner}: unknown option {key!r}; valid options: {valid}")
        try:
            values[key] = parse_value(str(text), fields[key].type)
        except (TypeError, ValueError) as exc:
            raise ConfigurationError(f"{owner}: option {key}={text!r}: {exc} (valid options: {valid})") from None
    try:
        return attrs.evolve(base, **values) if base is not None else cls(**values)
    except ConfigurationError as exc:
        raise ConfigurationError(f"{owner}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"{owner}: options {dict(options or {})}: {exc} (valid options: {valid})") from None


def describe_options(cls: type | None) -> list[tuple[str, str, Any]]:
    """(name, type, default) of each option of an options class (for listings and docs)."""
    if cls is None:
        return []
    out = []
    for name, a in option_fields(cls).items():
        default = a.default.factory() if isinstance(a.default, attrs.Factory) else a.default
        out.append((name, getattr(a.type, "__name__", None) or str(a.type), default))
    return out


# --- construction -----------------------------------------------------------------------------------

def make_estimator(spec: str | Estimator, config: EstimatorConfig | None, radars: Iterable[str],
                   options: Mapping[str, str] | None = None) -> Estimator:
    """An estimator with ``radars`` registered: plugin ``spec`` built with ``config`` and its typed
    ``options`` (``KEY=VALUE`` strings, parsed into the plugin's ``options_class``), or the instance
    ``spec`` as it is (``config`` and ``options`` do not apply to it), given each radar it lacks."""
    if isinstance(spec, Estimator):
        if options:
            raise ConfigurationError(f"estimator instance {type(spec).__name__}: options apply to a plugin "
                                     "name; set them when constructing the instance")
        est = spec
    else:
        cls = load_estimator(spec)
        owner = f"estimator {spec!r}"
        if cls.options_class is None and options:
            raise ConfigurationError(f"{owner}: unknown option {next(iter(options))!r}; this estimator takes no options")
        try:
            est = cls(config) if cls.options_class is None else cls(config, parse_options(owner, cls.options_class, options))
        except ConfigurationError:
            raise
        except ValueError as exc:  # a plugin refusing its settings
            raise ConfigurationError(f"{owner}: {exc}") from exc
    have = set(est.radars)
    for r in radars:
        if r not in have:
            est.add_radar(r)
            have.add(r)
    return est


@attrs.frozen
class FilterFactory:
    """Makes track filters: ``factory()`` is ``cls(config)``; ``factory(other)`` uses another config
    (a restored snapshot's). ``name`` and ``config`` say which plugin and which effective settings."""

    cls: type[TrackFilter]
    config: MotionConfig

    @property
    def name(self) -> str:
        return self.cls.name

    def __call__(self, config: MotionConfig | None = None) -> TrackFilter:
        return self.cls(self.config if config is None else config)


@attrs.frozen
class CallableFilterFactory:
    """A user's zero-argument filter factory behind the :class:`FilterFactory` call signature;
    the config argument is ignored (the factory's filters carry their own)."""

    make: Callable[[], TrackFilter]

    @property
    def name(self) -> str:
        return getattr(self.make, "__name__", type(self.make).__name__)

    def __call__(self, config: MotionConfig | None = None) -> TrackFilter:
        filt = self.make()
        if not isinstance(filt, TrackFilter):
            raise ConfigurationError(f"filter factory {self.name!r} returned {type(filt).__name__}, not a TrackFilter")
        return filt


def make_filter_factory(spec: str | type[TrackFilter] | Callable[[], TrackFilter],
                        options: Mapping[str, str] | None = None,
                        config: MotionConfig | None = None) -> FilterFactory | CallableFilterFactory:
    """A factory of track filters: for a plugin name or a TrackFilter class, a :class:`FilterFactory`
    with ``config`` (default: the class's ``config_class()``) updated by ``options`` (``KEY=VALUE``
    strings); any other zero-argument callable returning a TrackFilter (no options) is wrapped in a
    :class:`CallableFilterFactory`; a factory made here is returned as it is."""
    if isinstance(spec, (FilterFactory, CallableFilterFactory)) and not options and config is None:
        return spec
    if isinstance(spec, str) or (isinstance(spec, type) and issubclass(spec, TrackFilter)):
        cls = load_motion_model(spec) if isinstance(spec, str) else spec
        owner = f"motion model {spec if isinstance(spec, str) else cls.name!r}"
        if config is not None and not isinstance(config, cls.config_class):
            raise ConfigurationError(f"{owner} takes a {cls.config_class.__name__}, not a {type(config).__name__}")
        return FilterFactory(cls, parse_options(owner, cls.config_class, options, config))
    if not callable(spec):
        raise ConfigurationError(f"motion model: expected a plugin name, a TrackFilter class or a factory, got {spec!r}")
    if options or config is not None:
        raise ConfigurationError("motion model factory: options and config apply to a plugin name or class")
    return CallableFilterFactory(spec)


def make_associator(spec: str | Associator, settings: AssociationSettings | None = None) -> Associator:
    """Associator plugin ``spec`` built with ``settings``, or the instance ``spec`` as it is."""
    if isinstance(spec, Associator):
        return spec
    return load_associator(spec)(settings or AssociationSettings())


def motion_q(cfg: ManagerConfig) -> dict[str, str]:
    """``cfg.motion_options``, plus ``q`` = the estimator's process noise ``estimator_config.motion.q``
    when the motion model has a ``q`` setting that neither ``motion`` nor the options set: one aircraft
    process-noise density for the estimator and the track filters unless told otherwise."""
    options = dict(cfg.motion_options)
    if cfg.motion is None and "q" not in options and "q" in option_fields(load_motion_model(cfg.motion_model).config_class):
        options["q"] = repr(cfg.estimator_config.motion.q)
    return options


def make_manager(radars: list[Radar], reference: tuple[float, float], config: ManagerConfig | None = None,
                 on_event: Callable[[TrackEvent], None] | None = None, *, estimator: str | Estimator | None = None,
                 filter_factory: Any = None, associator: str | Associator | None = None) -> TrackManager:
    """A :class:`TrackManager` with its plugins built from ``config``'s names, or given here (an estimator
    instance is given each radar it lacks); ``on_event(event)`` is called for every event."""
    cfg = config or ManagerConfig()
    ids = [r.id for r in radars]
    est = (make_estimator(cfg.estimator, cfg.estimator_config, ids, cfg.estimator_options) if estimator is None
           else make_estimator(estimator, None, ids))
    new_filter = (make_filter_factory(cfg.motion_model, motion_q(cfg), cfg.motion) if filter_factory is None
                  else make_filter_factory(filter_factory))
    settings = AssociationSettings(cfg.gate, cfg.search_radius_m, cfg.new_track_exclusion)
    mgr = TrackManager(radars, reference, cfg, estimator=est, new_filter=new_filter,
                       associator=make_associator(cfg.associator if associator is None else associator, settings))
    if on_event is not None:
        mgr.events.subscribe(lambda event, track: on_event(event))
    return mgr


def restore_manager(path: str | os.PathLike, on_event: Callable[[TrackEvent], None] | None = None, **plugins: Any
                    ) -> TrackManager:
    """A manager continuing exactly where :meth:`TrackManager.snapshot` left off, its plugins built from the
    snapshot's configuration (or given as in :func:`make_manager`, of the classes it was made with);
    :class:`SnapshotError` naming ``path`` for anything else."""
    meta, blob = read_manager(path)
    try:
        mgr = make_manager(meta["radars"], tuple(meta["reference"]), meta["config"], on_event, **plugins)
    except Exception as exc:  # a crafted file's settings: refused, whatever they provoke (an overflow, …)
        raise SnapshotError(str(path), f"cannot restore: {type(exc).__name__}: {exc}") from None
    return restore_state(mgr, meta, blob, path)


def plugin_listing() -> str:
    """What ``radartracker estimators`` prints: every installed plugin by group, with its options."""
    lines = []
    for group, title, attr in ((ESTIMATOR_GROUP, "estimators", "options_class"),
                               (MOTION_GROUP, "motion models", "config_class"),
                               (ASSOCIATOR_GROUP, "associators", None),
                               (RECONSTRUCTOR_GROUP, "reconstructors", None)):
        lines.append(f"{title}:")
        for name, ep in sorted(installed(group).items()):
            lines.append(f"  {name:<16} {ep.value}")
            if attr is None:
                continue
            try:
                options = describe_options(getattr(ep.load(), attr, None))
            except Exception as exc:  # a broken plugin must not hide the others
                lines.append(f"      (not loadable: {type(exc).__name__}: {exc})")
                continue
            if options:
                shown = [(k, _RUN_Q if (k, attr) == ("q", "config_class") else _text(v)) for k, _, v in options]
                lines.append("      options: " + ", ".join(f"{k}={v}" for k, v in shown))
    return "\n".join(lines)


# a motion model's q as a run uses it: the estimator's (ManagerConfig), unless an option sets it
_RUN_Q = f"{ManagerConfig().estimator_config.motion.q:g} (the run's q unless set)"


def _text(value: Any) -> str:
    """A default as it would be written in KEY=VALUE."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, tuple):
        sep = ";" if value and isinstance(value[0], tuple) else ","
        return sep.join(_text(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)

"""Domain objects: radars, aircraft, plots, ADS-B reports, tracks and bias states.

Internally SI (metres, seconds, radians). Construction validates every field and raises
:class:`~radartracker.errors.InputError` (a ``RadarTrackerError`` and a ``ValueError``) naming the field
in its own units, so a bad number never turns into a silent NaN later; plots and
ADS-B reports made from columns (:func:`plots_from_columns`, :func:`plot_rows`) are checked column by
column instead. Degrees, feet and knots appear only at the I/O edges (:mod:`radartracker.io`).
"""

from __future__ import annotations

import collections
import itertools
import math
from collections.abc import Callable
from typing import Any

import attrs
import numpy as np

from radartracker.errors import InputError

TWO_PI = 2.0 * math.pi


def _finite(inst: Any, attr: attrs.Attribute, value: Any) -> None:
    if value is None:
        return
    if (isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating))
            or not math.isfinite(value)):  # True is an int to Python, not a time or a range
        raise InputError(f"{attr.name}: expected a finite number, got {value!r}")


def _positive(inst: Any, attr: attrs.Attribute, value: float) -> None:
    _finite(inst, attr, value)
    if value <= 0:
        raise InputError(f"{attr.name}: must be > 0, got {value!r}")


def _non_negative(inst: Any, attr: attrs.Attribute, value: float) -> None:
    _finite(inst, attr, value)
    if value < 0:
        raise InputError(f"{attr.name}: must be >= 0, got {value!r}")


def _latitude(inst: Any, attr: attrs.Attribute, value: float) -> None:
    _finite(inst, attr, value)
    if not -90.0 <= value <= 90.0:
        raise InputError(f"{attr.name}: latitude must be in [-90, 90] degrees, got {value!r}")


def _longitude(inst: Any, attr: attrs.Attribute, value: float) -> None:
    _finite(inst, attr, value)
    if not -180.0 <= value <= 180.0:
        raise InputError(f"{attr.name}: longitude must be in [-180, 180] degrees, got {value!r}")


def _azimuth(inst: Any, attr: attrs.Attribute, value: float) -> None:
    _finite(inst, attr, value)
    if not 0.0 <= value < TWO_PI:
        raise InputError(f"{attr.name}: azimuth must be in [0, 2π) radians, got {value!r} rad")


def _mode_s(inst: Any, attr: attrs.Attribute, value: str | None) -> None:
    if value is None:
        return
    if not isinstance(value, str) or len(value) != 6 or value.strip("0123456789abcdef"):  # a digit not hex
        raise InputError(f"{attr.name}: Mode S address must be 6 lower-case hex digits, got {value!r}")


def _mode_3a(inst: Any, attr: attrs.Attribute, value: str | None) -> None:
    if value is None:
        return
    if not isinstance(value, str) or len(value) != 4 or value.strip("01234567"):  # a digit not octal
        raise InputError(f"{attr.name}: Mode 3/A code must be 4 octal digits, got {value!r}")


def _address(inst: Any, attr: attrs.Attribute, value: str) -> None:
    if value is None:  # an aircraft's identity: never absent, unlike a plot's Mode S address
        raise InputError(f"{attr.name}: Mode S address must be 6 lower-case hex digits, got None")
    _mode_s(inst, attr, value)


def _nacp(lowest: int) -> Callable[[Any, attrs.Attribute, Any], None]:
    """A validator of a NACp category (DO-260B): an integer ``lowest``..11 (0: accuracy unknown)."""
    def check(inst: Any, attr: attrs.Attribute, value: Any) -> None:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lowest <= value <= 11:
            raise InputError(f"{attr.name}: NACp must be an integer category {lowest}..11"
                             f"{' (0: accuracy unknown)' if lowest == 0 else ''}, got {value!r}")
    return check


def _transponder(inst: Any, attr: attrs.Attribute, value: Any) -> None:
    if value not in TRANSPONDERS:
        raise InputError(f"{attr.name}: must be one of {', '.join(TRANSPONDERS)}, got {value!r}")


def _text(inst: Any, attr: attrs.Attribute, value: Any) -> None:
    if not isinstance(value, str):
        raise InputError(f"{attr.name}: expected a string, got {value!r}")


def _flag(inst: Any, attr: attrs.Attribute, value: Any) -> None:
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(f"{attr.name}: expected true or false, got {value!r}")


def _nonempty(inst: Any, attr: attrs.Attribute, value: str) -> None:
    if not isinstance(value, str) or not value.strip():
        raise InputError(f"{attr.name}: must be a non-empty string, got {value!r}")


def _lower(value: str | None) -> str | None:
    return value.lower() if isinstance(value, str) else value


@attrs.frozen
class Radar:
    """A rotating surveillance radar: site (WGS84, height above the ellipsoid), noise, period, coverage.

    ``sigma_range_m`` and ``sigma_azimuth_rad`` are the random-error standard deviations of
    W_j = diag(σ_r², σ_θ²) (seed 000 eq. 1.11); the antenna turns clockwise once per ``period_s``.
    """

    id: str = attrs.field(validator=_nonempty)
    lat: float = attrs.field(validator=_latitude)
    lon: float = attrs.field(validator=_longitude)
    height_m: float = attrs.field(validator=_finite)
    sigma_range_m: float = attrs.field(validator=_non_negative)
    sigma_azimuth_rad: float = attrs.field(validator=_non_negative)
    period_s: float = attrs.field(validator=_positive)
    max_range_m: float = attrs.field(validator=_positive)

    @property
    def W(self) -> np.ndarray:
        """Measurement noise covariance diag(σ_r², σ_θ²) in polar coordinates."""
        return np.diag([self.sigma_range_m**2, self.sigma_azimuth_rad**2])


# What the radars get from the aircraft: Mode S address, Mode 3/A code and altitude ("mode_s");
# Mode 3/A code and Mode C altitude only ("mode_a_c"); nothing, a primary-only target ("none").
TRANSPONDERS = ("mode_s", "mode_a_c", "none")


@attrs.frozen
class Aircraft:
    """An aircraft's identity: Mode S address, optional Mode 3/A code and callsign, ADS-B quality.

    ``transponder`` says what its radar plots carry (see ``TRANSPONDERS``); ``icao24`` always
    identifies it in simulation truth and ADS-B.
    """

    icao24: str = attrs.field(converter=_lower, validator=_address)
    callsign: str = attrs.field(default="", validator=_text)
    mode_3a: str | None = attrs.field(default=None, validator=_mode_3a)
    adsb: bool = attrs.field(default=False, validator=_flag)
    nacp: int = attrs.field(default=8, validator=_nacp(0))
    transponder: str = attrs.field(default="mode_s", validator=_transponder)


@attrs.frozen(slots=True)
class Plot:
    """One radar plot: time (s, UTC), slant range (m) and azimuth (rad, clockwise from north).

    ``altitude_m`` is the reported (barometric) altitude, ``None`` for primary-only plots.
    ``target`` is the true aircraft, present only in simulated data for evaluation.
    """

    time: float = attrs.field(validator=_finite)
    radar: str = attrs.field(validator=_nonempty)
    range_m: float = attrs.field(validator=_non_negative)
    azimuth_rad: float = attrs.field(validator=_azimuth)
    altitude_m: float | None = attrs.field(default=None, validator=_finite)
    mode_s: str | None = attrs.field(default=None, converter=_lower, validator=_mode_s)
    mode_3a: str | None = attrs.field(default=None, validator=_mode_3a)
    target: str | None = None


@attrs.frozen(slots=True)
class AdsbReport:
    """One ADS-B position report; NACp gives its 95 % horizontal accuracy bound (DO-260)."""

    time: float = attrs.field(validator=_finite)
    icao24: str = attrs.field(converter=_lower, validator=_mode_s)
    lat: float = attrs.field(validator=_latitude)
    lon: float = attrs.field(validator=_longitude)
    altitude_m: float | None = attrs.field(default=None, validator=_finite)
    nacp: int = attrs.field(default=8, validator=_nacp(1))


def _unchecked(cls: type) -> Callable[..., list]:
    """A function making a list of ``cls`` (a slotted attrs class) objects from columns of its field values in
    order, setting its slots without running converters or validators. Only for :func:`plot_rows` and
    :func:`report_rows`, once every value has passed the validators' rules."""
    setters = [cls.__dict__[a.name].__set__ for a in attrs.fields(cls)]

    def make(*cols: list) -> list:
        # a column at a time, by map over the slots' setters: no Python frame per object
        objs = list(map(object.__new__, itertools.repeat(cls, len(cols[0]))))
        for set_slot, col in zip(setters, cols):
            collections.deque(map(set_slot, objs, col), maxlen=0)
        return objs
    return make


_make_plot, _make_report = _unchecked(Plot), _unchecked(AdsbReport)


def _numbers(col: Any, lo: float = -math.inf, hi: float = math.inf, *, hi_open: bool = False,
             optional: bool = False) -> list | None:
    """The values of a numeric array column as the constructor gets them (``None`` for NaN if ``optional``),
    or ``None`` unless each passes ``_finite`` and lies in [lo, hi] (or [lo, hi))."""
    if not isinstance(col, np.ndarray) or col.dtype.kind not in "fiu":
        return None
    v = col.astype(float)
    nan = np.isnan(v)
    has_nan = bool(nan.any())
    if (has_nan and not optional) or np.isinf(v).any():
        return None
    w = v[~nan] if has_nan else v
    if not ((w >= lo) & ((w < hi) if hi_open else (w <= hi))).all():
        return None
    if not has_nan:
        return col.tolist()
    out = col.astype(object)
    out[nan] = None
    return out.tolist()


def _labels(col: Any, validator: Callable, field: attrs.Attribute, types: frozenset) -> list | None:
    """The values of an object array column, or ``None`` unless each is of one of ``types`` and passes
    ``validator`` unchanged (each distinct value checked once)."""
    if not isinstance(col, np.ndarray):
        return None
    values = col.tolist()
    if not set(map(type, values)) <= types:
        return None
    try:
        for v in set(values):
            validator(None, field, v)
    except ValueError:
        return None
    return values


_STR, _STR_OR_NONE = frozenset({str}), frozenset({str, type(None)})


RowMaker = Callable[[int, int], list]  # rows start:stop of checked columns as objects (see plot_rows)


def _rows(make: Callable[..., list], cols: tuple) -> RowMaker:
    return lambda start, stop: make(*(c[start:stop] for c in cols))


def plot_rows(time: np.ndarray, radar: np.ndarray, range_m: np.ndarray, azimuth_rad: np.ndarray,
              altitude_m: np.ndarray, mode_s: np.ndarray, mode_3a: np.ndarray, target: np.ndarray) -> RowMaker:
    """These columns (arrays; ``altitude_m`` NaN where absent) checked now, as a function giving ``Plot(...)`` of
    their rows ``start:stop``, in order: a long table's objects can be made a slice at a time, each just before
    it is used (fewer of them alive when the cyclic garbage collector scans).

    The columns are checked whole against the rules of Plot's validators (numbers as arrays; radar ids
    and codes with the validators themselves, once per distinct value). When every row passes, the
    objects are made without running the validators again field by field (the checks are already done,
    and per object they would be most of the work of reading); otherwise every row goes through
    ``Plot(...)`` now, which raises the first bad row's error.
    """
    f = attrs.fields(Plot)
    cols = (_numbers(time), _labels(radar, _nonempty, f.radar, _STR), _numbers(range_m, 0.0),
            _numbers(azimuth_rad, 0.0, TWO_PI, hi_open=True), _numbers(altitude_m, optional=True),
            _labels(mode_s, _mode_s, f.mode_s, _STR_OR_NONE), _labels(mode_3a, _mode_3a, f.mode_3a, _STR_OR_NONE),
            target.tolist() if isinstance(target, np.ndarray) else None)
    if any(c is None for c in cols):
        made = [Plot(t, r, rng, az, None if alt != alt else alt, ms, m3a, tg) for t, r, rng, az, alt, ms, m3a, tg
                in zip(*(c.tolist() for c in (time, radar, range_m, azimuth_rad, altitude_m, mode_s, mode_3a,
                                                target)))]
        return lambda start, stop: made[start:stop]
    return _rows(_make_plot, cols)


def plots_from_columns(time: np.ndarray, radar: np.ndarray, range_m: np.ndarray, azimuth_rad: np.ndarray,
                       altitude_m: np.ndarray, mode_s: np.ndarray, mode_3a: np.ndarray,
                       target: np.ndarray) -> list[Plot]:
    """``Plot(...)`` of each row of these columns, in order, checked as :func:`plot_rows` checks them."""
    return plot_rows(time, radar, range_m, azimuth_rad, altitude_m, mode_s, mode_3a, target)(0, len(time))


def report_rows(time: np.ndarray, icao24: np.ndarray, lat: np.ndarray, lon: np.ndarray, altitude_m: np.ndarray,
                nacp: np.ndarray) -> RowMaker:
    """These columns checked now, as a function giving ``AdsbReport(...)`` of their rows ``start:stop``
    (``nacp`` made an ``int``), checked as :func:`plot_rows` checks plots."""
    f = attrs.fields(AdsbReport)
    ok_nacp = isinstance(nacp, np.ndarray) and nacp.dtype.kind in "iu" and bool(((nacp >= 1) & (nacp <= 11)).all())
    cols = (_numbers(time), _labels(icao24, _mode_s, f.icao24, _STR_OR_NONE), _numbers(lat, -90.0, 90.0),
            _numbers(lon, -180.0, 180.0), _numbers(altitude_m, optional=True), nacp.tolist() if ok_nacp else None)
    if any(c is None for c in cols):
        made = [AdsbReport(t, icao, la, lo, None if alt != alt else alt, int(n)) for t, icao, la, lo, alt, n
                in zip(*(c.tolist() for c in (time, icao24, lat, lon, altitude_m, nacp)))]
        return lambda start, stop: made[start:stop]
    return _rows(_make_report, cols)


def reports_from_columns(time: np.ndarray, icao24: np.ndarray, lat: np.ndarray, lon: np.ndarray,
                         altitude_m: np.ndarray, nacp: np.ndarray) -> list[AdsbReport]:
    """``AdsbReport(...)`` of each row of these columns, in order, checked as :func:`report_rows` checks them."""
    return report_rows(time, icao24, lat, lon, altitude_m, nacp)(0, len(time))


# NACp → 95 % horizontal position bound EPU (m), DO-260B table; σ per axis = EPU / 2.448
# (the radius holding 95 % of a circular 2-D Gaussian).
NACP_EPU_M = {1: 18520.0, 2: 7408.0, 3: 3704.0, 4: 1852.0, 5: 926.0, 6: 555.6,
              7: 185.2, 8: 92.6, 9: 30.0, 10: 10.0, 11: 3.0}


def nacp_sigma_m(nacp: int) -> float:
    """Per-axis standard deviation (m) of an ADS-B position with this NACp."""
    if nacp not in NACP_EPU_M:
        raise InputError(f"nacp: must be 1..11 (0 means unknown accuracy, unusable), got {nacp!r}")
    return NACP_EPU_M[nacp] / 2.448


@attrs.frozen
class BiasState:
    """One radar's bias estimate ς = [Δr (m), Δθ (rad), …] and its covariance at ``time``.

    ``components`` names the entries of ``bias`` (:mod:`radartracker.estimation.sensor`): the range and
    azimuth offsets first, then any range gain (dimensionless) and time offset (s) the radar's model has.
    ``unobservable`` names the components the data do not inform, held at their prior mean with their prior
    σ (:func:`radartracker.estimation.observability.held_at_prior`), never reported with a small σ.
    """

    radar: str
    time: float
    bias: np.ndarray = attrs.field(converter=np.asarray)
    cov: np.ndarray = attrs.field(converter=np.asarray)
    components: tuple[str, ...] = ("range_offset", "azimuth_offset")
    unobservable: tuple[str, ...] = attrs.field(default=(), converter=tuple)

    def component(self, name: str) -> tuple[float, float]:
        """(estimate, σ) of the component ``name``."""
        k = self.components.index(name)
        return float(self.bias[k]), float(math.sqrt(max(self.cov[k, k], 0.0)))

    @property
    def range_m(self) -> float:
        return float(self.bias[0])

    @property
    def azimuth_rad(self) -> float:
        return float(self.bias[1])

    @property
    def sd_range_m(self) -> float:
        return float(math.sqrt(max(self.cov[0, 0], 0.0)))

    @property
    def sd_azimuth_rad(self) -> float:
        return float(math.sqrt(max(self.cov[1, 1], 0.0)))



"""Construction of domain objects validates every field and names it."""

import math
import random
import re

import numpy as np
import pytest

from radartracker.domain import AdsbReport, Aircraft, BiasState, Plot, Radar, nacp_sigma_m


def radar(**kw):
    args = dict(id="R1", lat=48.0, lon=2.0, height_m=100.0, sigma_range_m=70.0,
                sigma_azimuth_rad=math.radians(0.08), period_s=4.0, max_range_m=250e3)
    args.update(kw)
    return Radar(**args)


@pytest.mark.parametrize("field,value,words", [
    ("lat", math.nan, "lat: expected a finite number"),
    ("lat", 91.0, "lat: latitude"),
    ("lon", math.inf, "lon: expected a finite number"),
    ("sigma_range_m", -1.0, "sigma_range_m: must be >= 0"),
    ("sigma_azimuth_rad", -1e-3, "sigma_azimuth_rad: must be >= 0"),
    ("period_s", 0.0, "period_s: must be > 0"),
    ("id", " ", "id: must be a non-empty string"),
])
def test_radar_rejects_bad_fields(field, value, words):
    from radartracker.errors import RadarTrackerError

    with pytest.raises(RadarTrackerError, match=words):
        radar(**{field: value})


def test_radar_noise_matrix():
    r = radar()
    np.testing.assert_allclose(r.W, np.diag([70.0**2, math.radians(0.08) ** 2]))


@pytest.mark.parametrize("kw,words", [
    (dict(azimuth_rad=2 * math.pi), "azimuth_rad: azimuth must be in \\[0, 2π\\) radians, got 6.28"),
    (dict(azimuth_rad=-0.1), "azimuth_rad"),
    (dict(range_m=math.nan), "range_m: expected a finite number"),
    (dict(range_m=-5.0), "range_m: must be >= 0"),
    (dict(time=math.inf), "time: expected a finite number"),
    (dict(mode_s="xyz123"), "mode_s: Mode S address"),
    (dict(mode_3a="7778"), "mode_3a: Mode 3/A code"),
    (dict(altitude_m=math.nan), "altitude_m"),
])
def test_plot_rejects_bad_fields(kw, words):
    """A bad field is an InputError (the RadarTrackerError docs/api.md promises, still a ValueError) naming
    the field in its own units."""
    from radartracker.errors import InputError, RadarTrackerError

    args = dict(time=0.0, radar="R1", range_m=1e5, azimuth_rad=1.0)
    args.update(kw)
    with pytest.raises(InputError, match=words) as err:
        Plot(**args)
    assert isinstance(err.value, RadarTrackerError) and isinstance(err.value, ValueError)


@pytest.mark.parametrize("field, digits, length", [("mode_s", "0123456789abcdef", 6), ("mode_3a", "01234567", 4)])
def test_codes_are_accepted_exactly_when_every_character_is_a_digit(field, digits, length):
    """Against a regular expression: near misses are upper-case letters (lowered for Mode S), 8 and 9 in
    Mode 3/A, spaces, newlines, signs, non-ASCII digits and wrong lengths."""
    rng = random.Random(7)
    alphabet = digits + "89gAFx -\n\u0660\u00e9"
    rule = re.compile(f"[{digits}]{{{length}}}")
    seen = set()
    for _ in range(5000):
        v = "".join(rng.choice(alphabet) for _ in range(rng.choice([length - 1, length, length, length, length + 1])))
        ok = rule.fullmatch(v.lower() if field == "mode_s" else v) is not None
        try:
            Plot(0.0, "R1", 1e5, 1.0, **{field: v})
            accepted = True
        except ValueError:
            accepted = False
        assert accepted == ok, v
        seen.add(ok)
    assert seen == {True, False}


def test_plot_normalises_mode_s_case():
    assert Plot(0.0, "R1", 1e5, 1.0, mode_s="4B1A2C").mode_s == "4b1a2c"


def test_adsb_and_aircraft_validate():
    with pytest.raises(ValueError, match="lat"):
        AdsbReport(0.0, "4b1a2c", 100.0, 2.0)
    with pytest.raises(ValueError, match="nacp"):
        AdsbReport(0.0, "4b1a2c", 48.0, 2.0, nacp=0)
    with pytest.raises(ValueError, match="icao24"):
        Aircraft("zz")


@pytest.mark.parametrize("make,words", [
    (lambda: Aircraft("4b1a2c", nacp=12), "nacp: NACp must be an integer category 0..11"),
    (lambda: Aircraft("4b1a2c", nacp=True), "nacp: NACp"),
    (lambda: Aircraft("4b1a2c", transponder="mode_c"), "transponder: must be one of mode_s, mode_a_c, none"),
    (lambda: Aircraft("4b1a2c", callsign=7), "callsign: expected a string"),
    (lambda: Aircraft("4b1a2c", adsb="yes"), "adsb: expected true or false"),
    (lambda: Aircraft(None), "icao24: Mode S address"),
    (lambda: AdsbReport(0.0, "4b1a2c", 48.0, 2.0, nacp=12), "nacp: NACp must be an integer category 1..11"),
    (lambda: AdsbReport(0.0, "4b1a2c", 48.0, 2.0, nacp="8"), "nacp: NACp"),
    (lambda: Plot(True, "R1", 1e5, 1.0), "time: expected a finite number, got True"),
])
def test_every_refused_field_is_a_radartracker_error_naming_it(make, words):
    """Not attrs' ValueError with its tuple of internals: the one error class the CLI turns into one line."""
    from radartracker.errors import InputError

    with pytest.raises(InputError, match=words):
        make()


def test_nacp_sigma_is_95_percent_radius():
    # a circular 2-D Gaussian holds 95 % inside 2.448 σ: P(r < kσ) = 1 − exp(−k²/2)
    assert 1 - math.exp(-(2.448**2) / 2) == pytest.approx(0.95, abs=1e-3)
    assert nacp_sigma_m(8) == pytest.approx(92.6 / 2.448)
    with pytest.raises(ValueError, match="nacp"):
        nacp_sigma_m(0)


def test_bias_state():
    b = BiasState("R1", 10.0, [50.0, 0.001], np.diag([4.0, 1e-8]))
    assert (b.range_m, b.sd_range_m, b.sd_azimuth_rad) == (50.0, 2.0, pytest.approx(1e-4))


def test_track_status_identity_and_straight_line_state():
    """The manager's Track: a known status only; its Aircraft from its Mode S address; its state at a
    later time extrapolated in a straight line, never backwards (oracle: the arithmetic written here)."""
    from radartracker.registry import make_filter_factory
    from radartracker.tracking.track import Track

    f = make_filter_factory("cv")()
    f.start(10.0, np.array([100.0, 200.0]), 2500.0 * np.eye(2))
    f.update(14.0, np.array([500.0, 200.0]), 2500.0 * np.eye(2))
    tr = Track(1, f, "tentative", 10.0, 14.0, mode_s="abc123", mode_3a="1234")
    t0, x, _ = f.estimate()
    assert tr.state_at(20.0) == pytest.approx((x[0] + 6.0 * x[2], x[1] + 6.0 * x[3], x[2], x[3]))
    assert tr.state_at(0.0) == pytest.approx(tuple(x))
    assert tr.aircraft == Aircraft("abc123", mode_3a="1234") and Track(2, f, "confirmed", 0.0, 0.0).aircraft is None
    with pytest.raises(ValueError):
        Track(3, f, "lost", 0.0, 0.0)


# --- Plot / AdsbReport made from columns (the reader's path, issue 13) ------------------------------

def _plot_columns(n: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    alt = rng.uniform(0.0, 12e3, n)
    alt[rng.random(n) < 0.3] = math.nan
    codes = np.array([None, "4b1a2c", "00ff09", "abcdef"], object)
    return dict(time=np.sort(rng.uniform(-10.0, 1e5, n)), radar=np.array(["R1", "R 2", "é"], object)[rng.integers(0, 3, n)],
                range_m=np.concatenate([[0.0], rng.uniform(0.0, 4e5, n - 1)]),
                azimuth_rad=np.concatenate([[0.0, np.nextafter(2 * math.pi, 0)], rng.uniform(0, 2 * math.pi, n - 2)]),
                altitude_m=alt, mode_s=codes[rng.integers(0, 4, n)],
                mode_3a=np.array([None, "7777", "0123"], object)[rng.integers(0, 3, n)],
                target=np.array([None, "ac1", 7], object)[rng.integers(0, 3, n)])


def _report_columns(n: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    alt = rng.uniform(0.0, 12e3, n)
    alt[rng.random(n) < 0.3] = math.nan
    return dict(time=np.sort(rng.uniform(0.0, 1e5, n)), icao24=np.array([None, "4b1a2c", "abcdef"], object)[rng.integers(0, 3, n)],
                lat=np.concatenate([[-90.0, 90.0], rng.uniform(-90, 90, n - 2)]),
                lon=np.concatenate([[-180.0, 180.0], rng.uniform(-180, 180, n - 2)]),
                altitude_m=alt, nacp=rng.integers(1, 12, n))


def _one_by_one(cls, cols: dict) -> list:
    """The straightforward construction the columns' path must equal: the validating constructor per row."""
    rows = zip(*(c.tolist() for c in cols.values()))
    if cls is Plot:
        return [Plot(t, r, rng, az, None if alt != alt else alt, ms, m3a, tg) for t, r, rng, az, alt, ms, m3a, tg in rows]
    return [AdsbReport(t, i, la, lo, None if alt != alt else alt, int(n)) for t, i, la, lo, alt, n in rows]


def _error(f, *a):
    try:
        f(*a)
    except ValueError as exc:
        return str(exc)
    return None


@pytest.mark.parametrize("seed", range(3))
def test_columns_give_the_objects_of_the_validating_constructor(seed):
    from radartracker.domain import plots_from_columns, reports_from_columns

    pc, ac = _plot_columns(500, seed), _report_columns(500, seed)
    for cols, f, cls in ((pc, plots_from_columns, Plot), (ac, reports_from_columns, AdsbReport)):
        got, want = f(*cols.values()), _one_by_one(cls, cols)
        assert got == want and [hash(x) for x in got] == [hash(x) for x in want]
        assert [[type(v) for v in attrs_values(x)] for x in got] == [[type(v) for v in attrs_values(x)] for x in want]
        with pytest.raises(attrs_frozen_error()):
            got[0].time = 1.0


@pytest.mark.parametrize("bad", [False, True])
def test_rows_made_a_slice_at_a_time_are_those_of_the_whole_columns(bad):
    """plot_rows / report_rows: any slices give the validating constructor's objects of those rows; a bad row
    raises its error when the columns are handed over, before any slice is asked for."""
    from radartracker.domain import plot_rows, report_rows

    pc, ac = _plot_columns(500, 7), _report_columns(500, 7)
    for cols, f, cls in ((pc, plot_rows, Plot), (ac, report_rows, AdsbReport)):
        want = _one_by_one(cls, cols)
        if bad:
            cols["time"] = cols["time"].copy()
            cols["time"][321] = math.inf
            assert _error(f, *cols.values()) == _error(_one_by_one, cls, cols) is not None
            continue
        rows = f(*cols.values())
        for start, stop in ((0, 500), (0, 1), (7, 7), (123, 456), (499, 600)):
            assert rows(start, stop) == want[start:stop]


def attrs_values(x) -> tuple:
    import attrs

    return attrs.astuple(x, recurse=False)


def attrs_frozen_error():
    import attrs

    return attrs.exceptions.FrozenInstanceError


BAD_PLOT_VALUES = [("time", math.inf), ("time", math.nan), ("time", "1.0"), ("radar", ""), ("radar", " "), ("radar", 5),
                   ("range_m", -1e-9), ("range_m", math.inf), ("azimuth_rad", 2 * math.pi), ("azimuth_rad", -1e-12),
                   ("altitude_m", math.inf), ("altitude_m", -math.inf), ("mode_s", "4b1a2"), ("mode_s", "4b1a2g"),
                   ("mode_s", 123456), ("mode_3a", "7778"), ("mode_3a", "777"), ("mode_3a", 7777)]
BAD_REPORT_VALUES = [("time", math.nan), ("icao24", "xyz123"), ("icao24", ""), ("lat", 90.000001), ("lat", math.nan), ("lat", "45"),
                     ("lon", -180.5), ("altitude_m", math.inf), ("nacp", 0), ("nacp", 12)]


@pytest.mark.parametrize("field,value", BAD_PLOT_VALUES + [("r", v) for v in BAD_REPORT_VALUES])
def test_columns_with_a_bad_row_raise_what_the_constructor_raises(field, value):
    """The unchecked construction is reachable only when every row passes: one bad value in row 123 gives
    the validating constructor's error for that row (the rows before it made as usual)."""
    from radartracker.domain import plots_from_columns, reports_from_columns

    if field == "r":
        (field, value), cols, f, cls = value, _report_columns(300, 1), reports_from_columns, AdsbReport
    else:
        cols, f, cls = _plot_columns(300, 1), plots_from_columns, Plot
    # of its own dtype (a float or an int in a numeric column, anything in an object one); a text among numbers
    col = cols[field].astype(object) if isinstance(value, str) and cols[field].dtype != object else cols[field].copy()
    col[123] = value
    cols[field] = col
    want = _error(_one_by_one, cls, cols)
    assert want is not None and field in want
    assert _error(f, *cols.values()) == want


def _upper(col):
    return np.array([None if v is None else v.upper() for v in col], object)


def _np_str(col):  # a str subclass, which the converters' lower() makes a str
    return np.array([None if v is None else np.str_(v) for v in col], object)


@pytest.mark.parametrize("kind,field,change", [
    ("p", "mode_s", _upper), ("p", "mode_s", _np_str), ("p", "radar", _np_str), ("p", "range_m", lambda c: c.astype(np.int64)),
    ("p", "azimuth_rad", lambda c: np.where(c < 6.28, c, 1.0).astype(np.float32)), ("p", "time", lambda c: c.astype(object)),
    ("p", "altitude_m", lambda c: np.nan_to_num(c).astype(np.int32)), ("a", "icao24", _upper), ("a", "icao24", _np_str),
    ("a", "nacp", lambda c: c.astype(float)), ("a", "nacp", lambda c: c.astype(np.uint8)), ("a", "lat", list)])
def test_columns_the_constructor_converts_or_accepts_are_made_by_it(kind, field, change):
    """Codes to lower, str subclasses, integer, float32 and object columns: what the checked path does not
    take the validating constructor makes; the same objects, with values of the same types, either way."""
    from radartracker.domain import plots_from_columns, reports_from_columns

    cols, f, cls = ((_plot_columns(200, 4), plots_from_columns, Plot) if kind == "p" else
                    (_report_columns(200, 4), reports_from_columns, AdsbReport))
    cols[field] = change(cols[field])
    if isinstance(cols[field], list):  # not an array: neither path takes it
        with pytest.raises(AttributeError):
            f(*cols.values())
        return
    got, want = f(*cols.values()), _one_by_one(cls, cols)
    assert got == want
    assert [[type(v) for v in attrs_values(x)] for x in got] == [[type(v) for v in attrs_values(x)] for x in want]


def test_unchecked_construction_is_private_to_the_columns_path():
    """Nothing but plots_from_columns / reports_from_columns (after their checks) makes objects unchecked."""
    import pathlib
    import re

    root = pathlib.Path(__file__).resolve().parents[1]
    users = sorted(str(p.relative_to(root)) for d in ("radartracker", "plugins") for p in (root / d).rglob("*.py")
                   if re.search(r"_make_plot|_make_report|_unchecked", p.read_text(encoding="utf-8")))
    assert users == ["radartracker/domain.py"]

"""System tracks from a CAT062 recording (``radartracker assess --system-tracks``) and the intervals of the
system-track figures: a replay's tracks written as CAT062 and read back score as the replay's own, within
CAT062's quantisation; a reused track number is two tracks; thinned updates, breaks and latency against
oracles computed here from scipy's distributions, not from radartracker.assessment.stats."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import optimize
from scipy import stats as sps

from radartracker.assessment import stats
from radartracker.assessment.assess import assess
from radartracker.assessment.profile import load_profile
from radartracker.assessment.systracks import SystemTrackConfig, read_system_tracks
from radartracker.cli import main
from radartracker.geometry.plane import SystemPlane
from radartracker.io.asterix import CAT062, cat062_record, datablocks, write_cat062
from radartracker.io.asterix_reader import read_cat062
from radartracker.io.capture import write_pcap
from radartracker.io.sources import read_source

# CAT062's quantisation: I105 180°/2²⁵ (≤ 0.3 m each way once rounded), I070 1/128 s (≤ 1/256 s, ≤ 1.2 m at
# 300 m/s), I185 0.25 m/s over a coast: an RMS error moves by less than the RMS of the position differences
POSITION_TOL_M = 1.5
TIME_TOL_S = 1 / 128


@pytest.fixture(scope="module")
def round_trip(tmp_path_factory):
    """5 minutes of the `tracking` scenario, one aircraft's plots cut off at 150 s (its track is deleted before
    the end), assessed on its replay's tracks (API), and again through the command on those tracks written as
    CAT062."""
    root = tmp_path_factory.mktemp("cat062")
    assert main(["--quiet", "simulate", str(root / "s"), "--scenario", "tracking", "--duration", "300",
                 "--seed", "4"]) == 0
    plots = (root / "s" / "plots.csv").read_text().splitlines(keepends=True)
    gone = [k for k, line in enumerate(plots) if line.rstrip().endswith(",4b0d48") and float(line.split(",")[0]) > 150]
    (root / "s" / "plots.csv").write_text("".join(line for k, line in enumerate(plots) if k not in set(gone)))
    data = read_source(root / "s")
    own = assess(data, load_profile(), progress=False)
    write_cat062(root / "tracks.cat062", own.result)
    assert main(["--quiet", "assess", str(root / "s"), "--out", str(root / "out"),
                 "--system-tracks", str(root / "tracks.cat062")]) == 0
    return data, own, json.loads((root / "out" / "assessment.json").read_text()), root


def _close(a: float | None, b: float, tol: float) -> bool:
    """JSON's null is a bound at ±∞ (or no value) on both sides."""
    return (a is None and not math.isfinite(b)) or (a is not None and abs(a - b) <= tol)


def test_a_replays_tracks_as_cat062_score_as_its_own(round_trip):
    _, own, summary, root = round_trip
    system = summary["system"]
    assert system["source"] == str(root / "tracks.cat062")
    assert set(system["figures"]) == set(own.system) >= {"position_rmse_m", "probability_of_update",
                                                          "breaks_per_flight_hour", "false_tracks"}
    tol = {"position_rmse_m": POSITION_TOL_M, "initiation_delay_p95_s": TIME_TOL_S}
    for k, e in own.system.items():
        got = system["figures"][k]
        assert got["n"] == e.n and got["method"] == e.method, k
        for field, want in (("value", e.value), ("ci_low", e.low), ("ci_high", e.high)):
            assert _close(got[field], want, tol.get(k, 1e-12)), (k, field, got[field], want)
    records = _records(own.result.data, root / "tracks.cat062")
    ends = sorted(r["time"] for r in records if r["ended"])
    deleted = sorted(h.end for h in own.result.histories().values() if h.end > h.times[-1])
    assert len(ends) == len(deleted) == 1 and abs(ends[0] - deleted[0]) <= TIME_TOL_S  # the coast is in the file
    assert "no delivery time" in system["not_assessable"]["latency_p95_s"]
    assert "not delivered" in own.system_not_assessable["latency_p95_s"]
    assert system["verdicts"] == {"position_rmse_m": "pass", "probability_of_update": "pass"}


def _records(data, path) -> list[dict]:
    """The CAT062 records of ``path``, their times of day on the day of the recording's first plot."""
    return read_cat062(path, day_start=math.floor(data.plots.time.min() / 86400.0) * 86400.0)


def _rewrite(path, records: list[dict], keep=lambda r: True) -> None:
    recs = [cat062_record(r["time"], r["sac"], r["sic"], r["track_number"], r["lat"], r["lon"], r["x_m"], r["y_m"],
                          r["vx_mps"], r["vy_mps"], ended=r["ended"]) for r in records if keep(r)]
    path.write_bytes(b"".join(datablocks(CAT062, recs)))


def _wilson(k: int, n: int) -> tuple[float, float]:
    z = sps.norm.ppf(0.975)
    p = k / n
    centre, half = p + z * z / (2 * n), z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (centre - half) / (1 + z * z / n), (centre + half) / (1 + z * z / n)


def _garwood(k: int) -> tuple[float, float]:
    """The exact Poisson interval by root finding on the Poisson tails: P(X ≥ k; lo) = P(X ≤ k; hi) = 2.5 %."""
    lo = 0.0 if k == 0 else optimize.brentq(lambda m: sps.poisson.sf(k - 1, m) - 0.025, 1e-9, 10 * k + 10)
    hi = optimize.brentq(lambda m: sps.poisson.cdf(k, m) - 0.025, 1e-9, 10 * k + 20)
    return lo, hi


def test_a_gap_in_the_updates_is_missed_updates_and_a_break(round_trip):
    """The longest track's updates removed over 100 s: its number comes back after more than ``max_gap_s`` (a new
    track: one break more), and the intervals in between are not updated. P_u's interval is Wilson's and the
    breaks' Garwood's, as computed here."""
    data, own, _, root = round_trip
    records = _records(data, root / "tracks.cat062")
    longest = max({r["track_number"] for r in records}, key=lambda n: sum(r["track_number"] == n for r in records))
    t1 = [r["time"] for r in records if r["track_number"] == longest]
    cut = (t1[0] + 60.0, t1[0] + 160.0)
    _rewrite(root / "thinned.cat062", records,
             lambda r: r["track_number"] != longest or not cut[0] < r["time"] < cut[1])
    a = assess(data, load_profile(), progress=False, system_tracks=root / "thinned.cat062")
    pu, full = a.system["probability_of_update"], own.system["probability_of_update"]
    k = round(pu.value * pu.n)
    assert pu.n == full.n and 100.0 / 8 - 2 <= round(full.value * full.n) - k <= 100.0 / 8 + 1
    assert pu.method == "wilson" and (pu.low, pu.high) == pytest.approx(_wilson(k, pu.n), abs=1e-12)
    none, one = own.system["breaks_per_flight_hour"], a.system["breaks_per_flight_hour"]
    hours = _garwood(0)[1] / none.high  # the flight hours, from the replay's 0 breaks and the oracle's bound
    assert none.value == 0.0 and one.value * hours == pytest.approx(1.0)
    assert (one.low, one.high) == pytest.approx(tuple(b / hours for b in _garwood(1)), rel=1e-9)


def test_a_reused_track_number_is_two_tracks(tmp_path):
    """Number 7 lives 0–50 s, ends (TSE) and is reused at 60 s; number 9 stops at 50 s and comes back at 200 s
    (a gap over 60 s); another sender's number 7 lives 20–25 s. Five tracks, each with its own span; with
    ``max_gap_s`` 200, 9 stays one track."""
    plane = SystemPlane(48.0, 2.0)
    lat, lon = plane.to_geodetic(np.array([0.0]), np.array([0.0]))
    recs = [cat062_record(t, 0, 1, 7, lat[0], lon[0], 0.0, 0.0, 100.0, 0.0) for t in range(0, 51, 5)]
    recs.append(cat062_record(50.0, 0, 1, 7, lat[0], lon[0], 0.0, 0.0, 100.0, 0.0, ended=True))
    recs += [cat062_record(t, 0, 1, 7, lat[0], lon[0], 0.0, 0.0, 100.0, 0.0) for t in range(60, 91, 5)]
    recs += [cat062_record(t, 0, 1, 9, lat[0], lon[0], 0.0, 0.0, 0.0, 0.0) for t in [*range(0, 51, 5), 200, 205]]
    recs += [cat062_record(t, 0, 2, 7, lat[0], lon[0], 0.0, 0.0, 0.0, 0.0) for t in (20.0, 25.0)]  # another sender
    (tmp_path / "reused.cat062").write_bytes(b"".join(datablocks(CAT062, recs)))
    got = read_system_tracks(tmp_path / "reused.cat062", plane)
    spans = sorted((got.numbers[k], h.start, h.end) for k, h in got.histories.items())
    assert spans == [(7, 0.0, 50.0), (7, 20.0, 25.0), (7, 60.0, 90.0), (9, 0.0, 50.0), (9, 200.0, 205.0)]
    assert max(abs(h.states[:, :2]).max() for h in got.histories.values()) < 0.5  # I105 back in the plane
    joined = read_system_tracks(tmp_path / "reused.cat062", plane, SystemTrackConfig(max_gap_s=200.0))
    assert sorted((joined.numbers[k], h.start, h.end) for k, h in joined.histories.items())[3:] == [(9, 0.0, 205.0)]


def test_latency_from_a_pcaps_packet_times(round_trip, tmp_path):
    """Each update sent in its own packet 0.5 s after its time of applicability: every latency is 0.5 s."""
    data, _, _, root = round_trip
    records = _records(data, root / "tracks.cat062")
    packets = [(r["time"] + 0.5, next(datablocks(CAT062, [cat062_record(
        r["time"], 0, 100, r["track_number"], r["lat"], r["lon"], r["x_m"], r["y_m"], r["vx_mps"], r["vy_mps"],
        ended=r["ended"])]))) for r in records]
    write_pcap(tmp_path / "tracks.pcap", packets)
    a = assess(data, load_profile(), progress=False, system_tracks=tmp_path / "tracks.pcap")
    e = a.system["latency_p95_s"]
    assert e.method == "order-statistic" and e.n == sum(not r["ended"] for r in records)
    assert abs(e.value - 0.5) <= TIME_TOL_S and abs(e.low - 0.5) <= TIME_TOL_S and abs(e.high - 0.5) <= TIME_TOL_S
    assert "latency_p95_s" not in a.system_not_assessable


def _refused(capsys, args: list[str]) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err
    return err


def test_bad_system_tracks_are_one_line_and_exit_2(round_trip, tmp_path, capsys):
    _, _, _, root = round_trip
    base = ["--quiet", "assess", str(root / "s"), "--out", str(tmp_path / "o"), "--system-tracks"]
    corrupt = tmp_path / "corrupt.cat062"
    corrupt.write_bytes(bytes([62, 0, 9, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]))
    assert str(corrupt) in _refused(capsys, base + [str(corrupt)])
    no_position = tmp_path / "no105.cat062"
    items = {"010": (("SAC", 0), ("SIC", 1)), "070": (10.0, "s"), "040": 3, "080": (0,),
             "185": (("VX", (1.0, "m/s")), ("VY", (0.0, "m/s")))}
    no_position.write_bytes(next(datablocks(CAT062, [CAT062.cv_record.create(items)])))
    err = _refused(capsys, base + [str(no_position)])
    assert str(no_position) in err and "field I105" in err
    elsewhere = tmp_path / "tomorrow.cat062"
    _rewrite(elsewhere, [r | {"time": r["time"] + 40_000.0} for r in read_cat062(root / "tracks.cat062")])
    err = _refused(capsys, base + [str(elsewhere)])
    assert str(elsewhere) in err and "field I070" in err
    assert "--track-gap-s" in _refused(capsys, base + [str(root / "tracks.cat062"), "--track-gap-s", "0"])
    assert not (tmp_path / "o").exists()


def test_bootstrap_over_units_covers_a_known_ratio():
    """200 samples of 30 units (n_i ~ 1 + Poisson(40) pairs, squared errors χ²·σ² with σ = 70 m): the
    bootstrap interval of the RMS holds 70 m about 95 % of the time (within the binomial 99.9 % band)."""
    rng = np.random.default_rng(7)
    hits = 0
    for _ in range(200):
        n = 1 + rng.poisson(40, 30)
        sq = np.array([np.sum((70.0 * rng.standard_normal(k)) ** 2) for k in n])
        hits += stats.bootstrap_ratio(sq, n, root=True).contains(70.0)
    lo, hi = sps.binom.ppf([0.0005, 0.9995], 200, 0.95)
    assert lo <= hits <= hi


def test_order_statistic_and_zero_share_intervals():
    """The order statistics chosen are the narrowest pair holding the quantile with ≥ 95 %: the exact
    coverage B(u − 1) − B(l − 1) from scipy's binomial; a share no aircraft showed: [0, 1 − 0.025^(1/m)]."""
    x = np.arange(1.0, 201.0)
    e = stats.quantile(x, 0.95)
    lo_k, hi_k = int(e.low), int(e.high)  # x_(k) = k
    cover = sps.binom.cdf(hi_k - 1, 200, 0.95) - sps.binom.cdf(lo_k - 1, 200, 0.95)
    assert cover >= 0.95 and e.value == pytest.approx(np.percentile(x, 95))
    assert sps.binom.cdf(hi_k - 2, 200, 0.95) - sps.binom.cdf(lo_k - 1, 200, 0.95) < 0.95
    assert sps.binom.cdf(hi_k - 1, 200, 0.95) - sps.binom.cdf(lo_k, 200, 0.95) < 0.95
    z = stats.share_of_units(np.zeros(12), np.full(12, 100.0))
    assert (z.value, z.low) == (0.0, 0.0) and z.high == pytest.approx(1 - 0.025 ** (1 / 12))
    assert z.high == pytest.approx(sps.beta.ppf(0.975, 1, 12))


def test_reference_paths_have_no_repeated_time(demo_data):
    """The reference's paths on a 1 s grid end at the reference's last time: with times 1.4 … 4.4 s numpy's
    arange(1.4, 4.4, 1) already ends on 4.4, and appending the last time again made a zero step whose velocity
    was 0/0. Every time distinct, every velocity finite, the last step between 0.5 and 1.5 s."""
    import attrs
    import warnings

    from radartracker.assessment.reference import build_reference
    from radartracker.io.tables import TruthTable

    tr = demo_data.truth
    k = np.flatnonzero(tr.target == tr.target[0])[:7]
    truth = TruthTable(time=1.4 + 0.5 * np.arange(7), target=tr.target[k], lat=tr.lat[k], lon=tr.lon[k],
                       altitude_m=tr.altitude_m[k])
    assert np.arange(1.4, 4.4, 1.0)[-1] == 4.4  # the case
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        (t, _, v), = build_reference(attrs.evolve(demo_data, truth=truth)).paths().paths.values()
    assert t[0] == 1.4 and t[-1] == 4.4 and np.all(np.diff(t) > 0.5 - 1e-9) and np.all(np.diff(t) < 1.5)
    assert np.all(np.isfinite(v))

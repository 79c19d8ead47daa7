"""The reconstruction as the assessment's reference (``ReferenceConfig.reconstruct``, the default without truth):
a ``paris`` recording without its truth, where only every third aircraft broadcasts ADS-B; the others are
reconstructed from their Mode S plots with the replay's bias estimates removed. Judged by the simulator's truth,
which the assessment never sees."""

from __future__ import annotations

import math

import attrs
import numpy as np
import pytest

from radartracker.assessment.assess import AssessmentConfig, assess
from radartracker.assessment.profile import load_profile
from radartracker.assessment.reference import ReferenceConfig, build_reference
from radartracker.cli import main
from radartracker.errors import ConfigurationError
from radartracker.geometry.plane import SystemPlane
from radartracker.io.scenario import write_scenario
from radartracker.simulation.scenarios import build_scenario


@pytest.fixture(scope="module")
def recording():
    """(the scenario without truth, the truth table, the true biases)."""
    data = build_scenario("paris", seed=1, duration=300.0).run()
    truth = data.truth
    return attrs.evolve(data, truth=None), truth, data.truth_biases


@pytest.fixture(scope="module")
def assessed(recording):
    data, _, _ = recording
    config = AssessmentConfig(reference=ReferenceConfig(reconstruct=True))
    adsb_only = AssessmentConfig(reference=ReferenceConfig(reconstruct=False))
    return assess(data, load_profile(), config, progress=False), assess(data, load_profile(), adsb_only, progress=False)


def test_every_aircraft_with_mode_s_plots_gets_a_reference(recording, assessed):
    data, _, _ = recording
    with_rec, adsb_only = assessed
    assert adsb_only.reference == "adsb" and with_rec.reference == "adsb+reconstruction"
    assert with_rec.reference_left_out == {}
    adsb_keys = set(build_reference(data, ReferenceConfig(reconstruct=False)).tracks)
    plotted = {m for m in data.plots.mode_s if m is not None}
    assert len(adsb_keys) < len(plotted)
    reference = build_reference(data)  # reconstruct by default; the flights are added after the replay
    assert set(reference.tracks) == adsb_keys  # the reconstruction is added after the replay, in assess
    for r_rec, r_adsb in zip(with_rec.radars, adsb_only.radars):
        assert r_rec.figures["pd"].n > 1.5 * r_adsb.figures["pd"].n  # more aircraft judged


def test_bias_figures_hold_the_true_biases(recording, assessed):
    """Each radar's range and azimuth offset against the (partly reconstructed) reference holds the simulator's
    bias in its 95 % interval (5 m / 0.005° of slack for the one run; the assessment never sees the truth)."""
    _, _, true = recording
    with_rec, _ = assessed
    for r in with_rec.radars:
        dr, dtheta = true[r.radar]
        rng, az = r.figures["range_bias_vs_reference_m"], r.figures["azimuth_bias_vs_reference_deg"]
        assert rng.low - 5.0 < dr < rng.high + 5.0, (r.radar, rng, dr)
        assert az.low - 0.005 < math.degrees(dtheta) < az.high + 0.005, (r.radar, az, math.degrees(dtheta))


def test_reconstructed_paths_follow_the_truth(recording):
    """The reconstructions' positions against the truth at their own times: the reference's own accuracy
    (docs/assessment.md states it), well inside the radars' 70–100 m plot noise."""
    data, truth, true = recording
    from radartracker.assessment.reference import add_reconstructed

    biases = {r: (np.asarray(b, float), np.zeros((2, 2))) for r, b in true.items()}
    base = build_reference(data, ReferenceConfig(reconstruct=True))
    ref = add_reconstructed(base, data, biases, ReferenceConfig(reconstruct=True))
    plane = SystemPlane(*data.reference)
    x, y = plane.to_plane(truth.lat, truth.lon)
    errors = []
    for key in set(ref.tracks) - set(base.tracks):
        tr, sel = ref.tracks[key], truth.target.astype(str) == key
        t = tr.times[(tr.times >= truth.time[sel].min()) & (tr.times <= truth.time[sel].max())]
        px, py, _ = tr.trajectory.position(t)
        errors.append(np.hypot(px - np.interp(t, truth.time[sel], x[sel]), py - np.interp(t, truth.time[sel], y[sel])))
    e = np.concatenate(errors)
    assert len(errors) >= 4 and np.median(e) < 40.0 and np.percentile(e, 90) < 90.0


def test_an_unknown_reconstructor_is_refused_before_the_replay(recording, tmp_path, capsys):
    data, _, _ = recording
    config = AssessmentConfig(reference=ReferenceConfig(reconstruct=True, reconstructor="nope"))
    with pytest.raises(ConfigurationError, match="unknown reconstructor 'nope'"):
        assess(data, load_profile(), config, progress=False)
    write_scenario(tmp_path / "rec", data)
    assert main(["--quiet", "assess", str(tmp_path / "rec"), "--out", str(tmp_path / "out"),
                 "--reconstructor", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown reconstructor 'nope'" in err[0]
    assert not (tmp_path / "out").exists()


def test_plots_without_an_address_are_grouped_by_the_system_tracks(recording, assessed):
    """The same recording with the address taken off every plot of the aircraft without ADS-B (Mode A/C or
    primary): their plots are grouped by the replay's tracks (``track-<id>``) and reconstructed, so the radars
    are judged on nearly the same plots as when the addresses grouped them, and still hold the true biases."""
    data, _, true = recording
    with_addresses, _ = assessed
    adsb = set(data.adsb.icao24.astype(str))
    mode_s = data.plots.mode_s.copy()
    mode_s[[m is not None and m not in adsb for m in mode_s.tolist()]] = None
    stripped = attrs.evolve(data, plots=attrs.evolve(data.plots, mode_s=mode_s))
    config = AssessmentConfig(reference=ReferenceConfig(reconstruct=True))
    a = assess(stripped, load_profile(), config, progress=False)
    assert a.reference == "adsb+reconstruction" and a.reference_left_out == {}
    for r, full in zip(a.radars, with_addresses.radars):
        assert r.figures["pd"].n >= 0.95 * full.figures["pd"].n
        rng = r.figures["range_bias_vs_reference_m"]
        assert rng.low - 5.0 < true[r.radar][0] < rng.high + 5.0

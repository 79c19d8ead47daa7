"""`radartracker compare`: scores recomputed independently, pooling arithmetic, CLI outputs and errors."""

from __future__ import annotations

import json
import math

import attrs
import numpy as np
import pytest

from radartracker.cli import main
from radartracker.pipeline.compare import Score, markdown_table, pool, run_comparison, score, write_comparison
from radartracker.io.scenario import write_scenario
from radartracker.simulation.scenarios import build_scenario


@pytest.fixture(scope="module")
def demo_data():
    return build_scenario("demo", seed=2, duration=150.0).run()


def test_scores_agree_with_the_replay_summary(demo_data):
    results = run_comparison(demo_data, ["decoupled", "coupled"])
    for name, res in results.items():
        s = score(res)
        summ = res.summary()
        err_r = [b["error_range_m"] for b in summ["biases"].values()]
        err_a = [b["error_azimuth_deg"] for b in summ["biases"].values()]
        assert s.bias_rmse_range_m == pytest.approx(math.sqrt(np.mean(np.square(err_r))), rel=1e-12)
        assert s.bias_rmse_azimuth_deg == pytest.approx(math.sqrt(np.mean(np.square(err_a))), rel=1e-12)
        z2 = [b["z_range"] ** 2 + b["z_azimuth"] ** 2 for b in summ["biases"].values()]
        assert s.bias_nees >= 0.0 and s.radars == 3
        if name == "decoupled":  # C_s = D keeps its 2×2 bias covariance diagonal: NEES = Σ z²
            assert s.bias_nees == pytest.approx(np.mean(z2), rel=1e-9)
        assert s.position_rmse_m == summ["truth"]["position_rmse_m"]
        assert s.us_per_measurement > 0.0
    # the coupled filter's biases are better than the decoupled ones' (DESIGN §5: it is optimal)
    assert score(results["coupled"]).bias_rmse_range_m < score(results["decoupled"]).bias_rmse_range_m


def test_pool_weights_runs_by_radars_and_estimates():
    a = Score("x", 3.0, 0.3, 10.0, 1.0, 4.0, 2.0, 10.0, radars=1, estimates=100)
    b = Score("x", 1.0, 0.1, 20.0, 2.0, 6.0, 4.0, 30.0, radars=3, estimates=300)
    p = pool([a, b])
    assert p.bias_rmse_range_m == pytest.approx(math.sqrt((9.0 + 3.0) / 4.0))
    assert p.position_rmse_m == pytest.approx(math.sqrt((100 * 100.0 + 300 * 400.0) / 400.0))
    assert p.mean_nees == pytest.approx((100 * 4.0 + 300 * 6.0) / 400.0)
    assert p.bias_nees == pytest.approx((2.0 + 3 * 4.0) / 4.0)
    assert (p.runs, p.radars, p.us_per_measurement) == (2, 4, 20.0)
    assert pool([a]) == attrs.evolve(a)
    table = markdown_table([a, p])
    assert table.count("\n") == 3 and "| x | 3.0 |" in table


def test_compare_cli_writes_table_scores_and_figures(tmp_path, demo_data, capsys):
    write_scenario(tmp_path / "sc", demo_data)
    out = tmp_path / "cmp"
    assert main(["compare", str(tmp_path / "sc"), "--estimators", "decoupled,blom,coupled", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    for name in ("decoupled", "blom", "coupled"):
        assert f"| {name} |" in printed
    scores = json.loads((out / "scores.json").read_text())
    assert [s["estimator"] for s in scores] == ["decoupled", "blom", "coupled"]
    assert all(math.isfinite(s["position_rmse_m"]) for s in scores)
    for fig in ("bias_error.png", "rmse_vs_time.png"):
        assert (out / fig).read_bytes()[:4] == b"\x89PNG"


def test_compare_cli_rejects_unknown_estimator(tmp_path, demo_data, capsys):
    write_scenario(tmp_path / "sc", demo_data)
    rc = main(["compare", str(tmp_path / "sc"), "--estimators", "decoupled,nosuch", "--out", str(tmp_path / "o")])
    assert rc == 2 and "nosuch" in capsys.readouterr().err


def test_write_comparison_without_truth_skips_figures(tmp_path, demo_data):
    data = attrs.evolve(demo_data, truth=None, truth_biases=None)
    scores = write_comparison(run_comparison(data, ["coupled"]), tmp_path)
    assert math.isnan(scores[0].bias_rmse_range_m) and not (tmp_path / "bias_error.png").exists()


def test_compare_overwrite_that_fails_keeps_the_earlier_comparison(tmp_path, demo_data, capsys, monkeypatch):
    """An earlier comparison stays byte for byte when the rerun fails (here while drawing its figures, after
    its table was staged); a rerun that succeeds leaves only its own files."""
    import errno

    import radartracker.pipeline.compare as compare

    write_scenario(tmp_path / "sc", demo_data)
    out = tmp_path / "cmp"
    assert main(["compare", str(tmp_path / "sc"), "--estimators", "decoupled,coupled", "--out", str(out)]) == 0
    earlier = {p.name: p.read_bytes() for p in out.iterdir()}
    assert {"comparison.md", "scores.json", "bias_error.png"} <= set(earlier)

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(compare, "plot_rmse_vs_time", full)
    args = ["compare", str(tmp_path / "sc"), "--estimators", "coupled", "--out", str(out), "--overwrite"]
    assert main(args) == 2 and "No space left" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == earlier
    monkeypatch.undo()
    assert main(args) == 0
    now = {p.name: p.read_bytes() for p in out.iterdir()}
    assert set(now) == set(earlier) and now["scores.json"] != earlier["scores.json"]


def test_each_estimator_is_warmed_up_before_its_timed_run(demo_data, monkeypatch):
    """The first estimator's time per measurement included numba's compiling (or loading) of its kernels;
    each is now warmed up, with the run's settings, just before its own run."""
    import radartracker.pipeline.compare as compare
    import radartracker.pipeline.warmup as warmup

    calls = []
    monkeypatch.setattr(warmup, "warm_up", lambda cfg, **kw: calls.append(("warm", cfg.estimator)))
    real_run = compare.run
    monkeypatch.setattr(compare, "run", lambda data, cfg, **kw: calls.append(("run", cfg.estimator))
                        or real_run(data, cfg, **kw))
    run_comparison(demo_data, ["decoupled", "blom"], progress=False)
    assert calls == [("warm", "decoupled"), ("run", "decoupled"), ("warm", "blom"), ("run", "blom")]

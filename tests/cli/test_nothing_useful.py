"""Every command exits non-zero when it produced nothing useful (issue 12 §3)."""

from radartracker.cli import main
from tests.plugins.test_triangulation_cli import _rows, _write_bearings, _write_stations


def test_simulate_that_makes_no_plot_exits_2_and_writes_nothing(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "s"), "--duration", "1e-300"]) == 2
    assert "no plots" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_simulate_refuses_an_absurd_traffic_size(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "s"), "--scenario", "traffic", "--aircraft", "1000000000"]) == 2
    assert "--aircraft: 1000000000 must be <= 10000000" in capsys.readouterr().err


def test_triangulate_with_every_target_refused_exits_2_with_one_line(tmp_path, capsys):
    import numpy as np

    frame = _write_stations(tmp_path / "stations.csv")
    target = frame.enu(50.0, 7.0, 7000.0)
    # a single station sees the only target: degenerate geometry, refused
    _write_bearings(tmp_path / "b.csv", _rows(frame, ["df0"] * 3, [0.0, 1.0, 2.0], np.tile(target, (3, 1)), "T",
                                              np.random.default_rng(1)))
    assert main(["triangulate", str(tmp_path / "b.csv"), "--stations", str(tmp_path / "stations.csv"),
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no target located: 1 of 1 refused (target T: degenerate geometry" in err[0], err

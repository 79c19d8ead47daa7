"""Options of ``serve`` and ``send`` that used to pass and crash later (issue 33): each is refused at once,
with one line naming it and exit 2, before the service makes its state folder or opens a socket."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from radartracker.cli import main
from radartracker.io.asterix import write_asterix
from radartracker.service import ServiceConfig, parse_endpoint
from radartracker.simulation.scenarios import build_scenario


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("options")
    write_asterix(d / "rec.ast", build_scenario("demo", seed=3, duration=10.0).run())
    return d / "rec.ast"


BAD_SERVE = {
    "--frame-s 0": (["--frame-s", "0"], "--frame-s"),
    "--frame-s nan": (["--frame-s", "nan"], "--frame-s"),
    "--reorder-window -1": (["--reorder-window", "-1"], "--reorder-window"),
    "--sac 999": (["--sac", "999"], "sac"),
    "--sic -1": (["--sic", "-1"], "sic"),
    "--queue 1e10": (["--queue", "10000000000"], "queue_size"),
    "--checkpoint-s 1e-9": (["--checkpoint-s", "1e-9"], "checkpoint_s"),
    "--period inf": (["--period", "inf"], "period_s"),
}


@pytest.mark.parametrize("case", list(BAD_SERVE))
def test_a_bad_serve_option_is_refused_before_anything_starts(recording, tmp_path, capsys, case) -> None:
    extra, named = BAD_SERVE[case]
    state = tmp_path / "state"
    rc = main(["serve", "--radars", f"{recording}.radars.csv", "--listen", "udp://127.0.0.1:9",
               "--publish", "udp://127.0.0.1:9", "--state", str(state), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and named in err[0], err
    assert not state.exists()


def test_an_http_port_beyond_65535_is_a_usage_error(recording, tmp_path, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["serve", "--radars", f"{recording}.radars.csv", "--listen", "udp://127.0.0.1:9",
              "--publish", "udp://127.0.0.1:9", "--state", str(tmp_path / "s"), "--http", "127.0.0.1:99999"])
    assert exc.value.code == 2 and "0..65535" in capsys.readouterr().err


@pytest.mark.parametrize("speed", ["1e-300", "nan", "-1", "1e9"])
def test_a_bad_send_speed_is_refused(recording, capsys, speed) -> None:
    rc = main(["send", str(recording), "--to", "udp://127.0.0.1:9", "--speed", speed])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "--speed" in err[0], err


def test_service_config_bounds_hold_for_an_embedding_application(tmp_path) -> None:
    ep = parse_endpoint("udp://127.0.0.1:9")
    ok = ServiceConfig((ep,), ep, tmp_path, http=("127.0.0.1", 0), period_s=0.5, checkpoint_s=0.5, sac=255, sic=0)
    assert ok.sac == 255 and ok.http == ("127.0.0.1", 0)
    for bad in ({"sac": 256}, {"sic": 1.5}, {"queue_size": 0}, {"period_s": math.nan}, {"checkpoint_s": 1e6},
                {"http": ("127.0.0.1", 70_000)}, {"sac": True}):
        with pytest.raises(ValueError):
            ServiceConfig((ep,), ep, tmp_path, **bad)

"""main() builds its parser once per state of the path, and still sees a command installed or removed later."""

import os
import shutil
import sys
import textwrap

import pytest

from radartracker.cli import _parser, build_parser, main
from radartracker.entrypoints import path_state

COMMAND = '''
CALLS = []


def register(sub):
    p = sub.add_parser("latecomer")
    p.add_argument("--item", action="append", default=[])
    p.set_defaults(func=run)


def run(args):
    args.item.append("added by the command")  # in place: the next call must not see it
    CALLS.append(list(args.item))
    return 0
'''


def _touch(folder, seconds):
    """The folder's modification time moved on, as an install or removal a moment later would."""
    st = os.stat(folder)
    os.utime(folder, ns=(st.st_atime_ns, st.st_mtime_ns + seconds * 1_000_000_000))


@pytest.fixture()
def site(tmp_path, monkeypatch):
    folder = tmp_path / "site"
    folder.mkdir()
    monkeypatch.syspath_prepend(str(folder))
    yield folder
    sys.modules.pop("rt_latecomer_cmd", None)


def _install(site, entry: str, seconds: int):
    dist = site / "rt_latecomer_cmd-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: rt-latecomer-cmd\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[radartracker.commands]\nlatecomer = {entry}\n")
    _touch(site, seconds)
    return dist


def test_a_command_installed_then_removed_between_calls(site, capsys):
    with pytest.raises(SystemExit):  # not installed yet: argparse refuses the name
        main(["latecomer"])
    assert "invalid choice: 'latecomer'" in capsys.readouterr().err
    (site / "rt_latecomer_cmd.py").write_text(textwrap.dedent(COMMAND))
    dist = _install(site, "rt_latecomer_cmd:register", 1)
    assert main(["latecomer"]) == 0 and main(["latecomer", "--item", "a"]) == 0 and main(["latecomer"]) == 0
    calls = sys.modules["rt_latecomer_cmd"].CALLS
    assert calls == [["added by the command"], ["a", "added by the command"], ["added by the command"]]
    shutil.rmtree(dist)
    _touch(site, 2)
    with pytest.raises(SystemExit):
        main(["latecomer"])
    assert "invalid choice: 'latecomer'" in capsys.readouterr().err


def test_a_broken_command_is_named_at_every_call(site, capsys):
    _install(site, "rt_no_such_module:register", 1)
    for _ in range(2):
        with pytest.raises(SystemExit):
            main(["latecomer"])
        assert "warning: command 'latecomer' (rt_no_such_module:register) not loaded" in capsys.readouterr().err
    build_parser()
    assert "warning: command 'latecomer' (rt_no_such_module:register) not loaded" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [
    ["replay", "scen", "--out", "o", "--manager", "--motion-option", "q=2", "--motion-option", "r=1", "--quiet"],
    ["--quiet", "compare", "scen", "--out", "o"],
    ["simulate", "s", "--scenario", "traffic", "--aircraft", "5", "--adsb-share", "0.5"],
])
def test_the_kept_parser_parses_as_a_new_one(argv):
    kept, _ = _parser(path_state())
    assert kept is _parser(path_state())[0]
    assert vars(kept.parse_args(argv)) == vars(build_parser().parse_args(argv))  # the oracle: a parser built now

"""Plugin look-ups are read once per state of the path, and still see a plugin installed or removed later."""

import os
import shutil
import sys
import textwrap

from importlib.metadata import entry_points

from radartracker.entrypoints import installed
from radartracker.registry import ESTIMATOR_GROUP, MOTION_GROUP, available_estimators, load_estimator

PLUGIN = '''
from radartracker.api import Estimator


class Latecomer(Estimator):
    name = "latecomer"
'''


def _fresh(group):  # the oracle: importlib.metadata itself, read now
    return {ep.name: ep for ep in entry_points(group=group)}


def test_cached_groups_equal_importlib_metadata():
    for group in (ESTIMATOR_GROUP, MOTION_GROUP, "radartracker.commands"):
        assert list(installed(group).items()) == list(_fresh(group).items())
        assert list(installed(group).items()) == list(_fresh(group).items())  # the cached answer too


def test_a_plugin_installed_into_a_folder_already_on_the_path_is_found_then_forgotten(tmp_path, monkeypatch):
    site = tmp_path / "site"
    site.mkdir()
    monkeypatch.syspath_prepend(str(site))
    assert "latecomer" not in available_estimators()  # read (and kept) before the plugin is installed
    (site / "rt_latecomer.py").write_text(textwrap.dedent(PLUGIN))
    dist = site / "rt_latecomer-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: rt-latecomer\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[{ESTIMATOR_GROUP}]\nlatecomer = rt_latecomer:Latecomer\n")
    st = os.stat(site)
    os.utime(site, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))  # as an install a moment later would
    assert "latecomer" in _fresh(ESTIMATOR_GROUP) and "latecomer" in available_estimators()
    assert load_estimator("latecomer").__name__ == "Latecomer"
    shutil.rmtree(dist)
    os.utime(site, ns=(st.st_atime_ns, st.st_mtime_ns + 2_000_000_000))
    assert "latecomer" not in _fresh(ESTIMATOR_GROUP) and "latecomer" not in available_estimators()
    sys.modules.pop("rt_latecomer", None)

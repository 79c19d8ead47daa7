"""``radartracker --help`` starts light: registering the sub-commands imports none of the heavy modules.

A timing would be flaky on a loaded machine; what makes the start-up slow is what it imports, which a
new process reports exactly (``sys.modules`` after the command). benchmarks/bench_startup.py measures
the time.
"""

import json
import subprocess
import sys

import pytest

# numerical and plotting libraries, and the parts of the core that import them: a command imports them when it runs
HEAVY = ("numpy", "numba", "scipy", "matplotlib", "pyproj", "pyarrow", "networkx", "dask", "distributed", "asterix",
         "msgpack", "prometheus_client", "tqdm", "radartracker.pipeline", "radartracker.tracking",
         "radartracker.estimation", "radartracker.registry", "radartracker.simulation", "radartracker.domain",
         "radartracker.geometry", "radartracker.fusion", "radartracker.service", "radartracker.compiled")

CHILD = """
import json, sys
{before}
from radartracker.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
print(json.dumps(sorted(sys.modules)))
"""


def _imported(*argv: str, before: str = "") -> list[str]:
    """The heavy modules (or their submodules) a new process has imported after ``radartracker ARGV``."""
    out = subprocess.run([sys.executable, "-c", CHILD.format(before=before), *argv], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    modules = json.loads(out.stdout.strip().splitlines()[-1])
    return sorted({h for h in HEAVY for m in modules if m == h or m.startswith(h + ".")})


@pytest.mark.parametrize("argv", [("--help",), ("replay", "--help"), ("simulate", "--help"),
                                  ("triangulate", "--help"), ("reconstruct", "--help"), ("convert", "--help")],
                         ids=" ".join)
def test_help_imports_no_heavy_module(argv):
    assert _imported(*argv) == []


def test_the_probe_sees_a_heavy_import():
    """The check above can fail: modules imported on the way are reported."""
    found = _imported("--help", before="import numpy, radartracker.pipeline.config")
    assert {"numpy", "radartracker.pipeline", "radartracker.registry"} <= set(found)


def test_the_parsers_names_are_the_built_in_ones():
    """The scenario names the parser offers without importing the simulator are the simulator's."""
    from radartracker.settings import SCENARIOS
    from radartracker.simulation.scenarios import STANDARD_SCENARIOS

    assert sorted(SCENARIOS) == sorted(STANDARD_SCENARIOS)

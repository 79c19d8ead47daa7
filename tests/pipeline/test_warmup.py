"""The warm-up reaches every compiled kernel a run calls, so none is compiled inside the run."""

import json
import subprocess
import sys

CHILD = r"""
import json, sys
import numpy as np
from numba.core.registry import CPUDispatcher
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.run import run
from radartracker.pipeline.warmup import warm_up
from radartracker.simulation.traffic import traffic_scenario

def signatures():
    out = {}
    for name, mod in list(sys.modules.items()):
        if name.startswith(("radartracker", "radartracker_plugins")):
            for attr, obj in list(vars(mod).items()):
                if isinstance(obj, CPUDispatcher):
                    out[f"{name}.{attr}"] = len(obj.signatures)
    return out

labelled = sys.argv[1] == "labels"
config = RunConfig(association=sys.argv[1])
warm_up(config, labelled=labelled, notice=False)
before = signatures()
data = traffic_scenario(seed=11, duration=150.0, aircraft=40, radars=4, primary_share=0.3).run()
if not labelled:
    data.plots.target = np.full(len(data.plots), None, dtype=object)
    data.truth = None
result = run(data, config, progress=False)
after = signatures()
print(json.dumps({"before": before, "after": after, "used": result.counts.get("plots_used", 0)}))
"""


def _signatures_around_a_run(association: str) -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD, association], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_manager_run_after_the_warm_up_compiles_nothing():
    res = _signatures_around_a_run("manager")
    assert res["used"] > 100 and res["before"]  # the run used plots; kernels were loaded by the warm-up
    grown = {k: (res["before"].get(k, 0), n) for k, n in res["after"].items() if n > res["before"].get(k, 0)}
    assert not grown, f"kernels compiled inside the run: {grown}"


def test_a_labelled_run_after_the_warm_up_compiles_nothing():
    res = _signatures_around_a_run("labels")
    assert res["used"] > 100 and res["before"]
    grown = {k: (res["before"].get(k, 0), n) for k, n in res["after"].items() if n > res["before"].get(k, 0)}
    assert not grown, f"kernels compiled inside the run: {grown}"

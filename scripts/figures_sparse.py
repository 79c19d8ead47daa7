"""Figures of docs/estimators.md § "Exact coupled estimation at scale".

    python scripts/figures_sparse.py [--bench docs/figures/sparse_bench.jsonl]

* ``docs/figures/sparse_structure.png``: the joint information matrix of ``coupled-sparse`` after a
  10-minute run of a small region (6 radars in a row, ≈10 aircraft, no ADS-B), its
  nonzero pattern (the arrowhead) beside the coupling graph it corresponds to.
* ``docs/figures/sparse_scaling.png``: time per plot and storage vs number of aircraft, ``coupled`` vs
  ``coupled-sparse``, from the JSON lines written by ``benchmarks/bench_scaling.py --out``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import networkx as nx  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from bench_scaling import PRIOR_COV, region_plots  # noqa: E402

from radartracker.estimation.coupling import CouplingGraph  # noqa: E402
from radartracker.estimation.motion import MotionModel  # noqa: E402
from radartracker.estimation.base import EstimatorConfig  # noqa: E402
from radartracker.registry import make_estimator  # noqa: E402

FIG = Path(__file__).resolve().parent.parent / "docs" / "figures"


def structure_figure(out: Path) -> None:
    t, a, radar, z, C, R, ids, period, _ = region_plots(10, 6, 600.0, seed=3, max_range=200e3)
    est = make_estimator("coupled-sparse", EstimatorConfig(motion=MotionModel(1.0)), ids)
    graph = CouplingGraph(ids)
    for i in range(len(t)):
        if a[i] not in est.aircraft_keys:
            est.add_aircraft(a[i], t[i], np.array([z[i][0], z[i][1], 0.0, 0.0]), PRIOR_COV)
        est.update_many(t[i:i + 1], a[i:i + 1], radar[i:i + 1], z[i:i + 1], C[i:i + 1], R[i:i + 1])
        graph.observe(f"A{a[i]}", radar[i], t[i])
    info = est.information()
    keys = sorted(info["aircraft"])
    N, nb = 4 * len(keys), 2 * len(ids)
    Y = np.zeros((N + nb, N + nb))
    Y[N:, N:] = info["Ybb"]
    for r, key in enumerate(keys):
        Yii, blocks, _, _ = info["aircraft"][key]
        Y[4 * r:4 * r + 4, 4 * r:4 * r + 4] = Yii
        for rad, Yib in blocks.items():
            b = N + 2 * ids.index(rad)
            Y[4 * r:4 * r + 4, b:b + 2] = Yib
            Y[b:b + 2, 4 * r:4 * r + 4] = Yib.T
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 5.2))
    ax1.spy(np.abs(Y) > 0, markersize=2.5, color="k")
    for x in [4 * r for r in range(1, len(keys) + 1)]:
        ax1.axhline(x - 0.5, color="0.85", lw=0.5), ax1.axvline(x - 0.5, color="0.85", lw=0.5)
    ax1.axhline(N - 0.5, color="tab:red", lw=1), ax1.axvline(N - 0.5, color="tab:red", lw=1)
    ax1.set_title(f"information matrix Y: {len(keys)} aircraft (4×4 blocks), {len(ids)} radar biases",
                  fontsize=9)
    ax1.set_xticks([2 + 4 * r for r in range(len(keys))] + [N + 1 + 2 * j for j in range(len(ids))])
    ax1.set_xticklabels([f"A{k}" for k in keys] + ids, rotation=90, fontsize=6)
    ax1.set_yticks([])
    g = graph.graph.copy()
    g.remove_nodes_from([n for n, d in g.nodes(data=True) if d["kind"] == "reference" and g.degree(n) == 0])
    radars = [n for n, d in g.nodes(data=True) if d["kind"] == "radar"]
    # radars in a row as on the ground; each aircraft above the mean position of the radars that saw it
    pos = {f"radar:{r}": (j, 0.0) for j, r in enumerate(ids)}
    planes = sorted((n for n in g if n not in radars), key=lambda n: np.mean([pos[r][0] for r in g[n]]))
    pos.update({n: (i * (len(ids) - 1) / max(len(planes) - 1, 1), 1.0) for i, n in enumerate(planes)})
    nx.draw_networkx_nodes(g, pos, nodelist=radars, node_color="tab:red", node_shape="s", node_size=260, ax=ax2)
    nx.draw_networkx_nodes(g, pos, nodelist=[n for n in g if n not in radars], node_color="tab:blue",
                           node_size=160, ax=ax2)
    nx.draw_networkx_edges(g, pos, width=0.8, ax=ax2)
    nx.draw_networkx_labels(g, pos, {n: g.nodes[n]["label"] for n in g}, font_size=6, ax=ax2)
    ax2.set_title("coupling graph: an edge = a nonzero Y_ib block", fontsize=9)
    ax2.axis("off")
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    plt.close(fig)


def scaling_figure(bench: Path, out: Path) -> None:
    rows = [json.loads(line) for line in bench.read_text().splitlines() if line.strip()]
    sc = [r for r in rows if r["bench"] == "scaling"]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.4))
    for m, color in zip(sorted({r["radars"] for r in sc}), ("tab:blue", "tab:orange", "tab:green")):
        for name, style, key in (("coupled", "o--", "us_per_plot"), ("coupled-sparse", "s-", "us_per_plot"),
                                 ("coupled-sparse", "^:", "us_per_plot_batch")):
            pts = sorted((r["aircraft"], r[key], r["state_mib"]) for r in sc if r["estimator"] == name
                         and r["radars"] == m)
            if not pts:
                continue
            n, us, mib = zip(*pts)
            label = f"{name}{' update_many' if key.endswith('batch') else ''}, m = {m}"
            ax1.loglog(n, us, style, color=color, label=label, ms=4)
            if key == "us_per_plot":
                ax2.loglog(n, mib, style, color=color, label=f"{name}, m = {m}", ms=4)
    ax1.set_xlabel("aircraft n"), ax1.set_ylabel("µs per plot"), ax1.grid(True, which="both", alpha=0.3)
    ax2.set_xlabel("aircraft n"), ax2.set_ylabel("estimator storage (MiB)"), ax2.grid(True, which="both", alpha=0.3)
    ax1.legend(fontsize=6), ax2.legend(fontsize=6)
    ax1.set_title("time per plot (every radar sees every aircraft)", fontsize=9)
    ax2.set_title("memory", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", type=Path, default=FIG / "sparse_bench.jsonl")
    args = ap.parse_args(argv)
    structure_figure(FIG / "sparse_structure.png")
    if args.bench.exists():
        scaling_figure(args.bench, FIG / "sparse_scaling.png")


if __name__ == "__main__":
    main()

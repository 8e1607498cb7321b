"""The reach sets of System 2's certificate on one instance: the fast plan, the cheapest
path through the cells, the plan repaired from it, and the cells p_T can reach.

    python benchmarks/certify_corridor_figure.py --kind paper --index 27 \
        --out docs/figures/certify_corridor.png

Instances as in ``dualpilot bench certify`` (seed 1; paper instance i has 1 + i mod 10
hulls).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dualpilot.evaluation.certify_bench import instances
from dualpilot.evaluation.instances import SPEC
from dualpilot.model.dynamics import rollout
from dualpilot.system2.certify.planner import PlanCheck, relaxation_of
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import System2Params


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kind", default="paper")
    ap.add_argument("--index", type=int, default=27)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", default="docs/figures/certify_corridor.png")
    args = ap.parse_args()
    found = [inst for kind, inst in instances(30, 20, args.seed, ["grass-15", "shrub"])
             if kind == args.kind and inst.index == args.index]
    if not found:
        raise SystemExit(f"no {args.kind} instance {args.index}")
    inst = found[0]
    params = System2Params()
    fast_planner = FastSystem2(SPEC, params)
    fast = fast_planner.plan(inst.state, inst.hulls, inst.objective, inst.prev_control)
    rel = relaxation_of(SPEC, params, inst.state, inst.hulls, inst.objective,
                        inst.prev_control)
    reach = rel.reach
    if reach is None or reach.empty:
        raise SystemExit("the reach sets are empty: (P2) is infeasible here")
    path = reach.corridor()
    repaired = PlanCheck(SPEC, params, rel, inst.hulls, fast_planner.qp).from_corridor()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 6.4))
    last = np.isfinite(reach.value[-1])
    ii, jj = np.nonzero(last)
    h = reach.cell_m
    ax.scatter(reach.origin[0] + (ii + 0.5) * h, reach.origin[1] + (jj + 0.5) * h, s=0.3,
               color="0.85", label=f"cells p_T can reach ({int(last.sum())})")
    for k, hull in enumerate(inst.hulls):
        v = np.vstack([hull.vertices, hull.vertices[:1]])
        ax.fill(v[:, 0], v[:, 1], color="tab:red", alpha=0.35,
                label="fire hulls" if k == 0 else None)
    if fast.ok:
        ax.plot(fast.states[:, 0], fast.states[:, 1], ".-", ms=3, color="tab:blue",
                label=f"fast plan, cost {fast.cost:.3g}")
    if path is not None:
        ax.plot(path[:, 0], path[:, 1], "k.", ms=2, label="cheapest path through the cells")
    if repaired is not None:
        states = rollout(rel.x0, repaired[1], SPEC.dynamics)
        ax.plot(states[:, 0], states[:, 1], ".-", ms=3, color="tab:purple",
                label=f"repaired from it, cost {repaired[0]:.3g}")
    goal = SPEC.goal.center
    ax.plot(goal[0], goal[1], "*", ms=14, color="tab:green", label="G_o")
    ax.set(xlim=(0, SPEC.area_size_m), ylim=(0, SPEC.area_size_m), aspect="equal",
           xlabel="x (m)", ylabel="y (m)",
           title=f"{args.kind} instance {args.index}: bound's reach sets and corridor")
    ax.legend(loc="lower right", fontsize=7)
    fig.tight_layout()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"fast {fast.cost}, repaired {None if repaired is None else repaired[0]}; wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""System 2 fast in 3-D against 2-D on the same instances: planning time (docs/three_d.md).

Each instance of ``dualpilot.evaluation.instances.make_instance`` (T = 80, the paper's
fronts) is planned in 2-D and in 3-D with its hulls as prisms of three heights: taller
than the band ("tall": the reduction to the 2-D planner), 30.8 m ("low": grass-15's head
fire, passable over) and the two alternating ("mixed"); the UAV at G_o's altitude at rest.
Run under the heavy lock; the machine is shared, so the numbers are medians of one run.

    PYTHONPATH=. .venv/bin/python benchmarks/fast3_speed.py --n 60   (under the heavy lock)
"""

from __future__ import annotations

import argparse
import time

import harness  # the repository on the path (before its packages) and the quantiles
import numpy as np

from dualpilot.evaluation.instances import SPEC, make_instance
from dualpilot.model.altitude import lift_state
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.prism import Prism
from dualpilot.spec import MissionSpec
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import verify_p2_plan

SPEC3 = MissionSpec(dynamics=DynamicsParams(dim=3))
LOW_TOP_M = 30.8  # grass-15's head fire (docs/three_d.md)


def prism_tops(kind: str, n: int) -> list[float]:
    """The tops (m) of ``n`` prisms of ``kind``: "tall", "low" or "mixed" (low, tall, …)."""
    tall = SPEC3.above_ceiling_m
    if kind == "tall":
        return [tall] * n
    if kind == "low":
        return [LOW_TOP_M] * n
    return [LOW_TOP_M if k % 2 == 0 else tall for k in range(n)]


def ms_cells(seconds: list[float]) -> str:
    """A table's "median (ms) | p95 (ms)" cells of planning times given in seconds."""
    q = harness.quantiles(seconds, (50, 95), ndigits=1, scale=1000.0)
    return f"{q['p50']:.1f} | {q['p95']:.1f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=60, help="instances")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    p2, p3 = FastSystem2(SPEC), FastSystem2(SPEC3)
    kinds = ("tall", "low", "mixed")
    times: dict[str, list[float]] = {k: [] for k in ("2-D", *kinds)}
    ok = dict.fromkeys(times, 0)
    over = 0
    for i in range(args.n + 2):  # the first two warm the kernels up
        inst = make_instance(i, args.seed, n_hulls=2 + i % 5)
        p2.reset()
        t = time.perf_counter()
        plan = p2.plan(inst.state, inst.hulls, inst.objective, inst.prev_control)
        if i >= 2:
            times["2-D"].append(time.perf_counter() - t)
            ok["2-D"] += plan.ok
        x3 = lift_state(inst.state, SPEC3.band.goal_z_m)
        u3 = np.append(inst.prev_control, 0.0)
        for kind in kinds:
            prisms = tuple(Prism(h, 0.0, top) for h, top in
                           zip(inst.hulls, prism_tops(kind, len(inst.hulls)), strict=True))
            p3.reset()
            t = time.perf_counter()
            plan3 = p3.plan(x3, prisms, inst.objective, u3)
            if i < 2:
                continue
            times[kind].append(time.perf_counter() - t)
            if plan3.ok:
                verdict = verify_p2_plan(plan3.states, plan3.controls, prisms, SPEC3.dynamics,
                                         SPEC3.clearance_m, SPEC3.d_safe_m, SPEC3.area_size_m,
                                         band=SPEC3.band)
                if not verdict.ok:
                    raise AssertionError(f"instance {i} {kind}: {verdict.reason}")
                ok[kind] += 1
                over += kind != "tall" and float(np.max(plan3.states[:, 2])) > x3[2] + 1.0
    print(f"{args.n} instances (make_instance, seed {args.seed}, 2-6 fronts), T = 80")
    print("| case | median (ms) | p95 (ms) | OK |")
    print("|---|---|---|---|")
    for name, ts in times.items():
        print(f"| {name} | {ms_cells(ts)} | {ok[name]}/{len(ts)} |")
    print(f"3-D plans that climb more than 1 m (low and mixed): {over}")


if __name__ == "__main__":
    main()

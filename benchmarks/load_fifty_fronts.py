"""Planners under load: 50 active fire fronts against 1–9, in one run.

For each instance (``dualpilot.evaluation.instances.make_instance``: the paper's fire
process, a free UAV state), the fast System 2 and System 1 plan once; every
OK plan is checked independently (``dualpilot.evaluation.instances.check_plan``). Prints the
median and p95 wall time per group, the ratio of the medians, and how many
plans were OK and verified.

    .venv/bin/python benchmarks/load_fifty_fronts.py --instances 20 --seed 5
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from dualpilot.evaluation.instances import SPEC, check_plan, make_instance
from dualpilot.system1.planner import System1
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import System2Params


def run(n_instances: int, seed: int) -> None:
    s2 = FastSystem2(SPEC, System2Params())
    groups = {"1-9 fronts": [1 + i % 9 for i in range(n_instances)],
              "50 fronts": [50] * n_instances}
    warm = make_instance(0, seed, 3)
    s2.plan(warm.state, warm.hulls, warm.objective, warm.prev_control)
    names = ("system2", "system1")
    times: dict[str, dict[str, list[float]]] = {g: {n: [] for n in names} for g in groups}
    ok = {g: dict.fromkeys(names, 0) for g in groups}
    verified = {g: dict.fromkeys(names, 0) for g in groups}
    # the groups alternate instance by instance, so both see the same machine load
    for i in range(n_instances):
        for group, counts in groups.items():
            inst = make_instance(i, seed, counts[i])
            s1 = System1(SPEC, rng=np.random.default_rng(np.random.SeedSequence([seed, i])))
            s2.reset()  # no "previous plan" carried over from another instance
            for name, planner, p2 in (("system2", s2, True), ("system1", s1, False)):
                t0 = time.perf_counter()
                plan = planner.plan(inst.state, inst.hulls, inst.objective, inst.prev_control)
                times[group][name].append(time.perf_counter() - t0)
                if plan.ok:
                    ok[group][name] += 1
                    verified[group][name] += check_plan(plan, inst, p2=p2)[0]
    for group in groups:
        for name in names:
            ts = times[group][name]
            print(f"{group:11s} {name}: median {1e3 * float(np.median(ts)):6.1f} ms, "
                  f"p95 {1e3 * float(np.percentile(ts, 95)):6.1f} ms, "
                  f"OK {ok[group][name]}/{len(ts)}, "
                  f"verified {verified[group][name]}/{ok[group][name]}")
    for name in names:
        med = {g: float(np.median(times[g][name])) for g in groups}
        p95 = {g: float(np.percentile(times[g][name], 95)) for g in groups}
        print(f"{name}: 50 fronts / 1-9 fronts = {med['50 fronts'] / med['1-9 fronts']:.2f} "
              f"(median), {p95['50 fronts'] / p95['1-9 fronts']:.2f} (p95)")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--instances", type=int, default=20)
    p.add_argument("--seed", type=int, default=5)
    args = p.parse_args()
    run(args.instances, args.seed)


if __name__ == "__main__":
    main()

"""Handover smoothness of System 1: the paper's LQR ("rrt") vs the Δu-penalising LQR ("rrt+du").

Each seeded instance of :func:`dualpilot.evaluation.instances.make_instance` (UAV state,
hulls) is planned once by each method from the same RRT seed, with u_{t|t}
drawn uniformly in U (|u| ≤ u_max per axis, seeded; the control a System 2
plan may have left). Per OK plan: the first jump ‖u_0 − u_{t|t}‖² and the
plan's energy Σ_k ‖u_k − u_{k−1}‖² (u_{−1} = u_{t|t}, N²), and the planning
time. Prints a markdown table of medians and 95th percentiles.

    .venv/bin/python benchmarks/handover_energy.py [--n 100] [--seed 0] [--r-delta-u R]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from dualpilot.evaluation.instances import SPEC, make_instance
from dualpilot.planners import build_planner
from dualpilot.system1.lqr import R_DELTA_U
from dualpilot.system1.planner import System1Params
from dualpilot.verify import verify_trajectory


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="instances (default 100)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-hulls", type=int, default=6, help="instance i has 1 + i %% this hulls")
    ap.add_argument("--r-delta-u", type=float, default=R_DELTA_U, help="R_Δ of rrt+du")
    args = ap.parse_args()
    u_max = SPEC.dynamics.u_max_n
    methods = ("rrt", "rrt+du")
    rows: dict[str, dict[str, list[float]]] = {
        m: {"jump": [], "energy": [], "time": []} for m in methods}
    ok = dict.fromkeys(methods, 0)
    verified = dict.fromkeys(methods, 0)
    t_start = time.perf_counter()
    draw = np.random.default_rng(np.random.SeedSequence([args.seed, 14]))
    for i in range(args.n):
        inst = make_instance(i, args.seed, 1 + i % args.max_hulls)
        u_prev = draw.uniform(-u_max, u_max, size=2)
        for m in methods:
            params = System1Params(r_delta_u=args.r_delta_u)
            planner = build_planner(1, SPEC, m, params)
            planner.rng = np.random.default_rng(np.random.SeedSequence([args.seed, i]))  # type: ignore[attr-defined]
            plan = planner.plan(inst.state, inst.hulls, inst.objective, u_prev)
            if not plan.ok:
                continue
            ok[m] += 1
            verified[m] += verify_trajectory(plan.states, plan.controls, inst.hulls,
                                             SPEC.dynamics, SPEC.d_safe_m).ok
            du = np.diff(np.vstack([u_prev, plan.controls]), axis=0)
            sq = np.einsum("ij,ij->i", du, du)
            rows[m]["jump"].append(float(sq[0]))
            rows[m]["energy"].append(float(sq.sum()))
            rows[m]["time"].append(plan.compute_time_s)
    elapsed = time.perf_counter() - t_start

    def q(xs: list[float], p: float) -> str:
        return f"{np.percentile(xs, p):.2f}" if xs else "-"

    print(f"{args.n} instances (seed {args.seed}, 1-{args.max_hulls} hulls), u_t|t ~ U[-{u_max:g}, "
          f"{u_max:g}]² N, R_Δ = {args.r_delta_u:g}; {elapsed:.1f} s\n")
    print("| method | OK plans | verify at d_safe | ‖u_0 − u_t\\|t‖² median | p95 "
          "| Σ‖Δu‖² median | p95 | plan time median (ms) |")
    print("|---|---|---|---|---|---|---|---|")
    for m in methods:
        r = rows[m]
        t_ms = f"{1e3 * np.median(r['time']):.1f}" if r["time"] else "-"
        print(f"| {m} | {ok[m]}/{args.n} | {verified[m]}/{ok[m]} | {q(r['jump'], 50)} | "
              f"{q(r['jump'], 95)} | {q(r['energy'], 50)} | {q(r['energy'], 95)} | {t_ms} |")


if __name__ == "__main__":
    main()

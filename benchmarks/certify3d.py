"""System 2's certified method in 3-D against 2-D on the same instances (docs/three_d.md).

The instances of ``dualpilot bench certify`` (``certify_bench.instances``: the paper's
fires, 1-10 hulls, and the fire-behaviour scenarios' at T = 80) are planned with the
method's defaults (tolerance 1 %, 1 s budget) in 2-D and in 3-D with each hull a prism
taller than the band ("tall": the reduction, the UAV at G_o's altitude at rest), and
again with every prism 30.8 m tall ("low": grass-15's head fire, passable over), where the
method's bound is the least over the branches "over or around" (the planar bound on the
footprints a branch keeps plus its altitude's bound; the cheapest verified of the fast
3-D plan and the searches' plans lifted or climbed over); "high", every prism 80 m tall
(passed over only at 105 m or more), and "mixed", taller than the band and 30.8 m
alternating, the same. Per case: the share of instances whose
certified gap at 1 s (the run's trace) is at most 1 %, the median and 90th-percentile wall
time a request, and, tall against 2-D, whether plan, cost and bound are the same.
Run under the heavy lock; the machine is shared, so the numbers are one run's.

    PYTHONPATH=. .venv/bin/python benchmarks/certify3d.py --paper 30 --physics 20
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from dualpilot.evaluation.certify_bench import TARGET, gap_at, instances
from dualpilot.evaluation.instances import SPEC
from dualpilot.model.altitude import lift_state
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.prism import Prism
from dualpilot.plan import Plan
from dualpilot.spec import MissionSpec
from dualpilot.system2.certify.planner import CertifiedSystem2
from dualpilot.system2.problem import verify_p2_plan
from dualpilot.warmup import warm_certificate, warm_up

SPEC3 = MissionSpec(dynamics=DynamicsParams(dim=3))
LOW_TOP_M = 30.8
HIGH_TOP_M = 80.0


def _timed(planner: CertifiedSystem2, *args: object) -> tuple[Plan, float, float]:
    planner.reset()
    t0 = time.perf_counter()
    plan = planner.plan(*args)  # type: ignore[arg-type]
    wall = time.perf_counter() - t0
    gap = gap_at(planner.trace, 1.0) if plan.bound is not None else float("inf")
    return plan, wall, gap


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paper", type=int, default=30)
    ap.add_argument("--physics", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--scenarios", default="grass-15,shrub")
    args = ap.parse_args()
    warm_up()
    warm_certificate()
    p2, p3 = CertifiedSystem2(SPEC), CertifiedSystem2(SPEC3)
    cases: dict[str, tuple[list[float], list[float]]] = {k: ([], []) for k in
                                                          ("2-D", "3-D tall", "3-D low",
                                                           "3-D high", "3-D mixed")}
    same = verified = 0
    rows = instances(args.paper, args.physics, args.seed, args.scenarios.split(","))
    for kind, inst in rows:
        z = SPEC3.band.goal_z_m
        x3, u3 = lift_state(inst.state, z), np.append(inst.prev_control, 0.0)
        flat, wall2, gap2 = _timed(p2, inst.state, inst.hulls, inst.objective,
                                   inst.prev_control)
        tall = tuple(Prism(h, 0.0, SPEC3.above_ceiling_m) for h in inst.hulls)
        low = tuple(Prism(h, 0.0, LOW_TOP_M) for h in inst.hulls)
        a, wall3, gap3 = _timed(p3, x3, tall, inst.objective, u3)
        b, wall_low, gap_low = _timed(p3, x3, low, inst.objective, u3)
        high = tuple(Prism(h, 0.0, HIGH_TOP_M) for h in inst.hulls)
        mixed = tuple(t if i % 2 else lo for i, (t, lo) in enumerate(zip(tall, low,
                                                                        strict=True)))
        c, wall_high, gap_high = _timed(p3, x3, high, inst.objective, u3)
        d, wall_mixed, gap_mixed = _timed(p3, x3, mixed, inst.objective, u3)
        for name, gap, wall in (("2-D", gap2, wall2), ("3-D tall", gap3, wall3),
                                ("3-D low", gap_low, wall_low),
                                ("3-D high", gap_high, wall_high),
                                ("3-D mixed", gap_mixed, wall_mixed)):
            cases[name][0].append(gap)
            cases[name][1].append(wall)
        same += int(a.ok and flat.ok and a.cost == flat.cost and a.bound == flat.bound
                    and np.array_equal(a.states[:, [0, 1, 3, 4]], flat.states))
        for plan, prisms in ((a, tall), (b, low), (c, high), (d, mixed)):
            if plan.ok:
                verified += int(verify_p2_plan(plan.states, plan.controls, prisms,
                                               SPEC3.dynamics, SPEC3.clearance_m,
                                               SPEC3.d_safe_m, SPEC3.area_size_m,
                                               band=SPEC3.band).ok)
        print(f"{kind:9s} {inst.index:3d} hulls {inst.n_hulls:2d}  gap@1s 2-D {gap2:.4%} "
              f"3-D tall {gap3:.4%}  low {gap_low:.4%}  high {gap_high:.4%}  mixed "
              f"{gap_mixed:.4%}  wall {wall2:.3f} {wall3:.3f} {wall_low:.3f} {wall_high:.3f} "
              f"{wall_mixed:.3f} s", flush=True)
    n = len(rows)
    for name, (gaps, walls) in cases.items():
        share = sum(g <= TARGET for g in gaps) / n
        print(f"{name:9s}: gap <= 1 % at 1 s on {share:.0%} of {n}; wall median "
              f"{np.median(walls):.3f} s, p90 {np.quantile(walls, 0.9):.3f} s")
    print(f"3-D tall = 2-D (plan, cost, bound): {same}/{n}; 3-D plans verified in 3-D: "
          f"{verified} of {4 * n}")


if __name__ == "__main__":
    main()

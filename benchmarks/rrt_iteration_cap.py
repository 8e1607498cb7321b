"""Iteration-cap measurement for Alg. 1 (dualpilot.system1.rrt) and System1.plan timing.

Instances: Sec. IV-A area/goal; 1-6 fire fronts born uniformly in the area and
advanced 0-60 sub-steps (0-30 s, no extinction) by FireFront.advance; start
(50,50) for even instance ids, uniform in the area for odd ones (redrawn until
it keeps 25 m from every hull). Each instance is run once with a huge cap;
because the samples come from our rng only, the run with cap N is a prefix of
it, so fail rate(N) = share of instances needing > N iterations. Two variants:
plain Alg. 1, and ours, whose samples follow the grid corridor after the
paper's 500 (dualpilot.system1.rrt, "Narrow passages").
"""

import sys

import numpy as np

from dualpilot.model.dynamics import hover_state
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.spec import MissionSpec
from dualpilot.system1.planner import System1
from dualpilot.system1.rrt import RrtParams, SegmentChecker, plan_path

SPEC = MissionSpec()
goal = SPEC.goal
CLEAR = SPEC.clearance_m


def instance(i):
    rng = np.random.default_rng(10_000 + i)
    ff = FireField(FireParams())
    for _ in range(int(rng.integers(1, 7))):
        ff.spawn(rng, 0)
    n_sub = int(rng.integers(0, 61))
    ff.fronts = [f for f in ff.fronts]
    for _ in range(n_sub):
        ff.fronts = [f.advance(rng, ff.params) for f in ff.fronts]
    hulls = ff.snapshot().hulls
    ch = SegmentChecker(hulls)
    start = np.array([50.0, 50.0])
    if i % 2 == 1 or ch.point_distance(start) < CLEAR:
        for _ in range(1000):
            start = rng.uniform(0, SPEC.area_size_m, 2)
            if ch.point_distance(start) >= CLEAR and not goal.contains(start, CLEAR):
                break
    return hulls, start, ch


def cap_table(n: int, params: RrtParams, label: str) -> None:
    """Fail rates at several caps for one RRT variant (each instance run once, 20 000 cap)."""
    iters_l, found_l, blocked_l, t_rrt_l = [], [], [], []
    for i in range(n):
        hulls, start, ch = instance(i)
        r = plan_path(start, goal, hulls, np.random.default_rng(i), CLEAR, SPEC.area_size_m,
                      params, checker=ch)
        iters_l.append(r.iterations)
        found_l.append(r.found)
        t_rrt_l.append(r.time_s)
        blocked_l.append(not ch.clear(start[None], goal.center[None], CLEAR)[0])
    iters, found = np.array(iters_l), np.array(found_l)
    blocked, t_rrt = np.array(blocked_l), np.array(t_rrt_l)
    print(
        f"[{label}] instances {n}, direct line blocked in {blocked.sum()}, "
        f"no path even at 20000: {(~found).sum()}"
    )
    for cap in (500, 750, 1000, 1500, 2000, 3000, 5000):
        fail = (~found) | (iters > cap)
        print(
            f"cap {cap:5d}: fail {fail.mean():.3f} (all), {fail[blocked].mean():.3f} (blocked),"
            f" {fail[found].mean():.3f} (solvable)"
        )
    it = iters[found]
    print(
        f"iterations when found: median {np.median(it):.0f} p95 {np.percentile(it, 95):.0f}"
        f" max {it.max()}"
    )
    print(
        f"rrt time when found: median {np.median(t_rrt[found]):.3f} s"
        f" p95 {np.percentile(t_rrt[found], 95):.3f} s"
    )


def main(n: int) -> None:
    # Plain Alg. 1 (no corridor guidance) and ours (guided after the paper's 500 samples). A
    # run with a smaller cap is a prefix of the 20 000 run in both: the guidance starts at
    # sample 500 whatever the cap.
    cap_table(n, RrtParams(max_iterations=20_000, max_cpu_s=60.0, try_direct=False,
                           guide_after=20_000), "plain")
    cap_table(n, RrtParams(max_iterations=20_000, max_cpu_s=60.0, try_direct=False), "guided")
    # System1.plan with the defaults, first plan from a hover state
    times: list[float] = []
    statuses: dict[str, int] = {}
    for i in range(n):
        hulls, start, _ = instance(i)
        pl = System1(SPEC, rng=np.random.default_rng(i)).plan(hover_state(start), hulls)
        times.append(pl.compute_time_s)
        statuses[pl.status.value] = statuses.get(pl.status.value, 0) + 1
    t = np.array(times)
    print(
        f"System1.plan (defaults): {statuses} median {np.median(t):.3f} s"
        f" p95 {np.percentile(t, 95):.3f} s max {t.max():.3f} s"
    )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200)

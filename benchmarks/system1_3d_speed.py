"""System 1 in 3-D against 2-D on the same instances: planning time (docs/three_d.md).

Each instance of ``dualpilot.evaluation.instances.make_instance`` (T = 80, the paper's
fronts, 1-10 of them as ``dualpilot bench system1`` cycles them) is planned by System 1
(RRT, shortcut, LQR) in 2-D and in 3-D with its hulls as prisms of three heights: taller
than the band ("tall"), 30.8 m ("low": grass-15's head fire, passable over) and the two
alternating ("mixed"); the UAV at G_o's altitude at rest; under both readings of
``s1_altitude`` ("slice-first", the default, and "volume"). Every OK plan is checked by
``verify_trajectory`` (Eq. (1), limits, the band, d_safe from every prism). Each planner
draws from its own seeded stream, the same for 2-D and 3-D. Wall time from state in to
plan out; one run on a shared machine, so the numbers are medians of one run.

    PYTHONPATH=. .venv/bin/python benchmarks/system1_3d_speed.py --n 100  (under the heavy lock)
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from fast3_speed import SPEC3, ms_cells, prism_tops  # the same prisms as System 2's benchmark

from dualpilot.evaluation.instances import SPEC, Instance, make_instance
from dualpilot.model.altitude import lift_state
from dualpilot.model.prism import Prism
from dualpilot.model.vertical import S1Altitude
from dualpilot.plan import Plan
from dualpilot.system1.planner import System1, System1Params
from dualpilot.verify import verify_trajectory

KINDS = ("tall", "low", "mixed")
READINGS: tuple[S1Altitude, ...] = ("slice-first", "volume")


def _rng(seed: int, index: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([seed, index, 1]))


def _timed(planner: System1, state: np.ndarray, obstacles: tuple[object, ...],
           inst: Instance, prev: np.ndarray) -> tuple[Plan | None, float]:
    t = time.perf_counter()
    try:
        plan = planner.plan(state, obstacles, inst.objective, prev)  # type: ignore[arg-type]
    except ValueError:  # an invalid start (inside a front's clearance): as bench system1
        plan = None
    return plan, time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="instances")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    cases = ["2-D", *(f"3-D {kind}, {reading}" for reading in READINGS for kind in KINDS)]
    times: dict[str, list[float]] = {c: [] for c in cases}
    ok = dict.fromkeys(cases, 0)
    climbed = dict.fromkeys(cases, 0)
    for i in range(args.n + 2):  # the first two warm up (imports, OMPL, the kernels)
        inst = make_instance(i, args.seed, n_hulls=1 + i % 10)
        plan, wall = _timed(System1(SPEC, rng=_rng(args.seed, i)), inst.state, inst.hulls,
                            inst, inst.prev_control)
        if i >= 2:
            times["2-D"].append(wall)
            ok["2-D"] += plan is not None and plan.ok
        x3 = lift_state(inst.state, SPEC3.band.goal_z_m)
        u3 = np.append(inst.prev_control, 0.0)
        for reading in READINGS:
            params = System1Params(altitude=reading)
            for kind in KINDS:
                prisms = tuple(Prism(h, 0.0, top) for h, top in
                               zip(inst.hulls, prism_tops(kind, len(inst.hulls)), strict=True))
                planner = System1(SPEC3, params, rng=_rng(args.seed, i))
                plan3, wall = _timed(planner, x3, prisms, inst, u3)
                if i < 2:
                    continue
                case = f"3-D {kind}, {reading}"
                times[case].append(wall)
                if plan3 is None or not plan3.ok:
                    continue
                verdict = verify_trajectory(plan3.states, plan3.controls, prisms,
                                            SPEC3.dynamics, SPEC3.d_safe_m, band=SPEC3.band)
                if not verdict.ok:
                    raise AssertionError(f"instance {i} {case}: {verdict.reason}")
                ok[case] += 1
                climbed[case] += float(np.max(np.abs(plan3.states[:, 2] - x3[2]))) > 1.0
    print(f"{args.n} instances (make_instance, seed {args.seed}, 1-10 fronts), T = 80")
    print("| case | median (ms) | p95 (ms) | OK | left the start's altitude by > 1 m |")
    print("|---|---|---|---|---|")
    for name, ts in times.items():
        print(f"| {name} | {ms_cells(ts)} | {ok[name]}/{len(ts)} | "
              f"{climbed[name] if name != '2-D' else '-'} |")


if __name__ == "__main__":
    main()

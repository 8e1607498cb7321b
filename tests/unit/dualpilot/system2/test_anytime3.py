"""System 2's "fast+exact" in 3-D: the fast plan, then native SCIP seeded with it (docs/three_d.md,
6). SCIP's (P2) in 3-D (each prism's every face, tightest big-M over the reach box cut to the
band) is held to the compiled exact method's optimum, a formulation of its own."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.mission.monitor import check
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.model.geometry import Rect
from dualpilot.model.prism import Prism
from dualpilot.plan import Objective
from dualpilot.spec import MissionSpec
from dualpilot.system2.exact import ExactSystem2
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import System2Params, verify_p2_plan
from dualpilot.system2.scip import SeededExactSystem2

SPEC3 = MissionSpec(dynamics=DynamicsParams(dim=3))
SPEC2 = MissionSpec()
PARAMS = System2Params(horizon=20, max_hulls=2, max_faces=4)
X0 = np.array([100.0, 100.0, 50.0, 4.0, -2.0, 0.0])
U_PREV = np.array([1.0, -0.5, 0.0])
RECTS = (Rect(260.0, 260.0, 100.0, 100.0), Rect(420.0, 180.0, 80.0, 120.0))


def _cuboids(top: float) -> tuple[Prism, ...]:
    return tuple(Prism.cuboid(r, 0.0, top) for r in RECTS)


@pytest.mark.parametrize("top", [30.0, pytest.param(SPEC3.above_ceiling_m,
                                                     marks=pytest.mark.slow)])  # 8 s
def test_seeded_scip_gives_the_compiled_optimum_in_3d(top: float) -> None:
    """Over 30 m cuboids (passed over) and cuboids taller than the ceiling (around, the
    2-D optimum): the same optimum as the compiled MIQP, seeded with the fast plan or not."""
    hulls = _cuboids(top)
    exact = ExactSystem2(SPEC3, PARAMS).plan(X0, hulls, Objective.MISSION_TIME, U_PREV)
    fast = FastSystem2(SPEC3, PARAMS).plan(X0, hulls, Objective.MISSION_TIME, U_PREV)
    assert exact.ok and fast.ok and exact.info["optimal"] and exact.cost is not None
    seeded = SeededExactSystem2(SPEC3, PARAMS)
    for incumbent in (None, fast.controls):
        plan = seeded.plan(X0, hulls, Objective.MISSION_TIME, U_PREV, incumbent)
        assert plan.ok and plan.info["optimal"], plan.message
        assert plan.cost == pytest.approx(exact.cost, rel=1e-5)
        assert plan.states.shape == (21, 6)
        assert verify_p2_plan(plan.states, plan.controls, hulls, SPEC3.dynamics,
                              SPEC3.clearance_m, SPEC3.d_safe_m, SPEC3.area_size_m, tol=1e-3,
                              band=SPEC3.band).ok
        assert check(plan, X0, hulls, SPEC3).ok
    climbs = float(exact.states[:, 2].max()) > 54.0
    assert climbs == (top == 30.0)
    if top > SPEC3.band.ceiling_m:  # the top-down evaluation: the 2-D optimum
        flat = SeededExactSystem2(SPEC2, PARAMS).plan(X0[[0, 1, 3, 4]],
                                                      tuple(r.polytope() for r in RECTS),
                                                      Objective.MISSION_TIME, U_PREV[:2])
        assert flat.ok and flat.cost == pytest.approx(exact.cost, rel=1e-5)


@pytest.mark.slow  # a worker process of its own
def test_fast_plus_exact_plans_in_3d_and_keeps_the_better_verified_plan() -> None:
    from dualpilot.system2.anytime import AnytimeSystem2

    hulls = _cuboids(30.0)
    planner = AnytimeSystem2(SPEC3, PARAMS, exact_budget_s=20.0)
    try:
        plan = planner.plan(X0, hulls, Objective.MISSION_TIME, U_PREV)
    finally:
        planner.close()
    assert plan.ok and plan.states.shape == (21, 6)
    fast_cost = plan.info["fast_cost"]
    assert isinstance(fast_cost, float) and plan.cost is not None and plan.cost <= fast_cost
    assert check(plan, X0, hulls, SPEC3).ok
    with pytest.raises(ValueError, match="3-D under speed_limit = 'axis' only"):
        AnytimeSystem2(MissionSpec(dynamics=DynamicsParams(dim=3, speed_limit="norm")), PARAMS)

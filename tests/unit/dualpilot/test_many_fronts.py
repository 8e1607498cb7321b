"""50 fire fronts at once: every plan passes the independent checks or says why not."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.evaluation.instances import SPEC, check_plan, make_instance
from dualpilot.plan import PlanStatus
from dualpilot.system1.planner import System1
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import System2Params

INSTANCES = [make_instance(i, 5, 50) for i in (0, 4)]  # quick to draw (≈ 2–3 s each)


@pytest.mark.parametrize("index", range(len(INSTANCES)))
def test_system2_plans_verified_among_fifty_fronts(index: int) -> None:
    inst = INSTANCES[index]
    assert len(inst.hulls) == 50
    plan = FastSystem2(SPEC, System2Params()).plan(inst.state, inst.hulls, inst.objective,
                                                   inst.prev_control)
    assert plan.status is PlanStatus.OK, plan.message
    ok, why = check_plan(plan, inst)
    assert ok, why


@pytest.mark.parametrize("index", range(len(INSTANCES)))
def test_system1_among_fifty_fronts_never_returns_an_unchecked_plan(index: int) -> None:
    inst = INSTANCES[index]
    plan = System1(SPEC, rng=np.random.default_rng(index)).plan(inst.state, inst.hulls)
    if plan.ok:
        ok, why = check_plan(plan, inst, p2=False)
        assert ok, why
    else:
        # the fronts cover G's surroundings: the grid proves it instead of 2000 samples
        assert plan.status is PlanStatus.NO_PATH
        assert plan.info["rrt_status"] == "unreachable" and plan.info["rrt_iterations"] == 0

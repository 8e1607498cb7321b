"""50 fire fronts at once: every plan passes the independent checks or says why not."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.bench import GOAL, check_plan, make_instance
from dualpilot.model.dynamics import DynamicsParams
from dualpilot.plan import PlanStatus
from dualpilot.system1.planner import System1
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import System2Params

DYN = DynamicsParams()
INSTANCES = [make_instance(i, 5, 50) for i in (0, 4)]  # quick to draw (≈ 2–3 s each)


@pytest.mark.parametrize("index", range(len(INSTANCES)))
def test_system2_plans_verified_among_fifty_fronts(index: int) -> None:
    inst = INSTANCES[index]
    assert len(inst.hulls) == 50
    params = System2Params()
    plan = FastSystem2(GOAL, params, DYN).plan(inst.state, inst.hulls, inst.objective,
                                               inst.prev_control)
    assert plan.status is PlanStatus.OK, plan.message
    ok, why = check_plan(plan, inst, DYN, params.epsilon_m)
    assert ok, why


@pytest.mark.parametrize("index", range(len(INSTANCES)))
def test_system1_among_fifty_fronts_never_returns_an_unchecked_plan(index: int) -> None:
    inst = INSTANCES[index]
    plan = System1(GOAL, np.random.default_rng(index)).plan(inst.state, inst.hulls)
    if plan.ok:
        ok, why = check_plan(plan, inst, DYN, None)
        assert ok, why
    else:
        # the fronts cover G's surroundings: the grid proves it instead of 2000 samples
        assert plan.status is PlanStatus.NO_PATH
        assert plan.info["rrt_status"] == "unreachable" and plan.info["rrt_iterations"] == 0

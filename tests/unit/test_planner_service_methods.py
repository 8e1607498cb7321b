"""A planner service refuses a risk-aware method: a plan request over the bus has no forecast."""

from __future__ import annotations

import pytest

from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
from services.common.planning import PlannerService


@pytest.mark.parametrize(("system", "method"), [(1, "rrt+risk"), (1, "rrt+du+risk"),
                                                (2, "fast+risk")])
def test_a_risk_aware_method_is_refused_with_a_clear_error(system: int, method: str) -> None:
    service = PlannerService(system, lambda spec, m: build_planner(system, spec, m), "u")
    with pytest.raises(ValueError, match="plans on the fire forecast"):
        service.prepare("m1", MissionSpec(seed=3), method)
    assert "m1" not in service.missions


@pytest.mark.parametrize(("system", "method"), [(1, "rrt"), (2, "fast")])
def test_a_paper_method_is_prepared(system: int, method: str) -> None:
    service = PlannerService(system, lambda spec, m: build_planner(system, spec, m), "u")
    assert service.prepare("m1", MissionSpec(seed=3), method).method == method

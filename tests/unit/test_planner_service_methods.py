"""A planner service refuses a risk-aware method: a plan request over the bus has no forecast."""

from __future__ import annotations

import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
from services.common.planning import PlannerService


def service(system: int) -> PlannerService:
    return PlannerService(system, lambda spec, c: build_planner(
        system, spec, c.methods()[system], risk=c.risk), "u")


@pytest.mark.parametrize(("system", "controller"), [(1, "cc+risk"), (1, "concurrent+risk"),
                                                    (2, "s2+risk")])
def test_a_risk_aware_method_is_refused_with_a_clear_error(system: int, controller: str) -> None:
    s = service(system)
    with pytest.raises(ValueError, match="plans on the fire forecast"):
        s.prepare("m1", MissionSpec(seed=3), MissionConfig.named(controller, seed=3))
    assert "m1" not in s.missions


@pytest.mark.parametrize(("system", "controller", "method"), [(1, "cc", "rrt"),
                                                              (1, "concurrent", "rrt+du"),
                                                              (2, "s2", "fast")])
def test_a_paper_method_is_prepared(system: int, controller: str, method: str) -> None:
    config = MissionConfig.named(controller, seed=3)
    held = service(system).prepare("m1", MissionSpec(seed=3), config)
    assert held.config == config and held.planner.method == method

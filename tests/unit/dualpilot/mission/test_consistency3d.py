"""The 3-D world consistent with the top-down evaluation, step by step (docs/three_d.md).

With every cuboid taller than the ceiling (``fire_height = above-ceiling``) and the start
and G_o at one altitude, a 3-D mission is the 2-D mission: the step's d_t, the failure
rules, the fires, the decisions, the checks and the records give the 2-D numbers, the
altitude 50 m, the climb and the vertical force 0 throughout. Shown here for the part of
the mission the world alone decides: missions flown by braking only (no planner), and
missions whose planners are the 2-D planners under the reduction every 3-D planner tests
for first (tests/support/lifted.py), on the paper's process and two scenarios.
"""

from __future__ import annotations

import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import LocalFires, LocalPlanners, LocalVehicle, local_mission
from dualpilot.mission.result import MissionResult
from dualpilot.mission.step import Mission, MissionPorts
from dualpilot.model.altitude import lift_state, planar_state
from dualpilot.model.dynamics import hover_state
from dualpilot.plan import Planner
from dualpilot.planners import build_planner
from tests.support.lifted import LiftedPlanner, assert_same_mission

SCENARIOS = ("paper", "grass-5", "shrub")
THREE_D = {"dim": 3, "fire_height": "above-ceiling"}


def _pair(name: str, seed: int, scenario: str, max_steps: int = 150) -> tuple[
        MissionConfig, MissionConfig]:
    flat = MissionConfig.named(name, seed=seed, settings=(("scenario", scenario),
                                                          ("max_steps", max_steps)))
    return flat, flat.with_settings(THREE_D)


def _braking(config: MissionConfig, velocity: tuple[float, float]) -> MissionResult:
    """``config``'s mission flown by braking alone from ``velocity`` (m/s) at its start."""
    spec = config.spec()
    state = hover_state(spec.start_position, spec.dynamics)
    state[spec.dim: spec.dim + 2] = velocity
    reading = config.reading()
    fires = LocalFires(spec, reading.fire, config.forecast,
                       reading.altitude.fire_heights(spec, reading.fire.scenario))
    ports = MissionPorts(fires, LocalPlanners({}), LocalVehicle(state, spec.dynamics))
    return Mission(config, spec, ports, state).run()


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_braking_missions_in_3d_are_the_2d_missions(scenario: str) -> None:
    for seed in range(3):
        flat, tall = _pair("cc", seed, scenario, max_steps=40)
        a = _braking(flat, (12.0, 9.0))
        assert_same_mission(a, _braking(tall, (12.0, 9.0)))
        assert planar_state(lift_state(a.records[-1].state, 50.0)).tolist() == \
            a.records[-1].state.tolist()


def _lifted(config: MissionConfig, flat: MissionConfig) -> dict[int, Planner]:
    """The 2-D planners of ``flat``'s mission, as planners of ``config``'s 3-D mission."""
    spec2, spec3 = flat.spec(), config.spec()
    methods = flat.methods()
    return {s: LiftedPlanner(build_planner(s, spec2, methods[s], flat.system2_params() if s == 2
                                           else None, flat.risk), spec3)  # type: ignore
            for s in flat.systems()}


def flown_pair(name: str, seed: int, scenario: str) -> tuple[MissionResult, MissionResult]:
    """Seed ``seed``'s 2-D mission of ``name`` on ``scenario``, and its 3-D mission (fires
    above the ceiling) flown by the same 2-D planners under the reduction."""
    flat, tall = _pair(name, seed, scenario)
    a = local_mission(flat).run()
    b = local_mission(tall, planners=_lifted(tall, flat)).run()
    return a, b


def _flown(name: str, seed: int, scenario: str) -> None:
    assert_same_mission(*flown_pair(name, seed, scenario))


@pytest.mark.parametrize(("name", "scenario", "seed"), [
    ("cc", "paper", 7),  # 31 steps, both systems, caught while System 2 plans
    ("s1", "grass-5", 1),  # 97 steps to G
    ("s2", "shrub", 5),  # 40 steps, a braking step, fire contact in flight
    ("cc+risk", "paper", 2)])
def test_missions_of_the_2d_planners_reduced_are_the_2d_missions(name: str, scenario: str,
                                                                 seed: int) -> None:
    _flown(name, seed, scenario)


#: the controllers whose 2-D planners fly under the reduction, and the seeds ``make test``
#: flies of each (the 40-seed sweep: ``benchmarks/consistency3d.py``, docs/three_d.md)
LIFTED = ("cc", "s1", "s2", "cc+risk")
SEEDS = (0, 1)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", SCENARIOS)
@pytest.mark.parametrize("name", LIFTED)
def test_missions_of_each_controller_and_scenario(name: str, scenario: str) -> None:
    for seed in SEEDS:
        _flown(name, seed, scenario)

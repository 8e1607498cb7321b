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
from dualpilot.mission.local import LocalFires, LocalPlanners, LocalVehicle
from dualpilot.mission.result import MissionResult
from dualpilot.mission.step import Mission, MissionPorts
from dualpilot.model.altitude import lift_state, planar_state
from dualpilot.model.dynamics import hover_state
from tests.support.lifted import LIFTED, SCENARIOS, assert_same_mission, config_pair, flown_pair


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
        flat, tall = config_pair("cc", seed, scenario, max_steps=40)
        a = _braking(flat, (12.0, 9.0))
        assert_same_mission(a, _braking(tall, (12.0, 9.0)))
        assert planar_state(lift_state(a.records[-1].state, 50.0)).tolist() == \
            a.records[-1].state.tolist()


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


#: the seeds ``make test`` flies of each controller under the reduction (the 40-seed sweep:
#: ``benchmarks/consistency3d.py``, docs/three_d.md)
SEEDS = (0, 1)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", SCENARIOS)
@pytest.mark.parametrize("name", LIFTED)
def test_missions_of_each_controller_and_scenario(name: str, scenario: str) -> None:
    for seed in SEEDS:
        _flown(name, seed, scenario)

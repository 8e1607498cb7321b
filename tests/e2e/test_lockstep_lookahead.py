"""The lookahead supervisor through the stack: the in-process mission, step for step.

The supervisor process runs the lookahead supervisor
(dualpilot/supervisor/lookahead/planning.py); its known future is the EWS's forecast of
each step's fire state, asked over the wire, and its space-time plans are its own. Three
seeds of each physics scenario of the yardstick's tables
(grass-5, grass-15, shrub), paper timing, flown through the stack (a shared router, EWS and
planner pair; a uavsim and a supervisor per vehicle, unpaced) and in-process given the
vehicle's measurements (tests/e2e/test_lockstep.py's ``ReplayedStates``, as for every
risk-aware controller on physics fires: a float32 step of the measured state decides
near-ties between plans): identical records (tests/e2e/test_lockstep.py's comparison), a
forecast received at every step that asked for one, and no forecast_stale fault.

The default mission (``make run``, ``docker compose up``: lookahead+risk, seed 7, today's
reading) flies the same way, and reaches the goal.
"""

from __future__ import annotations

from typing import Any

import pytest

from dualpilot.mission.config import DEFAULT_MISSION
from dualpilot.mission.result import Ending
from tests.e2e.test_lockstep import (
    assert_same_mission,
    config_of,
    fly,
    forecasts_in,
    replaying_states,
    twin_of,
    unpaced_fleet,
)

pytestmark = [pytest.mark.slow, pytest.mark.timeout(900)]

SEEDS = (0, 1, 2)
SCENARIOS = ("grass-5", "grass-15", "shrub")


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Any:
    with unpaced_fleet(tmp_path_factory, "lockstep-lookahead", "la", len(SEEDS)) as f:
        yield f


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_the_lookahead_supervisor_flies_the_in_process_mission_through_the_stack(
        fleet: Any, scenario: str) -> None:
    f, out = fleet
    runs = [(seed, "lookahead+risk", "paper", None, scenario) for seed in SEEDS]
    for run, got in fly(f, runs, out, replaying_states).items():
        received, stale = forecasts_in(got.run_dir)
        assert received > 0 and stale == 0, (run, received, stale)
        assert_same_mission(got.result, twin_of(got), str(run))


def test_the_default_mission_reaches_the_goal_through_the_stack(fleet: Any) -> None:
    """The README's first run (DEFAULT_MISSION: what make run and docker compose up fly)
    reaches G through the stack, step for step its in-process twin (dualpilot mission)."""
    f, out = fleet
    run = (DEFAULT_MISSION.seed, DEFAULT_MISSION.controller_name, DEFAULT_MISSION.timing.value,
           None)
    assert config_of(*run) == DEFAULT_MISSION  # today's reading, no other setting
    got = fly(f, [run], out, replaying_states)[run]
    received, stale = forecasts_in(got.run_dir)
    assert received > 0 and stale == 0, (received, stale)
    assert got.result.ending is Ending.GOAL, got.result.ending
    assert_same_mission(got.result, twin_of(got), str(run))

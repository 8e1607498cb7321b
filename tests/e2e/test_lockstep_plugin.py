"""The example plug-in through the stack: the in-process mission, step for step.

The example package (examples/dualpilot-example, installed by make setup) adds the
supervisor "proximity" and the System 1 method "straight" through entry points. Flown
through the stack (a shared router, EWS and planner pair; a uavsim and a supervisor per
vehicle, unpaced), the supervisor process finds "proximity" by the name its environment
gives (CONTROLLER), the System 1 service builds "straight" by the name the mission's
configuration carries on the wire, and the EWS and both planner services accept a
configuration naming a supervisor they have installed. Three seeds, paper timing: the
records are the in-process mission's (tests/e2e/test_lockstep.py's comparison), and the
straight line's plans are among those flown.
"""

from __future__ import annotations

from typing import Any

import pytest

from dualpilot.planners import method_names
from tests.e2e.test_lockstep import assert_same_mission, fly, in_process, twin_of, unpaced_fleet

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]

#: seeds on which the in-process "proximity" mission flies 53 to 77 steps, both systems in
#: control at some step
SEEDS = (0, 2, 3)


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Any:
    assert "straight" in method_names(1), "the example package is not installed: make setup"
    with unpaced_fleet(tmp_path_factory, "lockstep-plugin", "px", len(SEEDS)) as f:
        yield f


def test_the_example_plugin_flies_the_in_process_mission_through_the_stack(fleet: Any) -> None:
    f, out = fleet
    runs = [(seed, "proximity", "paper", None) for seed in SEEDS]
    flown = fly(f, runs, out, lambda run, run_dir: in_process(run), from_records=False)
    for run, got in flown.items():
        assert_same_mission(got.result, twin_of(got), str(run))
        straight = [r for r in got.result.records if r.info.get("planner") == "straight"]
        assert straight and all(r.system == 1 for r in straight), run
        assert {r.decision.system for r in got.result.records} == {1, 2}, run

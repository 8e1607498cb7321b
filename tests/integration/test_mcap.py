"""mission.mcap of an in-process mission read back with the ``mcap`` library, step for step
against the mission's steps.jsonl (written by the supervisor's StepLog)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import local_mission
from dualpilot.mission.params import Controller
from dualpilot.mission.records import StepLog, read_step_log, result_from_log, write_all
from dualpilot.mission.result import MissionResult

from .foxglove_check import compare_with_log, read_mcap

pytestmark = pytest.mark.timeout(240)


def fly(controller: Controller, seed: int, out: Path, max_steps: int = 150) -> MissionResult:
    """Fly in-process; write steps.jsonl as the supervisor does, then the end-of-run records."""
    mission = local_mission(MissionConfig(controller=controller, seed=seed,
                                          settings=(("max_steps", max_steps),)))
    s = mission.spec
    with StepLog(out / "steps.jsonl") as steps:
        steps.write("mission", controller=controller.value, seed=seed, timing="paper",
                    start=list(s.start), area_size_m=s.area_size_m,
                    goal=[s.goal.center_x, s.goal.center_y, s.goal.width, s.goal.height])
        for record in iter(mission.step, None):
            steps.step(record)
        r = mission.result
        steps.write("end", success=r.success, failure_cause=r.failure_cause, steps=r.steps,
                    final_state=[float(v) for v in np.asarray(r.final_state)])
    write_all(r, out, uav="uav3")
    return r


@pytest.mark.parametrize(("controller", "seed"), [(Controller.CC, 26), (Controller.S1, 3)])
def test_mission_mcap_equals_steps_jsonl(controller: Controller, seed: int,
                                         tmp_path: Path) -> None:
    result = fly(controller, seed, tmp_path)
    entries = read_step_log(tmp_path / "steps.jsonl")
    rec = read_mcap(tmp_path / "mission.mcap")
    assert compare_with_log(rec, entries, "uav3") == len(result.records) > 5
    assert rec.schemas == {
        "/uav3/tf": ("foxglove.FrameTransform", "protobuf"),
        "/uav3/area": ("foxglove.SceneUpdate", "protobuf"),
        "/uav3/fires": ("foxglove.SceneUpdate", "protobuf"),
        "/uav3/plan/system1": ("foxglove.SceneUpdate", "protobuf"),
        "/uav3/plan/system2": ("foxglove.SceneUpdate", "protobuf"),
        "/uav3/path": ("foxglove.SceneUpdate", "protobuf"),
        "/uav3/uav": ("foxglove.SceneUpdate", "protobuf"),
        "/uav3/decision": ("dualpilot.Decision", "jsonschema"),
        "/uav3/events": ("foxglove.Log", "protobuf"),
    }  # no forecast: the records keep none
    assert rec.metadata["mission"] == {
        "uav": "uav3", "controller": controller.value, "seed": str(seed), "timing": "paper",
        "success": str(result.success).lower(), "failure_cause": result.failure_cause,
        "steps": str(result.steps)}
    # the simulated clock: each step starts where the last one's planning and flight ended
    # (fire sub-steps of T_f = 0.5 s, ΔT = 1 s)
    steps = [e for e in entries if e["kind"] == "step"]
    for a, b in zip(steps, steps[1:], strict=False):
        assert b["time_s"] == pytest.approx(a["time_s"] + 0.5 * a["fire_substeps"] + 1.0)
    last_log_ns = max(t for msgs in rec.messages.values() for t, _ in msgs)
    assert last_log_ns == round(result.sim_time_s * 1e9)
    end = rec.messages["/uav3/events"][-1][1].message
    assert end.startswith(f"mission ended after {result.steps} steps")


def test_a_resumed_record_keeps_the_clock(tmp_path: Path) -> None:
    """A mission rebuilt from steps.jsonl (a restarted supervisor) keeps each step's time."""
    result = fly(Controller.CC, 26, tmp_path, max_steps=8)
    again = result_from_log(read_step_log(tmp_path / "steps.jsonl"))
    assert [r.time_s for r in again.records] == [r.time_s for r in result.records]
    mission = local_mission(MissionConfig(seed=26))
    mission.resume(again)
    last = result.records[-1]
    assert mission.sim_time_s == last.time_s + 0.5 * last.fire_substeps + 1.0

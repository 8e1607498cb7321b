"""The stack's observer of the mission step in this process (services/supervisor/observer.py).

A mission flown by the session with the stack in this process
(tests/support/stack.py); the observer writes each step's record line and
publishes the decision, the plans, the state and the events. What it must name
is made to happen at a known step: the EWS gone for two steps (``fire_stale``,
the data's age and the grown hulls, then the fires caught up), both planners
silent for a step (``plan_deadline``, the braking step's hold reason), their
tokens gone while the vehicle moves (``no planner alive``), the vehicle's state
changed without a new step (``vehicle_moved``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.model.stale_fire import credible_margin_m
from services.common import keys
from services.msgs import supervisor_pb2
from tests.support.stack import UAV, Rig, rig

SEED = 26  # cc reaches the goal in 56 steps; the first 16 (the step limit) are enough here
SHORT = (("max_steps", 16),)
SUBSTEP_S = 0.5  # T_f of the default reading (s)


def lines(run_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run_dir / "steps.jsonl").read_text().splitlines()]


def steps(run_dir: Path) -> dict[int, dict[str, Any]]:
    return {g["t"]: g for g in lines(run_dir) if g["kind"] == "step"}


def between(r: Rig, step: int, act: Any) -> None:
    """``act()`` once, between steps ``step`` - 1 and ``step`` (when the state is published)."""
    done: list[bool] = []

    def hook(key: str, msg: Any) -> None:
        if key == keys.vehicle_state(UAV) and msg.step == step and not done:
            done.append(True)
            act()

    r.stack.on_publish.append(hook)


def step_events(r: Rig) -> dict[int, supervisor_pb2.MissionEvent]:
    return {e.step: e for e, k in zip(r.stack.events(), r.stack.event_kinds(), strict=True)
            if k == "STEP"}


def test_each_step_is_recorded_with_its_reasons_and_published(tmp_path: Path) -> None:
    r = rig(MissionConfig.named("cc", seed=SEED), tmp_path)
    result = r.session.run()
    got = steps(tmp_path)
    decisions = r.stack.on(keys.decision(UAV))
    plans = r.stack.on(keys.step_plans(UAV))
    for rec in result.records:
        g = got[rec.t]
        assert g["commanded_system"] == rec.decision.system and g["system"] == rec.system
        assert g["planners_alive"] == ["system1", "system2"] and g["ews_alive"]
        assert (g["fire_age_s"], g["fire_stale"], g["fire_margin_m"]) == (0.0, False, 0.0)
        assert g["after"] == [float(v) for v in result.records[rec.t + 1].state] if (
            rec.t + 1 < result.steps) else True
        d = decisions[rec.t]
        assert d.commanded_system == rec.decision.system and not d.fire_stale
        assert d.plan_source == ("rrt" if rec.system == 1 else "")  # no operator waypoints
        assert plans[rec.t].step == rec.t and plans[rec.t].flown_system == rec.system
    # System 1 flew step 31 on its RRT path (no operator waypoints): the operator columns say so
    flown_by_s1 = [rec.t for rec in result.records if rec.system == 1]
    assert flown_by_s1 == [31]
    assert [(o.t, o.source, o.waypoints) for o in r.record.operator if o.source] == [
        (31, "rrt", 0)]
    assert [row[0] for row in r.record.latency.rows] == list(range(result.steps))


def test_fire_data_the_ews_did_not_advance_is_stale_until_caught_up(tmp_path: Path) -> None:
    r = rig(MissionConfig.named("cc", seed=SEED, settings=SHORT), tmp_path)

    def ews(up: bool) -> None:
        r.stack.ews_down = not up
        (r.tokens.up if up else r.tokens.down)("ews")

    between(r, 10, lambda: ews(False))
    between(r, 12, lambda: ews(True))
    result = r.session.run()
    got = steps(tmp_path)
    # steps 10 and 11 advanced the fires without the EWS: their sub-steps are owed
    owed = got[10]["fire_substeps"] + got[11]["fire_substeps"]
    assert owed > 0
    age = got[10]["fire_substeps"] * SUBSTEP_S
    fire = r.session.config.reading().fire
    assert got[11]["fire_stale"] and got[11]["fire_age_s"] == age
    assert got[11]["fire_margin_m"] == round(credible_margin_m(age, fire,
                                                               r.bus.stack.stale), 3)
    assert got[11]["faults"] == ["fire_stale"] and not got[11]["ews_alive"]
    assert not got[10]["fire_stale"] and got[10]["faults"] == []  # fresh when step 10 began
    assert not got[12]["fire_stale"] and got[12]["faults"] == []  # caught up before step 12
    caught = [g for g in lines(tmp_path) if g["kind"] == "fires_caught_up"]
    assert [c["owed_substeps"] for c in caught] == [owed]
    note = step_events(r)[11].message
    assert note == (f"fire data stale: {age:g} s old, hulls grown by "
                    f"{got[11]['fire_margin_m']:.1f} m")
    assert r.stack.on(keys.decision(UAV))[11].fire_stale
    assert r.session.observer.faults.totals == {"fire_stale": 1}
    assert result.steps > 12


def test_planners_that_miss_their_deadline_make_a_braking_step(tmp_path: Path) -> None:
    r = rig(MissionConfig.named("cc", seed=SEED, settings=SHORT), tmp_path)
    between(r, 5, lambda: r.stack.silent_planners.update({1, 2}))
    between(r, 6, r.stack.silent_planners.clear)
    r.session.run()
    got = steps(tmp_path)
    assert got[5]["system"] == 0 and got[5]["hold_reason"] == "no OK plan"
    assert got[5]["faults"] == ["plan_deadline"] * len(got[5]["plan_status"].split(";"))
    assert "hold_reason" not in got[4] and "hold_reason" not in got[6]
    assert step_events(r)[5].message == "braking: no OK plan"
    assert r.session.observer.faults.totals["plan_deadline"] >= 1


def test_with_the_planners_gone_a_moving_vehicle_brakes(tmp_path: Path) -> None:
    r = rig(MissionConfig.named("cc", seed=SEED, settings=SHORT), tmp_path)
    def back() -> None:
        r.tokens.up("system1", "system2")

    def paused(key: str, msg: Any) -> None:  # at rest without a planner: paused, then back
        if key == keys.mission_event(UAV) and r.stack.event_kinds()[-1] == "PAUSED":
            back()

    between(r, 5, lambda: r.tokens.down("system1", "system2"))
    between(r, 7, back)
    r.stack.on_publish.append(paused)
    r.session.run()
    got = steps(tmp_path)
    assert got[5]["system"] == 0 and got[5]["hold_reason"] == "no planner alive"
    assert got[5]["planners_alive"] == [] and got[5]["faults"] == []
    assert step_events(r)[5].message == "braking: no planner alive"  # still moving: it brakes


def test_a_vehicle_state_that_changes_without_a_step_is_named(tmp_path: Path) -> None:
    r = rig(MissionConfig.named("cc", seed=SEED, settings=SHORT), tmp_path)

    def nudge() -> None:  # LOCAL_POSITION_NED with the same time_boot_ms, another state
        with r.autopilot.lock:
            r.autopilot.state = r.autopilot.state + [0.5, 0.0, 0.0, 0.0]
            r.autopilot.position()

    between(r, 7, nudge)
    r.session.run()
    got = steps(tmp_path)
    assert got[7]["faults"] == ["vehicle_moved"]
    assert r.link.position.moved_without_step == 1
    assert r.session.observer.faults.totals == {"vehicle_moved": 1}


@pytest.mark.parametrize("flown", [True, False])
def test_the_end_is_recorded_with_the_final_state(tmp_path: Path, flown: bool) -> None:
    config = MissionConfig.named("cc" if flown else "s1", seed=SEED)
    r = rig(config, tmp_path)
    result = r.session.run()
    end = lines(tmp_path)[-1]
    assert end["kind"] == "end" and end["steps"] == result.steps
    assert (end["success"], end["failure_cause"]) == (result.success, result.failure_cause)
    assert end["final_state"] == [float(v) for v in r.session.state]
    last = r.stack.events()[-1]
    assert r.stack.event_kinds()[-1] == "STEP" and last.step == result.records[-1].t
    assert last.flown_system == result.records[-1].system

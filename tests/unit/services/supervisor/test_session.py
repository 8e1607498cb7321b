"""The supervisor's mission session in this process (services/supervisor/session.py).

The session flies a mission through its ports with the stack in this process
(tests/support/stack.py): the EWS's and the planner services' own handlers
behind a fake transport, a real vehicle link to a simulated autopilot, a fake
wall clock. What it must do is worked out independently by the in-process
mission of the same configuration (dualpilot.mission.local): the same steps,
states and decisions, the setpoint of step t due at τ_{t+1}; and, around the
step, the start (take the vehicle, its mission, the planners), the resume
from a record, the pauses (the vehicle held or lost, no planner alive), the
operator's waypoints, the records and the publications, the end.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.local import local_mission
from dualpilot.mission.result import Ending, MissionResult
from services.common import keys, mav, mavmodes
from services.supervisor.session import Aborted, VehicleGone
from tests.support.stack import (
    BOOT_MS,
    UAV,
    PlantAutopilot,
    Rig,
    rig,
    serve_link,
)

m = mav.mavlink
SEED = 26  # cc reaches the goal in 56 steps, System 2 flying all but one
#: the first 16 steps of it (the step limit ends it): enough for what happens at step 11
SHORT = (("max_steps", 16),)


@functools.cache
def twin(config: MissionConfig) -> MissionResult:
    """The in-process mission of ``config``: what the stack must fly."""
    return local_mission(config).run()


def assert_same_mission(got: MissionResult, want: MissionResult) -> None:
    assert (got.steps, got.success, got.failure_cause) == (want.steps, want.success,
                                                           want.failure_cause)
    for a, b in zip(got.records, want.records, strict=True):
        assert (a.t, a.system, a.plan_status, a.fire_substeps) == (b.t, b.system,
                                                                   b.plan_status, b.fire_substeps)
        assert np.array_equal(a.state, b.state) and np.array_equal(a.control, b.control)
        assert a.decision.attention == b.decision.attention
        assert np.array_equal(a.decision.psi, b.decision.psi)
        assert a.snapshot.regions == b.snapshot.regions


def lines(run_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run_dir / "steps.jsonl").read_text().splitlines()]


def on_state(r: Rig, step: int, act: Any) -> None:
    """``act()`` once, when the vehicle's state after step ``step`` - 1 is published (between
    steps ``step`` - 1 and ``step``)."""
    done: list[bool] = []

    def hook(key: str, msg: Any) -> None:
        if key == keys.vehicle_state(UAV) and msg.step == step and not done:
            done.append(True)
            act()

    r.stack.on_publish.append(hook)


def test_a_mission_is_the_in_process_mission_published_and_recorded(tmp_path: Path) -> None:
    config = MissionConfig.named("cc", seed=SEED)
    r = rig(config, tmp_path)
    result = r.session.run()
    r.session.close()
    want = twin(config)
    assert_same_mission(result, want)
    assert result.success and result.steps == 56
    # the vehicle: taken (a hold setpoint at its time, offboard, armed), then each step's
    # target due at the next step's time τ_{t+1} on the vehicle's clock
    assert r.autopilot.commands == [m.MAV_CMD_REQUEST_MESSAGE, m.MAV_CMD_DO_SET_MODE,
                                    m.MAV_CMD_COMPONENT_ARM_DISARM]
    dues = [ms for _, ms in r.autopilot.setpoints]
    assert dues[0] == BOOT_MS and len(dues) == 1 + result.steps
    assert dues[1:-1] == [BOOT_MS + round(1000 * rec.time_s) for rec in want.records[1:]]
    assert [s for s, _ in r.autopilot.setpoints[1:-1]] == [
        [float(v) for v in rec.state] for rec in want.records[1:]]
    # the EWS: reset once, then one advance per step that planned (no replay, no forecast)
    assert r.stack.fire_commands == ["reset"] + ["advance"] * sum(
        1 for rec in want.records if rec.fire_substeps)
    # what is published: the start, a STEP event, decision, clock and plans per step, the
    # state after each flown step
    kinds = r.stack.event_kinds()
    assert kinds == ["STARTED"] + ["STEP"] * 56
    ev = r.stack.events()
    assert (ev[0].position.east_m, ev[0].position.north_m) == (50.0, 50.0)
    assert [e.step for e in ev[1:]] == list(range(56))
    assert [e.flown_system for e in ev[1:]] == [rec.system for rec in want.records]
    states = r.stack.on(keys.vehicle_state(UAV))
    assert [s.step for s in states] == list(range(57))
    for key in (keys.decision(UAV), keys.clock(UAV), keys.step_plans(UAV)):
        assert len(r.stack.on(key)) == 56, key
    # what is recorded: the mission, how the vehicle was taken, each step, the end
    got = lines(tmp_path)
    assert [g["kind"] for g in got] == ["mission"] + ["event"] * 4 + ["step"] * 56 + ["end"]
    assert got[0]["mission_id"] == "m1" and got[0]["seed"] == SEED and got[0]["start"] == [
        50.0, 50.0]
    assert got[1]["event"] == "started"
    assert [(g["mode"], g["armed"]) for g in got[2:5]] == [
        ("AUTO.LOITER", False), ("OFFBOARD", False), ("OFFBOARD", True)]
    steps = [g for g in got if g["kind"] == "step"]
    assert [g["t"] for g in steps] == list(range(56))
    assert all(g["faults"] == [] and g["flown"] and not g["fire_stale"] for g in steps)
    assert [g["sim_time_s"] for g in steps[:-1]] == [rec.time_s for rec in want.records[1:]]
    assert got[-1]["success"] and got[-1]["steps"] == 56 and got[-1]["failure_cause"] == ""
    assert len(r.record.latency.rows) == 56 and len(r.record.operator) == 56
    # the end announced (the companion's call): where the records are
    r.session.announce_end(str(tmp_path))
    end = r.stack.events()[-1]
    assert r.stack.event_kinds()[-1] == "ENDED" and end.success and end.step == 56
    assert end.message == str(tmp_path)


def test_a_stopped_mission_resumes_from_its_record(tmp_path: Path) -> None:
    config = MissionConfig.named("cc", seed=SEED)
    first = rig(config, tmp_path)
    on_state(first, 21, first.bus.stop.set)  # the supervisor stops after step 20
    with pytest.raises(Aborted, match="stopped"):
        first.session.run()
    first.session.close()
    assert first.record.lock is not None
    first.record.lock.close()  # its process ended
    assert [g["t"] for g in lines(tmp_path) if g["kind"] == "step"] == list(range(21))
    # a new supervisor: the same services, the vehicle where it is (its clock and state)
    first.stack.fire_commands.clear()
    first.stack.published.clear()
    first.stack.on_publish.clear()
    again = rig(config, tmp_path, stack=first.stack, autopilot=first.autopilot)
    result = again.session.run()
    assert again.session.resumed_at == 21
    assert_same_mission(result, twin(config))
    # the EWS reset and replayed to the recorded fire world, then the mission goes on
    replayed = sum(1 for rec in result.records[:21] if rec.fire_substeps)
    assert again.stack.fire_commands[:1 + replayed] == ["reset"] + ["advance"] * replayed
    ev = again.stack.events()
    assert again.stack.event_kinds()[0] == "RESUMED" and ev[0].step == 21
    assert ev[0].message.startswith("supervisor restarted: mission picked up at step 21 ")
    got = lines(tmp_path)
    assert [g["kind"] for g in got].count("mission") == 1  # the record goes on
    assert [g["t"] for g in got if g["kind"] == "step"] == list(range(56))
    assert got[-1]["kind"] == "end" and got[-1]["success"]


def test_a_vehicle_held_by_a_ground_station_pauses_the_mission_until_handed_back(
        tmp_path: Path) -> None:
    config = MissionConfig.named("cc", seed=SEED, settings=SHORT)
    r = rig(config, tmp_path)
    held_at: list[float] = []

    def hold() -> None:
        r.autopilot.switch(mavmodes.PX4_MODES.hold, "Hold by ground station")
        held_at.append(r.wall.now())

    def hand_back(now: float) -> None:
        held = r.autopilot.mode == mavmodes.PX4_MODES.hold
        if held and held_at and now - held_at[0] >= 2.0 - 1e-9:  # 2 s later (sums of 0.05 s)
            r.autopilot.switch(mavmodes.PX4_MODES.offboard)

    on_state(r, 11, hold)
    r.wall.on_wait.append(hand_back)
    result = r.session.run()
    assert_same_mission(result, twin(config))  # held at rest between steps: nothing moved
    kinds, ev = r.stack.event_kinds(), r.stack.events()
    paused = kinds.index("PAUSED")
    assert kinds[paused:paused + 2] == ["PAUSED", "RESUMED"] and ev[paused].step == 11
    assert ev[paused].message == "vehicle not flying offboard (AUTO.LOITER, armed)"
    assert ev[paused + 1].message == "paused 2.0 s"
    assert r.session.pause.pauses == 1 and r.session.pause.paused_s == pytest.approx(2.0)
    got = lines(tmp_path)
    step11 = next(g for g in got if g["kind"] == "step" and g["t"] == 11)
    assert step11["faults"] == ["vehicle_hold: Hold by ground station"]
    events = [(g["event"], g.get("mode"), g.get("text")) for g in got if g["kind"] == "event"]
    assert ("paused", None, None) in events and ("resumed", None, None) in events
    assert ("vehicle_mode", "AUTO.LOITER", "Hold by ground station") in events
    assert r.session.observer.faults.totals == {"vehicle_hold": 1}


def test_a_vehicle_lost_and_back_is_taken_again(tmp_path: Path) -> None:
    config = MissionConfig.named("cc", seed=SEED, settings=SHORT)
    r = rig(config, tmp_path)

    lost_at: list[float] = []

    def lose() -> None:  # silent for 4 s: lost to the link (3 s without a heartbeat)
        r.autopilot.present = False
        r.wall.now_s += 4.0
        lost_at.append(r.wall.now())

    def back(now: float) -> None:  # a second into the pause it answers again
        if not r.autopilot.present and r.session.pause.pauses and now >= lost_at[0] + 1.0:
            r.autopilot.present = True
            r.autopilot.switch(r.autopilot.mode)  # its heartbeat again

    on_state(r, 11, lose)
    r.wall.on_wait.append(back)
    result = r.session.run()
    assert_same_mission(result, twin(config))
    kinds, ev = r.stack.event_kinds(), r.stack.events()
    assert ev[kinds.index("PAUSED")].message == "vehicle lost: no heartbeat for 3 s"
    assert "RESUMED" in kinds
    assert r.session.observer.faults.totals == {"vehicle_lost": 1}
    step11 = next(g for g in lines(tmp_path) if g["kind"] == "step" and g["t"] == 11)
    assert step11["faults"] == ["vehicle_lost"]


def test_a_vehicle_gone_for_good_ends_the_mission(tmp_path: Path) -> None:
    config = MissionConfig.named("cc", seed=SEED, settings=SHORT)
    r = rig(config, tmp_path)

    gone_at: list[float] = []

    def gone() -> None:  # no heartbeat for 4 s, and its liveliness token gone
        r.autopilot.present = False
        r.tokens.down("uavsim")
        r.wall.now_s += 4.0
        gone_at.append(r.wall.now())

    on_state(r, 11, gone)
    with pytest.raises(VehicleGone, match="no heartbeat and its liveliness token gone for 5 s"):
        r.session.run()
    # gone for vehicle_gone_s (5 s) of wall time, at the pause's first check past it (every
    # 0.05 s), long before the pause limit (300 s)
    assert 5.0 < r.wall.now() - gone_at[0] <= 5.05 + 1e-9
    r.session.end_lost("vehicle lost")
    r.session.close()
    result = r.session.result
    assert result is not None and result.ending is Ending.VEHICLE_LOST and result.steps == 11
    end = lines(tmp_path)[-1]
    assert end["kind"] == "end" and not end["success"]
    assert end["failure_cause"] == "vehicle_lost" and end["steps"] == 11
    r.session.announce_end(str(tmp_path))
    last = r.stack.events()[-1]
    assert r.stack.event_kinds()[-1] == "ENDED" and last.failure_cause == "vehicle_lost"


def test_with_no_planner_alive_the_mission_holds_until_one_is_back(tmp_path: Path) -> None:
    config = MissionConfig.named("cc", seed=SEED, settings=SHORT)
    r = rig(config, tmp_path)
    prepared: list[int] = []
    for k, service in r.stack.services.items():
        prepare = service.prepare

        def counted(*args: Any, k: int = k, prepare: Any = prepare) -> Any:
            prepared.append(k)
            return prepare(*args)

        service.prepare = counted  # type: ignore[method-assign,assignment]

    def planners(key: str, msg: Any) -> None:
        kind = r.stack.event_kinds()[-1] if r.stack.events() else ""
        if kind == "STARTED" and key == keys.mission_event(UAV):
            r.tokens.down("system1", "system2")  # both planners gone before step 0
        elif kind == "PAUSED" and key == keys.mission_event(UAV):
            r.tokens.up("system1", "system2")  # and back as soon as the pause is announced

    r.stack.on_publish.append(planners)
    result = r.session.run()
    kinds, ev = r.stack.event_kinds(), r.stack.events()
    assert kinds[:3] == ["STARTED", "PAUSED", "RESUMED"]
    assert ev[1].message == ("holding: no planner alive (system1, system2: liveliness token "
                             "gone)")
    assert ev[2].message == "system1, system2 back after 0.0 s"
    assert prepared == [1, 2, 1, 2]  # prepared at the start, and again when back
    assert r.session.holding == ""
    assert_same_mission(result, twin(config))  # held at rest before step 0: nothing moved


def test_a_mission_uploaded_to_the_vehicle_becomes_the_operator_waypoints(
        tmp_path: Path) -> None:
    config = MissionConfig.named("cc", seed=SEED, settings=SHORT)
    r = rig(config, tmp_path)

    def upload(points: list[tuple[float, float]], mission_id: float) -> None:
        r.autopilot.upload(points, mission_id)
        serve_link(r.link, r.wall)  # the link's poll sees MIS_ID change, the watcher downloads

    on_state(r, 5, lambda: upload([(2000.0, 300.0)], 8))  # outside the area: ignored
    on_state(r, 8, lambda: upload([(200.0, 300.0), (650.5, 720.25)], 7))
    r.session.run()
    kinds, ev = r.stack.event_kinds(), r.stack.events()
    assert kinds.count("WAYPOINTS") == 1
    wp = ev[kinds.index("WAYPOINTS")]
    assert wp.step == 8 and wp.message == "2 operator waypoints (mission 7)"
    # published on their key: each planner service has them, as revision 1 of this mission
    for service in r.stack.services.values():
        got = service.waypoints["m1"]
        assert got.revision == 1 and got.points is not None
        assert np.allclose(got.points, [(200.0, 300.0), (650.5, 720.25)], atol=0.05)  # degE7
    assert r.session.waypoints_n == 2 and r.session.mission_rev == 3


def test_a_vehicle_that_refuses_to_arm_aborts_the_start_before_any_record(
        tmp_path: Path) -> None:
    config = MissionConfig.named("cc", seed=SEED, settings=SHORT)
    r = rig(config, tmp_path)
    r.autopilot.refuse[m.MAV_CMD_COMPONENT_ARM_DISARM] = m.MAV_RESULT_UNSUPPORTED
    with pytest.raises(Aborted, match="vehicle: arm: UNSUPPORTED"):
        r.session.run()
    assert r.session.result is None and not (tmp_path / "steps.jsonl").exists()
    assert r.stack.fire_commands == [] and r.stack.events() == []
    r.session.announce_end(str(tmp_path), "vehicle: arm: UNSUPPORTED")
    (aborted,) = r.stack.events()
    assert r.stack.event_kinds() == ["ABORTED"] and aborted.message == "vehicle: arm: UNSUPPORTED"


#: the multirotor in a 5 m/s wind, moderate turbulence, GPS σ 1.5 m (docs/plant.md)
MULTIROTOR = (("plant", "multirotor"), ("wind_speed_mps", 5.0), ("turbulence", "moderate"),
              ("gps_sigma_m", 1.5))


def test_a_multirotor_mission_is_the_in_process_one_judged_on_the_true_flight(
        tmp_path: Path) -> None:
    """uavsim's vehicle flying the mission's multirotor (tests/support/stack.py's
    PlantAutopilot): the session plans from the measured state the vehicle reports and
    judges on the truth it answers on uavsim/flight, so its mission is the in-process one bit
    for bit: the noisy states, the controls, the ending, every flight's tracking error."""
    config = MissionConfig.named("cc", seed=SEED, settings=SHORT + MULTIROTOR)
    r = rig(config, tmp_path)
    result = r.session.run()
    r.session.close()
    want = twin(config)
    assert_same_mission(result, want)
    assert result.steps == 16 and result.ending is Ending.STEP_LIMIT
    assert len(result.tracking_error_m) == 16
    for got, expected in zip(result.tracking_error_m, want.tracking_error_m, strict=True):
        assert np.array_equal(got, expected)
    # the start is the plant's true position (the spec's), planned from its estimate
    assert list(result.spec.start) == [50.0, 50.0]
    assert not np.array_equal(result.records[0].state[:2], [50.0, 50.0])
    r.record.write(result, UAV, {})  # the companion's end of the run (companion.py)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert (summary["tracking_error_p50_m"], summary["tracking_error_p99_m"]) == (
        want.tracking_percentiles())


def test_a_plant_vehicle_that_stops_giving_its_truth_ends_the_mission_after_its_timeout(
        tmp_path: Path) -> None:
    """The truth is asked after every state; a vehicle that answers "unavailable" (here: its
    plant gone after step 4, a vehicle flying Eq. (1)) is asked again until the vehicle
    timeout (10 s of wall time), then the mission aborts saying why: never judged on a
    guess."""
    config = MissionConfig.named("cc", seed=SEED, settings=SHORT + MULTIROTOR)
    r = rig(config, tmp_path)
    assert isinstance(r.autopilot, PlantAutopilot)
    autopilot = r.autopilot
    on_state(r, 5, lambda: setattr(autopilot.vehicle, "plant", None))
    began = r.wall.now()
    with pytest.raises(Aborted, match="the vehicle's ground truth: this vehicle flies the ideal"):
        r.session.run()
    assert r.wall.now() - began >= r.bus.stack.vehicle_timeout_s
    assert r.session.result is not None and r.session.result.steps == 5

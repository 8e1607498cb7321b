"""One vehicle's companion in this process (services/supervisor/companion.py).

:func:`fly` with a :class:`Stack` in this process (tests/support/stack.py):
the liveliness tokens, the services' own handlers behind a fake transport, a
real vehicle link (its threads running) to a simulated autopilot. It must
refuse a vehicle another supervisor holds, wait for the services and the
vehicle, fly, write the records (summary.json with the stack's section) and
announce the end, and say how it went in its exit code (0 success, 1 aborted,
3 failed).
"""

from __future__ import annotations

import json
import threading
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from dualpilot.mission.local import local_mission
from dualpilot.model.dynamics import hover_state
from services.common import bus, mav, rejections
from services.supervisor import companion
from services.supervisor.link import LinkParams, VehicleLink
from services.supervisor.options import EXIT_ABORTED, EXIT_FAILED, EXIT_SUCCESS, Options, parse
from tests.support.stack import (
    UAV,
    FakeWall,
    InProcessStack,
    SimAutopilot,
    SimConnection,
    Tokens,
    in_process_ews,
    planner_services,
)

m = mav.mavlink
OWN = "supervisor-zid"  # this supervisor's session


@dataclass
class Context:
    """What :func:`fly` reads of its service's context (services/common/bus: Context)."""

    settings: object
    stop: threading.Event
    tokens: Tokens
    announced: int = 0

    def announce(self) -> None:
        """The supervisor's liveliness token, held by this process."""
        self.announced += 1
        self.tokens.claim("supervisor", OWN)


@dataclass
class Stack:
    """The companion's stack in this process (companion.Stack)."""

    transport_: InProcessStack
    tokens: Tokens
    autopilot: SimAutopilot
    wall: FakeWall = field(default_factory=FakeWall)
    others: list[str] = field(default_factory=list)  # supervisors already holding the vehicle
    #: tokens (service, zid) that are up when the companion starts tracking them
    up: list[tuple[str, str]] = field(default_factory=list)
    links: list[VehicleLink] = field(default_factory=list)

    def own_id(self) -> str:
        return OWN

    def holders(self, uav: str) -> list[str]:
        return list(self.others)

    def liveliness(self, uav: str) -> bus.Liveliness:
        live = self.tokens.tracker()
        for service, zid in self.up:
            self.tokens.claim(service, zid)
        return live

    def transport(self) -> InProcessStack:
        return self.transport_

    def link(self, params: LinkParams) -> VehicleLink:
        link = VehicleLink(params, SimConnection(self.autopilot, self.wall), clock=self.wall.now)
        self.links.append(link)
        return link


def options(tmp_path: Path, *extra: str) -> Options:
    return parse(["--uav-id", UAV, "--controller", "cc", "--seed", "26", "--mission-id", "m1",
                  "--speed-factor", "0", "--out", str(tmp_path), "--exit-after-mission",
                  "--setpoint-stream", "thread", "--wait-services-s", "5", *extra], "test")


def stack_for(opts: Options, *services: str) -> tuple[Context, Stack]:
    """The companion's context and stack: ``services`` alive, the vehicle at the start."""
    stop = threading.Event()
    spec = opts.config(0).spec()
    vehicle = SimAutopilot(hover_state(np.array(spec.start), spec.dynamics))
    tokens = Tokens()
    stack = Stack(InProcessStack(in_process_ews(stop), planner_services()), tokens, vehicle,
                  up=[(s, f"{s}-zid") for s in services])
    return Context(opts.settings, stop, tokens), stack


def fly(ctx: Context, opts: Options, stack: Stack) -> int:
    try:
        return companion.fly(ctx, opts, stack)  # type: ignore[arg-type]
    finally:
        for link in stack.links:  # closed: every thread of the link ended
            assert not any(th.is_alive() for th in link._threads)


ALL = ("ews", "uavsim", "system1", "system2")


def touched(vehicle: SimAutopilot) -> bool:
    """Whether the vehicle was commanded: a setpoint, a mode or arming (the link's polls of
    its origin and mission are not commands)."""
    return bool(vehicle.setpoints) or bool(
        {m.MAV_CMD_DO_SET_MODE, m.MAV_CMD_COMPONENT_ARM_DISARM} & set(vehicle.commands))


@pytest.fixture(autouse=True)
def _flags_only(monkeypatch: pytest.MonkeyPatch) -> None:
    """The options come from the flags here, not from the test run's environment."""
    for name in ("CONTROLLER", "SUPERVISOR", "MISSION_SEED", "MISSION_SEEDS", "TIMING",
                 "READINGS_PROFILE", "READINGS", "S1_METHOD", "S2_METHOD", "RUN_DIR"):
        monkeypatch.delenv(name, raising=False)


def test_a_mission_is_flown_recorded_and_announced(tmp_path: Path) -> None:
    opts = options(tmp_path)
    ctx, stack = stack_for(opts, *ALL)
    assert fly(ctx, opts, stack) == EXIT_SUCCESS
    want = local_mission(opts.config(0)).run()
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["success"] and summary["steps"] == want.steps
    assert {"steps.csv", "trace.json", "latency.csv"} <= {p.name for p in tmp_path.iterdir()}
    st = summary["stack"]
    assert st["mission_id"] == "m1" and st["aborted"] is None and st["faults"] == {}
    assert st["vehicle_modes"] == [{"mode": "AUTO.LOITER", "armed": False, "text": ""},
                                   {"mode": "OFFBOARD", "armed": False, "text": ""},
                                   {"mode": "OFFBOARD", "armed": True, "text": ""}]
    # the link's own stream (not UDP): every setpoint sent, each step's and the repeats
    assert st["stream"]["process"] is False and st["stream"]["frames"] == st["setpoints_sent"]
    assert st["setpoints_sent"] >= want.steps + 1 and st["planner_failovers"] == 0
    assert ctx.announced == 1
    kinds = stack.transport_.event_kinds()
    assert kinds[0] == "STARTED" and kinds[-1] == "ENDED"
    end = stack.transport_.events()[-1]
    assert end.success and end.step == want.steps and end.message == str(tmp_path)


def test_a_mission_that_fails_exits_3(tmp_path: Path) -> None:
    opts = options(tmp_path, "--controller", "s1")  # seed 26: fire while planning, step 67
    ctx, stack = stack_for(opts, "ews", "uavsim", "system1")
    assert fly(ctx, opts, stack) == EXIT_FAILED
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert not summary["success"] and summary["ending"] == "fire_while_planning"
    end = stack.transport_.events()[-1]
    assert not end.success and end.failure_cause == "fire_while_planning"


def test_a_vehicle_another_supervisor_holds_is_never_touched(tmp_path: Path) -> None:
    opts = options(tmp_path)
    ctx, stack = stack_for(opts)
    stack.others = ["other-zid"]
    assert fly(ctx, opts, stack) == EXIT_ABORTED
    assert stack.links == [] and ctx.announced == 0 and not touched(stack.autopilot)


def test_a_vehicle_another_supervisor_claimed_first_is_left_to_it(tmp_path: Path) -> None:
    opts = options(tmp_path)
    ctx, stack = stack_for(opts, *ALL)
    stack.up.insert(0, ("supervisor", "other-zid"))  # another supervisor's token came first
    assert fly(ctx, opts, stack) == EXIT_ABORTED
    assert not touched(stack.autopilot) and not (tmp_path / "steps.jsonl").exists()


def test_services_missing_abort_before_the_vehicle_is_taken(tmp_path: Path) -> None:
    opts = options(tmp_path, "--wait-services-s", "0.2")
    ctx, stack = stack_for(opts, "ews", "uavsim", "system1")  # cc needs system2 too
    assert fly(ctx, opts, stack) == EXIT_ABORTED
    assert not touched(stack.autopilot) and stack.transport_.published == []


def test_a_stop_while_waiting_ends_without_a_mission(tmp_path: Path) -> None:
    opts = options(tmp_path)
    ctx, stack = stack_for(opts, *ALL)
    ctx.stop.set()
    assert fly(ctx, opts, stack) == EXIT_SUCCESS
    assert not touched(stack.autopilot) and stack.transport_.published == []


def test_a_mission_that_could_not_start_is_aborted_and_announced(tmp_path: Path) -> None:
    opts = options(tmp_path)
    ctx, stack = stack_for(opts, *ALL)
    stack.autopilot.refuse[m.MAV_CMD_COMPONENT_ARM_DISARM] = m.MAV_RESULT_UNSUPPORTED
    assert fly(ctx, opts, stack) == EXIT_ABORTED
    assert stack.transport_.event_kinds() == ["ABORTED"]
    assert stack.transport_.events()[0].message == "vehicle: arm: UNSUPPORTED"
    assert not (tmp_path / "summary.json").exists()


def test_records_that_cannot_be_written_are_counted_and_the_end_still_announced(
        tmp_path: Path) -> None:
    opts = options(tmp_path)
    ctx, stack = stack_for(opts, *ALL)
    (tmp_path / "summary.json").mkdir(parents=True)  # the summary cannot be written there
    before = rejections.REJECTED.snapshot().get("storage/records", {}).get("write_error", 0)
    assert fly(ctx, opts, stack) == EXIT_SUCCESS
    after = rejections.REJECTED.snapshot()["storage/records"]["write_error"]
    assert after == before + 1
    assert stack.transport_.event_kinds()[-1] == "ENDED"

"""The setpoint stream under a stalled supervisor, and lockstep's offboard loss (real processes).

Each test flies one cc mission (paper timing) through a shared router, EWS
and planner pair and stops the supervisor with SIGSTOP at a step:

* the supervisor alone, 1.5 s (longer than COM_OF_LOSS_T = 1 s): its stream
  process keeps the vehicle's stream beating, so the vehicle sees no gap of a
  second, no failsafe fires, no fault is named and the mission is the
  in-process one, step for step;
* its stream process, killed: the supervisor starts it again and gives it
  the link and the setpoint back before the vehicle's failsafe could fire;
* the supervisor and its stream process, 2.5 s: the stream stops, the
  vehicle's lockstep failsafe holds it as it is (no simulated time passes),
  the stream comes back, the supervisor names the fault ``vehicle_hold`` in
  its step record — and still the mission is the in-process one, since a
  lockstep hold changes nothing the mission can see.

The plan deadlines are raised so that a stop during a plan request is not a
late plan (that fault, ``plan_deadline``, has its own tests in test_faults.py).
"""

from __future__ import annotations

import json
import os
import queue
import signal
import time
from pathlib import Path
from typing import Any

import pytest

from dualpilot.mission.records import read_step_log, result_from_log
from services import launch
from services.common import keys, wire
from services.msgs import supervisor_pb2
from tests.support.waits import check, logs_in, wait_for

from .test_lockstep import assert_same_mission, in_process

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]

SEED = 26
EV = supervisor_pb2
#: the stalls and the kill are in wall time and the mission is lockstep, so the pace changes
#: nothing the tests check; at 25 the mission (331 simulated s) still streams for ~13 s, 260
#: setpoints at the link's 20 Hz and more than a hundred after the stall
SPEED = 25
ENV = {"CONTROLLER": "cc", "TIMING": "paper", "SPEED_FACTOR": str(SPEED), "SUPERVISOR": "paper",
       "IGNITION_CLEARANCE_M": "", "PLAN_DEADLINE_S": "20,20"}


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Any:
    out = tmp_path_factory.mktemp("stream")
    cfg = launch.StackConfig(run_dir=out / "shared", speed_factor=float(SPEED), free_ports=True,
                             log_format="text")
    with launch.Fleet(cfg, ["st1"]) as f:
        yield f, out


def children(pid: int) -> list[int]:
    return [int(c) for task in Path(f"/proc/{pid}/task").glob("*")
            for c in (task / "children").read_text().split()]


def fly_with_stop(fleet: Any, tag: str, group: bool, stop_s: float, kill_stream: bool = False
                  ) -> tuple[Path, dict[str, Any]]:
    """Fly SEED, SIGSTOP the supervisor (with its stream process if ``group``) for ``stop_s``
    once step 5 is out — or, with ``kill_stream``, SIGKILL its stream process instead;
    returns the run directory and the vehicle's stream statistics."""
    f, out = fleet
    events: queue.Queue[bytes] = queue.Queue()
    with launch.client_session(f.endpoint) as session:
        sub = session.declare_subscriber(keys.mission_event("st1"),
                                         lambda s: events.put(s.payload.to_bytes()))
        v = f.start_vehicle("st1", SEED, out / tag, env=ENV)
        logs = [*logs_in(v.run_dir), *logs_in(f.stack.logs)]
        sup = next(p for p in v.procs if p.name.startswith("supervisor"))
        seen: list[Any] = []

        def step5() -> bool:
            try:
                seen.append(wire.parse(events.get(timeout=0.5), EV.MissionEvent))
            except queue.Empty:
                return False
            return seen[-1].kind == EV.MISSION_EVENT_KIND_STEP and seen[-1].step >= 5

        wait_for(step5, 120, "the mission's STEP event of step 5", logs, period_s=0,
                 last=lambda: seen[-1] if seen else "no mission event")
        pid = sup.popen.pid
        if kill_stream:
            (stream_pid,) = children(pid)
            os.kill(stream_pid, signal.SIGKILL)
        elif group:
            os.killpg(pid, signal.SIGSTOP)
        else:
            os.kill(pid, signal.SIGSTOP)
        time.sleep(stop_s)  # the stall itself: nothing to wait on, the processes are stopped
        if kill_stream:
            pass
        elif group:
            os.killpg(pid, signal.SIGCONT)
        else:
            os.kill(pid, signal.SIGCONT)
        sub.undeclare()
    outcome = f.wait_end({"st1": v.mission_id}, 180.0)["st1"]
    codes = f.stop_vehicle("st1")
    check(outcome.ended, f"the {tag} mission to end", logs, outcome)
    check(all(code == 0 for code in codes.values()), "the vehicle's processes to exit with 0",
          logs, codes)
    return v.run_dir, json.loads((v.run_dir / "stream.json").read_text())


def check_stream(run_dir: Path, stream: dict[str, Any], failsafes: int) -> None:
    """The vehicle's own record of the stream (stream.json): ``failsafes`` offboard-loss
    failsafes, and without one no gap in the stream of a second (COM_OF_LOSS_T) or more.

    The gap bound is the real-time guarantee the stack keeps on purpose — the
    supervisor's stream process runs at SCHED_RR (services/supervisor/stream/)
    so that the vehicle keeps hearing it however loaded the machine is — not a
    figure of the test's own timing."""
    logs = logs_in(run_dir)
    check(stream["failsafes"] == failsafes, f"the vehicle to count {failsafes} offboard-loss "
          f"failsafe(s) (stream.json)", logs, stream)
    if failsafes == 0:
        check(stream["gaps"]["max_ms"] < 1000.0, "every setpoint gap the vehicle saw to stay "
              "under COM_OF_LOSS_T = 1000 ms (the stream process at SCHED_RR keeps the stream "
              "beating however loaded the machine is)", logs, stream)


def step_faults(run_dir: Path) -> list[str]:
    return [fault for e in read_step_log(run_dir / "steps.jsonl") if e.get("kind") == "step"
            for fault in e.get("faults", [])]  # type: ignore[union-attr]


def test_a_stopped_supervisor_keeps_its_stream_and_its_mission(fleet: Any) -> None:
    run_dir, stream = fly_with_stop(fleet, "supervisor-stopped", group=False, stop_s=1.5)
    check_stream(run_dir, stream, failsafes=0)
    assert stream["gaps"]["n"] > 100, stream
    assert step_faults(run_dir) == []
    summary = json.loads((run_dir / "summary.json").read_text())["stack"]
    assert summary["faults"] == {} and summary["stream"]["process"] is True
    stack = result_from_log(read_step_log(run_dir / "steps.jsonl"))
    assert_same_mission(stack, in_process((SEED, "cc", "paper", None)), "stopped supervisor")


def test_lockstep_offboard_loss_holds_as_it_is_and_is_named(fleet: Any) -> None:
    run_dir, stream = fly_with_stop(fleet, "companion-stopped", group=True, stop_s=2.5)
    check_stream(run_dir, stream, failsafes=1)
    assert stream["clock"] == "lockstep", stream
    faults = step_faults(run_dir)
    assert len(faults) == 1 and faults[0].startswith("vehicle_hold"), faults
    assert "offboard lost" in faults[0], faults
    summary = json.loads((run_dir / "summary.json").read_text())["stack"]
    assert summary["faults"] == {"vehicle_hold": 1}, summary["faults"]
    stack = result_from_log(read_step_log(run_dir / "steps.jsonl"))
    assert_same_mission(stack, in_process((SEED, "cc", "paper", None)), "stopped companion")


def test_a_killed_stream_process_is_started_again_before_the_vehicle_notices(
        fleet: Any) -> None:
    run_dir, stream = fly_with_stop(fleet, "stream-killed", group=False, stop_s=0.0,
                                    kill_stream=True)
    check_stream(run_dir, stream, failsafes=0)
    summary = json.loads((run_dir / "summary.json").read_text())["stack"]
    assert summary["stream"]["restarts"] == 1 and summary["faults"] == {}, summary
    sup_log = run_dir / "logs" / "supervisor.log"
    check("stream process ended: starting it again" in sup_log.read_text(),
          "the supervisor to log that it started its stream process again", [sup_log])
    stack = result_from_log(read_step_log(run_dir / "steps.jsonl"))
    assert_same_mission(stack, in_process((SEED, "cc", "paper", None)), "stream restarted")

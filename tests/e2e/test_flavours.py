"""The supervisor flies a whole mission with each flavour, and a ground station takes over and
hands back in the middle of it.

The stack (router, EWS, System 1 and 2, uavsim, supervisor) flies System 1's
mission of seed 3 with the vehicle claiming PX4 (OFFBOARD is main mode 6)
or ArduPilot (GUIDED is 4): the supervisor reads the mode numbers from the
vehicle's HEARTBEAT. After 10 steps a ground station (pymavlink on the
ground-station link) asks for the hold mode: the vehicle holds, the mission
pauses; then it asks for the offboard mode, which hands control back to the
supervisor's live setpoint stream: the mission resumes and ends. The run's
record shows every mode change (``vehicle_mode`` events in steps.jsonl, the
list in summary.json) and names the hold as a fault of its step.
"""

from __future__ import annotations

import json
import queue
import time
from pathlib import Path
from typing import Any

import pytest

from dualpilot.mission.config import MissionConfig
from e2e.conftest import drain_messages
from services import launch
from services.common import keys, mav, mavmodes
from services.msgs import supervisor_pb2
from tests.e2e.sitl import Watch
from tests.support.waits import check, logs_in, wait_for

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]
m = mav.mavlink
SEED = 3  # System 1 reaches the goal in 97 steps in-process
KIND = supervisor_pb2.MissionEventKind


def set_mode(gcs: Watch, modes: mavmodes.ModeMap, custom: int, sub: float) -> int:
    """DO_SET_MODE for ``custom`` (its main mode, and ``sub`` for PX4): the ACK's result."""
    main = (custom >> 16) & 0xFF if modes.family == "px4" else custom
    return gcs.command(m.MAV_CMD_DO_SET_MODE, m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main, sub)


@pytest.mark.parametrize("flavour", ["px4", "ardupilot"])
def test_a_mission_with_a_ground_station_take_over_and_hand_back(flavour: str,
                                                                  tmp_path: Path) -> None:
    modes = mavmodes.PX4_MODES if flavour == "px4" else mavmodes.ARDUPILOT_MODES
    cfg = launch.StackConfig(
        run_dir=tmp_path / "run", mission=MissionConfig.named("s1", seed=SEED),
        speed_factor=20.0, free_ports=True, uav_id=f"e2e-{flavour}", log_format="text",
        deferred=("supervisor",), extra_env={"uavsim": {"UAV_AUTOPILOT": flavour}})
    cfg.run_dir.mkdir(parents=True)
    stack = launch.Stack(cfg)
    logs = cfg.run_dir
    gcs_port = int(stack.service_env("uavsim")["GCS_URL"].rsplit(":", 1)[1])
    events: queue.Queue[bytes] = queue.Queue()
    seen: list[int] = []

    def kinds() -> list[int]:
        seen.extend(e.kind for e in drain_messages(events, supervisor_pb2.MissionEvent))
        return seen

    gcs = Watch(mav.connect(f"udpout:127.0.0.1:{gcs_port}", 255, 190), speak=True)
    with stack, launch.client_session(stack.endpoint) as session, gcs.running():
        sub = session.declare_subscriber(keys.mission_event(cfg.uav_id),
                                         lambda s: events.put(s.payload.to_bytes()))

        def until(pred: Any, timeout_s: float, what: str) -> None:
            wait_for(pred, timeout_s, what, logs_in(logs), last=gcs.mode)

        until(gcs.mode, 60, "the vehicle's HEARTBEAT")
        stack.start_deferred()
        until(lambda: gcs.mode() == (modes.offboard, True)
              and gcs.last("LOCAL_POSITION_NED").time_boot_ms >= 10_000, 90,
              f"the supervisor flying the vehicle in {modes.name(modes.offboard)} 10 s")
        # the ground station takes over: the vehicle holds, the mission pauses
        assert set_mode(gcs, modes, modes.hold, 3) == m.MAV_RESULT_ACCEPTED
        until(lambda: gcs.mode() == (modes.hold, True), 10, "the hold mode")
        until(lambda: KIND.Value("MISSION_EVENT_KIND_PAUSED") in kinds(), 10,
              "the mission's PAUSED event")
        held = gcs.last("LOCAL_POSITION_NED").time_boot_ms
        time.sleep(1.0)  # the supervisor's stream goes on: nothing flies it meanwhile
        assert gcs.last("LOCAL_POSITION_NED").time_boot_ms == held
        # and hands back: the offboard link's stream is live, so offboard mode is accepted
        assert set_mode(gcs, modes, modes.offboard, 0) == m.MAV_RESULT_ACCEPTED
        wait_for(lambda: KIND.Value("MISSION_EVENT_KIND_ENDED") in kinds(), 120,
                 "the mission's ENDED event", logs_in(logs),
                 last=lambda: [KIND.Name(k) for k in kinds()[-5:]])
        sub.undeclare()
    assert KIND.Value("MISSION_EVENT_KIND_RESUMED") in seen
    assert KIND.Value("MISSION_EVENT_KIND_ABORTED") not in seen
    summary = json.loads((cfg.run_dir / "summary.json").read_text())
    check(summary["success"], "the mission to reach the goal", logs_in(logs), summary)
    names = [(c["mode"], c["armed"]) for c in summary["stack"]["vehicle_modes"]]
    offboard, hold = modes.name(modes.offboard), modes.name(modes.hold)
    assert names[:3] == [(hold, False), (offboard, False), (offboard, True)]
    assert (hold, True) in names and names[names.index((hold, True)) + 1] == (offboard, True)
    lines = [json.loads(x) for x in (cfg.run_dir / "steps.jsonl").read_text().splitlines()]
    events_ = [e for e in lines if e.get("event") == "vehicle_mode"]
    assert [(e["mode"], e["armed"]) for e in events_] == names
    assert all(e["autopilot"] == flavour for e in events_)
    faults = [f for e in lines if e.get("kind") == "step" for f in e.get("faults", [])]
    assert any(f.startswith("vehicle_hold") for f in faults), faults

"""End to end: the whole stack with the viewer; a real Foxglove WebSocket client follows the
mission live, and what it received equals the supervisor's records; mission.mcap too."""

from __future__ import annotations

import asyncio
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from integration.foxglove_check import (
    SUBPROTOCOL,
    FoxgloveClient,
    check_decision,
    check_plan,
    check_uav,
    compare_with_log,
    meta,
    read_mcap,
)

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.records import read_step_log
from e2e.conftest import router_ready
from services import launch
from tests.support.waits import check, logs_in, wait_for

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]

UAV = "e2ev"
SEED = 26
TOPICS = ("tf", "area", "fires", "forecast", "plan/system1", "plan/system2", "path", "uav",
          "decision", "events")
#: how long the client waits for the mission's end event after the mission ended (s)
END_WAIT_S = 15.0
SCHEMAS = {"tf": "foxglove.FrameTransform", "forecast": "foxglove.Grid",
           "decision": "dualpilot.Decision", "events": "foxglove.Log"}


class LiveClient(threading.Thread):
    """A Foxglove client in a thread of its own: subscribes to every wanted topic as soon as it
    is advertised, until ``done`` is set."""

    def __init__(self, url: str, wanted: set[str]):
        super().__init__(daemon=True)
        self.url, self.wanted = url, wanted
        self.done = threading.Event()
        self.client: FoxgloveClient | None = None
        self.error: BaseException | None = None

    async def _main(self) -> None:
        for _ in range(300):  # the viewer starts with the stack
            try:
                async with FoxgloveClient(self.url) as c:
                    self.client, self.error = c, None
                    while not self.done.is_set():
                        await c.pump(0.05)
                        await c.subscribe(sorted(self.wanted))
                    # the mission's end reaches the viewer and then this client after the
                    # supervisor's records: on a loaded machine, well after 0.5 s
                    deadline = time.monotonic() + END_WAIT_S
                    while not self._saw_the_end(c) and time.monotonic() < deadline:
                        await c.pump(0.05)
                    await c.pump(0.5)
                    return
            except OSError as err:
                self.error = err  # the last refusal, if it never connects
                await asyncio.sleep(0.1)

    @staticmethod
    def _saw_the_end(c: FoxgloveClient) -> bool:
        return any(m.message.startswith("mission ended after")
                   for _, m in c.received.get(f"/{UAV}/events", []))

    def run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as err:  # reported by the test
            self.error = err


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Any:
    run_dir = tmp_path_factory.mktemp("live") / f"live-cc-s{SEED}"
    cfg = launch.StackConfig(run_dir=run_dir, mission=MissionConfig(seed=SEED),
                             speed_factor=100.0, free_ports=True, uav_id=UAV, log_format="text",
                             profiles=("viewer",))
    stack = launch.Stack(cfg)
    url = stack.viewer_url()
    client = LiveClient(url, {f"/{UAV}/{t}" for t in TOPICS})
    with stack:
        client.start()
        router_ready(stack.endpoint, logs_in(stack.logs))
        outcome = launch.follow(stack, timeout_s=180.0, quiet=True)
        client.done.set()
        wait_for(lambda: not client.is_alive(), 30, "the Foxglove client to finish",
                 logs_in(stack.logs))
    codes = {p.name: int(p.popen.returncode) for p in stack.group.procs}
    return run_dir, outcome, codes, client, url


def test_the_live_view_follows_the_mission(live: Any) -> None:
    run_dir, outcome, codes, thread, url = live
    run_logs = logs_in(run_dir)
    check(outcome.ended, "the mission to end (launch.follow)", run_logs, outcome)
    check(thread.client is not None, "the Foxglove client to connect to the live view",
          run_logs, thread.error)
    check(thread.error is None, "the Foxglove client to follow the mission without an error",
          run_logs, repr(thread.error))
    c: FoxgloveClient = thread.client
    assert c.ws.subprotocol == SUBPROTOCOL and url.startswith("ws://127.0.0.1:")
    channels = c.by_topic()
    for t in TOPICS:
        ch = channels[f"/{UAV}/{t}"]
        assert ch["schemaName"] == SCHEMAS.get(t, "foxglove.SceneUpdate"), t
    entries = read_step_log(run_dir / "steps.jsonl")
    head = next(e for e in entries if e["kind"] == "mission")
    steps = {e["t"]: e for e in entries if e["kind"] == "step"}
    end = next(e for e in entries if e["kind"] == "end")

    decisions = c.received[f"/{UAV}/decision"]
    assert len(decisions) >= len(steps) // 2, (len(decisions), len(steps))
    for _, doc in decisions:
        check_decision(doc, steps[doc["t"]], head["controller"])
    for k in (1, 2):
        got = c.received[f"/{UAV}/plan/system{k}"]
        assert len(got) >= len(steps) // 2
        for _, update in got:
            check_plan(update, steps[int(meta(update.entities[0])["step"])], k)
    states = c.received[f"/{UAV}/uav"]
    assert len(states) >= len(steps) // 2
    for _, update in states:
        step = int(meta(update.entities[0])["step"])
        x = steps[step]["state"] if step in steps else end["final_state"]
        check_uav(update, x, step)
    fires = [u for _, u in c.received[f"/{UAV}/fires"] if u.entities]
    assert fires and all(e.id.startswith(("front/", "hull/")) for u in fires for e in u.entities)
    grid = c.received[f"/{UAV}/forecast"][-1][1]
    assert grid.column_count > 0 and len(grid.data) == grid.row_stride * (
        len(grid.data) // grid.row_stride) and grid.fields[0].name == "p_0s"
    logs = [m.message for _, m in c.received[f"/{UAV}/events"]]
    assert any(m.startswith("mission ended after") for m in logs), logs[-3:]
    # every log time is a sender's wall clock, in order per channel
    for topic, msgs in c.received.items():
        times = [t for t, _ in msgs]
        assert all(t > 1_600_000_000 * 10**9 for t in times), topic

    viewer_log = run_dir / "logs" / "viewer.log"
    text = viewer_log.read_text()
    check("serving the live view" in text and "stopped" in text, "the viewer to log that it "
          "served the live view and stopped", [viewer_log])
    check(codes.get("viewer") == 0, "the viewer to exit with 0", [viewer_log], codes)


def test_the_supervisors_mission_mcap_equals_its_steps_jsonl(live: Any) -> None:
    run_dir = Path(live[0])
    entries = read_step_log(run_dir / "steps.jsonl")
    rec = read_mcap(run_dir / "mission.mcap")
    steps = [e for e in entries if e["kind"] == "step"]
    assert compare_with_log(rec, entries, UAV) == len(steps) > 5
    assert rec.metadata["mission"]["uav"] == UAV

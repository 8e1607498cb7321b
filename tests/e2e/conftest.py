"""One whole mission through the real stack (router + five services from docker-compose.yml).

The seed is one the in-process mission (the same core, same step semantics)
flies to the goal with the cognitive controller: the first success among a
few candidates. While the stack flies it, the test process records every
fire sub-step the EWS publishes and every vehicle state the supervisor
republishes, so the checks do not rely on the supervisor's own records.
"""

from __future__ import annotations

import queue
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from dualpilot.mission.result import MissionResult
from services import launch
from services.common import keys, wire
from services.msgs import fire_pb2, supervisor_pb2, vehicle_pb2

#: seeds to try in order (26 and 57 reached the goal with the core of the time of writing)
CANDIDATE_SEEDS = (26, 57, *range(100, 140))
SEARCH_BUDGET_S = 60.0
SPEED_FACTOR = 100.0


def in_process(seed: int) -> MissionResult:
    from dualpilot.mission.local import local_mission
    from dualpilot.mission.params import Controller, Timing
    from dualpilot.spec import MissionSpec

    return local_mission(Controller.CC, MissionSpec(seed=seed), timing=Timing.PAPER).run()


def successful_seed() -> tuple[int, MissionResult]:
    t0 = time.monotonic()
    tried = []
    for seed in CANDIDATE_SEEDS:
        result = in_process(seed)
        if result.success:
            return seed, result
        tried.append(f"{seed}: {result.failure_cause} at {result.steps}")
        if time.monotonic() - t0 > SEARCH_BUDGET_S:
            break
    pytest.fail(f"no candidate seed reaches the goal in-process ({'; '.join(tried)})")


@dataclass
class Recorded:
    seed: int
    reference: MissionResult
    run_dir: Path
    outcome: launch.Outcome
    codes: dict[str, int]
    wall_s: float
    fires: list[fire_pb2.FireState] = field(default_factory=list)
    states: list[vehicle_pb2.VehicleState] = field(default_factory=list)
    decisions: list[supervisor_pb2.Decision] = field(default_factory=list)


def drain_messages(q: queue.Queue[bytes], cls: Any) -> list[Any]:
    """Every message waiting in ``q`` (payload bytes), parsed as ``cls``."""
    out = []
    while True:
        try:
            out.append(wire.parse(q.get_nowait(), cls))
        except queue.Empty:
            return out


@pytest.fixture(scope="module")
def mission(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Recorded]:
    seed, reference = successful_seed()
    run_dir = tmp_path_factory.mktemp("run") / f"e2e-cc-s{seed}"
    cfg = launch.StackConfig(run_dir=run_dir, seed=seed, speed_factor=SPEED_FACTOR,
                             controller="cc", timing="paper", free_ports=True, uav_id="e2e",
                             log_format="text")
    stack = launch.Stack(cfg)
    inboxes: dict[str, queue.Queue[bytes]] = {k: queue.Queue() for k in ("f", "s", "d")}
    t0 = time.monotonic()
    with stack:
        launch.wait_router(stack.endpoint)
        with launch.client_session(stack.endpoint) as session:
            subs = [session.declare_subscriber(key, lambda s, q=q: q.put(s.payload.to_bytes()))
                    for key, q in ((keys.fires(cfg.uav_id), inboxes["f"]),
                                   (keys.vehicle_state(cfg.uav_id), inboxes["s"]),
                                   (keys.decision(cfg.uav_id), inboxes["d"]))]
            outcome = launch.follow(stack, timeout_s=180.0, quiet=True)
            for sub in subs:
                sub.undeclare()
    wall = time.monotonic() - t0
    codes = {p.name: int(p.popen.returncode) for p in stack.group.procs}
    rec = Recorded(seed, reference, run_dir, outcome, codes, wall,
                   fires=drain_messages(inboxes["f"], fire_pb2.FireState),
                   states=drain_messages(inboxes["s"], vehicle_pb2.VehicleState),
                   decisions=drain_messages(inboxes["d"], supervisor_pb2.Decision))
    yield rec

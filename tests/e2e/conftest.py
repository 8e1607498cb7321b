"""One whole mission through the real stack (router + five services from docker-compose.yml).

The seed is one the in-process mission (the same core, same step semantics)
flies to the goal with the cognitive controller: the first success among a
few candidates. While the stack flies it, the test process records every
fire sub-step the EWS publishes and every vehicle state the supervisor
republishes, so the checks do not rely on the supervisor's own records.
"""

from __future__ import annotations

import queue
import subprocess
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.result import MissionResult
from services import launch
from services.common import bus, keys, wire
from services.forking import server as forkserver
from services.msgs import fire_pb2, supervisor_pb2, vehicle_pb2
from tests.support.waits import Logs, explain, logs_in, wait_for

#: seeds to try, in order and all of them if need be (26 and 57 reached the goal with the core
#: of the time of writing): a fixed list, so which seed flies does not depend on how fast the
#: machine runs the in-process missions
CANDIDATE_SEEDS = (26, 57, *range(100, 140))
SPEED_FACTOR = 100.0


# -- waits that explain themselves (tests/support/waits.py) for the stack's own waits -------------
def router_ready(endpoint: str, logs: Logs, timeout_s: float = 30.0) -> None:
    """:func:`launch.wait_router`, failing with the processes' last lines."""
    try:
        launch.wait_router(endpoint, timeout_s)
    except TimeoutError as err:
        pytest.fail(explain(f"timed out after {timeout_s:g} s waiting for the Zenoh router "
                            f"to accept connections ({err})", logs), pytrace=False)


def alive(live: bus.Liveliness, services: Iterable[str], timeout_s: float, logs: Logs) -> None:
    """Wait until every one of ``services`` holds its liveliness token."""
    names = sorted(services)
    wait_for(lambda: not live.missing(names), timeout_s,
             f"the liveliness tokens of {', '.join(names)}", logs,
             last=lambda: f"still missing: {sorted(live.missing(names))}")


def gone(live: bus.Liveliness, service: str, timeout_s: float, logs: Logs) -> None:
    """Wait until ``service``'s liveliness token is gone."""
    wait_for(lambda: live.missing([service]), timeout_s,
             f"{service}'s liveliness token to go", logs,
             last=lambda: f"{service} holders: {live.replicas(service) or live.holder(service)}")


def run_process(argv: Sequence[str], timeout_s: float, what: str,
                logs: Logs | Callable[[], Logs] = None,
                **kwargs: Any) -> subprocess.CompletedProcess[str]:
    """``subprocess.run`` (text, output captured) that, past ``timeout_s``, fails with what it
    ran, its output so far and the logs' tails (instead of a bare TimeoutExpired); ``logs``
    may be a function, for logs the process itself creates."""
    try:
        return subprocess.run(list(argv), capture_output=True, text=True, timeout=timeout_s,
                              **kwargs)
    except subprocess.TimeoutExpired as err:
        out = "".join(x.decode(errors="replace") if isinstance(x, bytes) else (x or "")
                      for x in (err.stdout, err.stderr))
        shown = logs() if callable(logs) else logs
        pytest.fail(explain(f"timed out after {timeout_s:g} s waiting for {what} to end",
                            shown, f"its output so far:\n{out[-3000:]}"), pytrace=False)


def in_process(seed: int) -> MissionResult:
    from dualpilot.mission.local import local_mission

    return local_mission(MissionConfig(seed=seed)).run()


def successful_seed() -> tuple[int, MissionResult]:
    """The first of :data:`CANDIDATE_SEEDS` the in-process mission flies to the goal."""
    tried = []
    for seed in CANDIDATE_SEEDS:
        result = in_process(seed)
        if result.success:
            return seed, result
        tried.append(f"{seed}: {result.failure_cause} at {result.steps}")
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


@pytest.fixture(scope="module", autouse=True)
def forked_services() -> Iterator[None]:
    """The services of this tier's stacks come from the warm fork server
    (services/forking/server.py: what ``python -m services.<name>`` would be, without a
    second of start-up CPU each); the integration tier, run in the same pytest process,
    starts fresh interpreters."""
    forkserver.enable()
    yield
    forkserver.disable()


def pytest_sessionfinish() -> None:
    """The fork server ends with the session, waited for (an xdist worker may leave without
    running atexit): the services' CPU time is then counted in the test run's."""
    forkserver.stop()


@pytest.fixture(scope="module")
def mission(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Recorded]:
    seed, reference = successful_seed()
    run_dir = tmp_path_factory.mktemp("run") / f"e2e-cc-s{seed}"
    cfg = launch.StackConfig(run_dir=run_dir, mission=MissionConfig(seed=seed),
                             speed_factor=SPEED_FACTOR, free_ports=True, uav_id="e2e",
                             log_format="text")
    stack = launch.Stack(cfg)
    inboxes: dict[str, queue.Queue[bytes]] = {k: queue.Queue() for k in ("f", "s", "d")}
    t0 = time.monotonic()
    with stack:
        router_ready(stack.endpoint, logs_in(stack.logs))
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

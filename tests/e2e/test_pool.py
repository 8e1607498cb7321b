"""A planner pool: three System 2 replicas serve one mission; one is killed mid-request.

``--scale system2=3`` (services.launch, as ``docker compose up --scale``)
starts three replicas; each holds System 2's token under its own Zenoh id
and answers on ``plan/system2/<zid>``. The supervisor asks the mission's
replica (rendezvous order, services/supervisor/ports.py). The test freezes
that replica (SIGSTOP) while a request is waiting on it, then kills it
(SIGKILL): Zenoh ends the pending query, the supervisor asks the next
replica within the same deadline, and the mission goes on — no plan lost,
no deadline missed, every step recorded.
"""

from __future__ import annotations

import hashlib
import json
import os
import queue
import re
import signal
import time
from pathlib import Path
from typing import Any

import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.records import read_step_log
from services import launch
from services.common import bus, keys, wire
from services.msgs import supervisor_pb2
from tests.support.waits import check, logs_in, wait_for

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]

EV = supervisor_pb2
SEED = 26


def rendezvous(mission_id: str, zids: list[str]) -> list[str]:
    """The replica order of services/supervisor/ports.py, worked out here on its own."""
    return sorted(zids, key=lambda z: hashlib.blake2b(f"{mission_id}/{z}".encode(),
                                                      digest_size=8).digest())


def zid_of(log: Path) -> str:
    found = re.search(r"zenoh session open .*zid=([0-9a-f]+)", log.read_text())
    check(found is not None, "a replica's log to name its Zenoh id", [log])
    return found.group(1) if found else ""


def requests_to(log: Path, replica: str) -> list[tuple[int, int]]:
    """(seq, stamp in wall ns) of every plan request the supervisor sent ``replica``, from its
    DEBUG lines."""
    found = re.findall(rf"plan request sent .*replica={replica} seq=(\d+) stamped_ns=(\d+)",
                       log.read_text(errors="replace"))
    return [(int(seq), int(ns)) for seq, ns in found]


def replies_from(log: Path, replica: str) -> set[int]:
    """The request seqs whose replies from ``replica`` the supervisor received."""
    return {int(seq) for seq in re.findall(
        rf"plan reply received .*replica={replica} seq=(\d+)", log.read_text(errors="replace"))}


def pending_at(log: Path, replica: str, stopped_ns: int, grace_s: float = 2.0) -> bool:
    """Whether a request to the stopped ``replica`` is certainly pending: one stamped after the
    stop (it cannot have been answered), or one from before whose reply has not come within
    ``grace_s`` of the stop (a reply already on its way over loopback arrives in microseconds;
    it is the supervisor's 5 s deadline that must not pass before the kill)."""
    sent, got = requests_to(log, replica), replies_from(log, replica)
    if any(ns > stopped_ns for _, ns in sent):
        return True
    waiting = [seq for seq, _ in sent if seq not in got]
    return bool(waiting) and time.time_ns() - stopped_ns > grace_s * 1e9


def test_a_replica_killed_mid_request_loses_no_plan(tmp_path: Path) -> None:
    cfg = launch.StackConfig(run_dir=tmp_path / "pool",
                             mission=MissionConfig.named("s2", seed=SEED), speed_factor=10.0,
                             free_ports=True,
                             log_format="text", scale={"system2": 3},
                             extra_env={"supervisor": {"LOG_LEVEL": "DEBUG"}})
    events: queue.Queue[bytes] = queue.Queue()
    with launch.Stack(cfg) as stack, launch.client_session(stack.endpoint) as session:
        logs = logs_in(stack.logs)
        live = bus.Liveliness(session, cfg.uav_id)
        sub = session.declare_subscriber(keys.mission_event(cfg.uav_id),
                                         lambda s: events.put(s.payload.to_bytes()))
        wait_for(lambda: len(live.replicas("system2")) >= 3, 120,
                 "three System 2 replicas' liveliness tokens", logs,
                 last=lambda: f"replicas {live.replicas('system2')}")
        procs = {zid_of(p.log_path): p for p in stack.group.procs
                 if p.name.startswith("system2")}
        assert set(procs) == set(live.replicas("system2"))
        seen: list[Any] = []

        def event(pred: Any) -> Any:
            try:
                seen.append(wire.parse(events.get(timeout=0.5), EV.MissionEvent))
            except queue.Empty:
                return None
            return seen[-1] if pred(seen[-1]) else None

        wait_for(lambda: event(lambda e: e.kind == EV.MISSION_EVENT_KIND_STEP and e.step >= 5),
                 120, "the STEP event of step 5", logs, period_s=0,
                 last=lambda: seen[-1] if seen else "no mission event")
        victim_zid = rendezvous(cfg.run_dir.name, list(procs))[0]
        victim = procs[victim_zid]
        supervisor_log = stack.logs / "supervisor.log"
        os.killpg(victim.popen.pid, signal.SIGSTOP)
        stopped_ns = time.time_ns()
        # the replica dies with a request pending (the supervisor logs at DEBUG each request it
        # sends, with its stamp, and each reply it receives)
        wait_for(lambda: pending_at(supervisor_log, victim_zid, stopped_ns), 60,
                 f"a plan request pending at the stopped replica {victim_zid}", logs)
        os.killpg(victim.popen.pid, signal.SIGKILL)
        victim.popen.wait()
        ended = wait_for(lambda: event(lambda e: e.kind in (
            EV.MISSION_EVENT_KIND_ENDED, EV.MISSION_EVENT_KIND_ABORTED)), 120,
            "the mission's end (ENDED or ABORTED)", logs_in(stack.logs), period_s=0,
            last=lambda: seen[-1] if seen else "no mission event")
        sub.undeclare()
        check(ended.kind == EV.MISSION_EVENT_KIND_ENDED, "the mission to end, not abort",
              logs_in(stack.logs), ended)
        wait_for(lambda: len(live.replicas("system2")) == 2, 15,
                 "the killed replica's liveliness token to go", logs_in(stack.logs),
                 last=lambda: f"replicas {live.replicas('system2')}")
    entries = read_step_log(cfg.run_dir / "steps.jsonl")
    steps = [e for e in entries if e.get("kind") == "step"]
    assert [e["t"] for e in steps] == list(range(len(steps))) and len(steps) == ended.step
    assert all(e["plan_status"].startswith("s2:ok") for e in steps), [
        e["plan_status"] for e in steps if not e["plan_status"].startswith("s2:ok")]
    assert not [f for e in steps for f in e.get("faults", [])]
    summary = json.loads((cfg.run_dir / "summary.json").read_text())
    assert summary["stack"]["planner_failovers"] >= 1
    assert summary["stack"]["faults"] == {}
    supervisor_log = stack.logs / "supervisor.log"
    check("failed over" in supervisor_log.read_text(), "the supervisor to log its fail-over",
          [supervisor_log])

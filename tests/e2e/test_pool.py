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

import pytest

from dualpilot.mission.records import read_step_log
from services import launch
from services.common import bus, keys, wire
from services.msgs import supervisor_pb2

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]

EV = supervisor_pb2
SEED = 26


def rendezvous(mission_id: str, zids: list[str]) -> list[str]:
    """The replica order of services/supervisor/ports.py, worked out here on its own."""
    return sorted(zids, key=lambda z: hashlib.blake2b(f"{mission_id}/{z}".encode(),
                                                      digest_size=8).digest())


def zid_of(log: Path) -> str:
    found = re.search(r"zenoh session open .*zid=([0-9a-f]+)", log.read_text())
    assert found, log
    return found.group(1)


def test_a_replica_killed_mid_request_loses_no_plan(tmp_path: Path) -> None:
    cfg = launch.StackConfig(run_dir=tmp_path / "pool", seed=SEED, speed_factor=10.0,
                             controller="s2", timing="paper", free_ports=True,
                             log_format="text", scale={"system2": 3})
    events: queue.Queue[bytes] = queue.Queue()
    with launch.Stack(cfg) as stack, launch.client_session(stack.endpoint) as session:
        live = bus.Liveliness(session, cfg.uav_id)
        sub = session.declare_subscriber(keys.mission_event(cfg.uav_id),
                                         lambda s: events.put(s.payload.to_bytes()))
        deadline = time.monotonic() + 120
        while len(live.replicas("system2")) < 3:
            assert time.monotonic() < deadline, live.replicas("system2")
            time.sleep(0.1)
        procs = {zid_of(p.log_path): p for p in stack.group.procs
                 if p.name.startswith("system2")}
        assert set(procs) == set(live.replicas("system2"))
        ended = None
        step5 = False
        while ended is None and time.monotonic() < deadline:
            try:
                ev = wire.parse(events.get(timeout=0.5), EV.MissionEvent)
            except queue.Empty:
                continue
            if ev.kind in (EV.MISSION_EVENT_KIND_ENDED, EV.MISSION_EVENT_KIND_ABORTED):
                ended = ev
            elif ev.kind == EV.MISSION_EVENT_KIND_STEP and ev.step >= 5 and not step5:
                step5 = True
                victim = procs[rendezvous(cfg.run_dir.name, list(procs))[0]]
                os.killpg(victim.popen.pid, signal.SIGSTOP)
                time.sleep(1.0)  # a step at speed 10 is at most 0.6 s: a request now waits
                os.killpg(victim.popen.pid, signal.SIGKILL)
                victim.popen.wait()
                killed_at = time.monotonic()
        sub.undeclare()
        assert step5 and ended is not None
        assert ended.kind == EV.MISSION_EVENT_KIND_ENDED, ended.message
        while len(live.replicas("system2")) != 2 and time.monotonic() < killed_at + 15:
            time.sleep(0.1)
        assert len(live.replicas("system2")) == 2
    entries = read_step_log(cfg.run_dir / "steps.jsonl")
    steps = [e for e in entries if e.get("kind") == "step"]
    assert [e["t"] for e in steps] == list(range(len(steps))) and len(steps) == ended.step
    assert all(e["plan_status"].startswith("s2:ok") for e in steps), [
        e["plan_status"] for e in steps if not e["plan_status"].startswith("s2:ok")]
    assert not [f for e in steps for f in e.get("faults", [])]
    summary = json.loads((cfg.run_dir / "summary.json").read_text())
    assert summary["stack"]["planner_failovers"] >= 1
    assert summary["stack"]["faults"] == {}
    supervisor_log = (stack.logs / "supervisor.log").read_text()
    assert "failed over" in supervisor_log

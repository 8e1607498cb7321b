"""A planner pool: three System 2 replicas serve one mission; one is killed mid-request.

``--scale system2=3`` (services.launch, as ``docker compose up --scale``)
starts three replicas; each holds System 2's token under its own Zenoh id
and answers on ``plan/system2/<zid>``. The supervisor asks the mission's
replica (rendezvous order, services/supervisor/pool.py). The test freezes
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
import subprocess
import sys
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
#: the pace of the missions (System 2, paper timing: 336 simulated s, ~17 s of wall time); the
#: plan deadlines the fail-over must keep are in wall time, whatever the pace
SPEED = 20


def rendezvous(mission_id: str, zids: list[str]) -> list[str]:
    """The replica order of services/supervisor/pool.py, worked out here on its own."""
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
                             mission=MissionConfig.named("s2", seed=SEED), speed_factor=SPEED,
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


def _join(endpoint: str, out: Path, uavs: list[str]) -> subprocess.Popen[str]:
    """A second launcher on the stack's router: one System 2 replica serving ``uavs``."""
    return subprocess.Popen(
        [sys.executable, "-m", "services.launch", "--join", endpoint, "--services", "system2",
         "--uav-ids", ",".join(uavs), "--out", str(out), "--log-format", "text"],
        cwd=launch.REPO, env=dict(os.environ, PYTHONPATH=str(launch.REPO)),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)


def _processes_of(run_dir: Path) -> list[int]:
    """The processes started with ``run_dir`` as their RUN_DIR (a launcher's services)."""
    mark = f"RUN_DIR={run_dir}".encode()
    found = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit() and mark in (proc / "environ").read_bytes().split(b"\0"):
                found.append(int(proc.name))
        except OSError:
            continue
    return found


def test_replicas_of_a_second_launcher_serve_a_fleet_and_fail_over_when_it_dies(
        tmp_path: Path) -> None:
    """A fleet whose System 2 runs only on two other launchers (``--join``: they share the
    router, nothing else, as replicas on other machines would). The host whose replica a
    mission asks first dies (SIGKILL to its launcher and its replica) while the missions fly:
    each goes on with the other host's replica, no step without a plan, no fault."""
    uavs = ["j1", "j2"]
    cfg = launch.StackConfig(run_dir=tmp_path / "shared", speed_factor=SPEED, free_ports=True,
                             log_format="text")
    hosts = {name: tmp_path / name for name in ("host-a", "host-b")}
    joined: dict[str, subprocess.Popen[str]] = {}
    with launch.Fleet(cfg, uavs, shared=("ews", "system1")) as fleet, \
            launch.client_session(fleet.endpoint) as session:
        logs = [*logs_in(fleet.stack.logs), *(p for h in hosts.values() for p in logs_in(h))]
        live = bus.Liveliness(session, uavs[0])
        try:
            for name, out in hosts.items():
                joined[name] = _join(fleet.endpoint, out, uavs)
                wait_for(lambda: len(live.replicas("system2")) == len(joined), 120,
                         f"{name}'s System 2 replica", logs)
            zids = {zid_of(out / "logs" / "system2.log"): name for name, out in hosts.items()}
            mission = MissionConfig.named("s2", seed=SEED)
            ids = {uav: fleet.start_vehicle(uav, SEED, tmp_path / uav, config=mission,
                                            env={"SPEED_FACTOR": str(SPEED)}).mission_id
                   for uav in uavs}
            victim = zids[rendezvous(ids["j1"], list(zids))[0]]  # j1's replica: its host dies
            wait_for(lambda: all(_steps(tmp_path / u) >= 5 for u in uavs), 120,
                     "both missions at step 5", logs)
            killed_at = _steps(tmp_path / "j1")
            for pid in [joined[victim].pid, *_processes_of(hosts[victim])]:
                os.kill(pid, signal.SIGKILL)  # the host dies: its launcher and its replica
            joined[victim].wait()
            outcomes = fleet.wait_end(ids, 200.0)
            check(all(o.ended for o in outcomes.values()), "both missions to end", logs,
                  outcomes)
            check(len(live.replicas("system2")) == 1, f"{victim}'s replica to be gone", logs,
                  live.replicas("system2"))
        finally:
            for proc in joined.values():
                if proc.poll() is None:
                    proc.send_signal(signal.SIGTERM)
                    proc.wait(60)
    for uav in uavs:
        steps = [e for e in read_step_log(tmp_path / uav / "steps.jsonl")
                 if e.get("kind") == "step"]
        assert steps and all(e["plan_status"].startswith("s2:ok") for e in steps), [
            e["plan_status"] for e in steps]
        assert not [f for e in steps for f in e.get("faults", [])]
    assert _steps(tmp_path / "j1") >= killed_at + 5, "j1 flew on after its replica's host died"
    survivor = next(name for name in hosts if name != victim)
    served = (hosts[survivor] / "logs" / "system2.log").read_text()
    assert f"planner ready mission={ids['j1']}" in served, served[-2000:]
    assert not _processes_of(hosts["host-a"]) and not _processes_of(hosts["host-b"])


def _steps(run_dir: Path) -> int:
    """How many step lines a vehicle's record holds so far."""
    path = run_dir / "steps.jsonl"
    return sum(1 for e in read_step_log(path) if e.get("kind") == "step") if path.is_file() else 0

"""A fleet flown across the test bed, each vehicle on its own air host and its own radio link.

A real deployment gives each UAV its own radio or LTE link to the ground; the vehicles share
only the ground. :func:`topology` makes that test bed: the host ``ground`` and hosts
``air1`` … ``airN``, link ``radio<k>`` between ``air<k>`` and ``ground`` (subnet
``10.10.k.0/24``), each shaped by its own impairer, so a bandwidth, a loss draw or an outage of
one vehicle's link is that vehicle's alone.

:func:`fly_fleet` runs the ground's part of the stack once (``python -m services.launch --role
ground``: the router, the EWS, the System 2 pool, serving ``uav1`` … ``uavN``) and each
vehicle's air part in its own host (``--role air --uav-id uav<k>``: its router joining the
ground's across its link, uavsim, the supervisor, System 1; one mission), every radio link
shaped alike, each cut for ``outage_s`` once its own vehicle's record holds step
``outage_at_step`` (services/testbed/mission.py :class:`Watch`). Each vehicle's records go to
``<run_dir>/uav<k>/`` with a ``link.json`` of its own link's counters; the ground's logs to
``<run_dir>/ground/``.
"""

from __future__ import annotations

import json
import logging
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from services.launch import Proc
from services.testbed.bed import TestBed
from services.testbed.impairment import Impairment
from services.testbed.mission import LinkPlan, Watch, step_lines, wire_per_step
from services.testbed.topology import LinkSpec, Topology

log = logging.getLogger(__name__)

GROUND = "ground"
#: the ground router's port, on every one of its radio links
PORT = 7447
#: how long the ground's services may take to be alive before the vehicles start anyway (s)
GROUND_READY_S = 90.0


def air(k: int) -> str:
    """Vehicle ``k``'s air host (from 1)."""
    return f"air{k}"


def radio(k: int) -> str:
    """Vehicle ``k``'s radio link (from 1)."""
    return f"radio{k}"


def uav(k: int) -> str:
    """Vehicle ``k``'s id (from 1), as the ground's services serve it."""
    return f"uav{k}"


def topology(n: int) -> Topology:
    """``ground`` and ``air1`` … ``air<n>``, link ``radio<k>`` = ``10.10.k.0/24`` (ground .1,
    air<k> .k+1)."""
    if not 1 <= n <= 64:
        raise ValueError(f"a fleet on the test bed has 1..64 vehicles, got {n}")
    return Topology(hosts=(GROUND, *(air(k) for k in range(1, n + 1))),
                    links=tuple(LinkSpec(radio(k), air(k), GROUND, k) for k in range(1, n + 1)))


@dataclass(frozen=True)
class FleetPlan:
    """The fleet's missions and what every radio link does.

    Parameters
    ----------
    seeds : vehicle k flies ``seeds[k - 1]``.
    mission : ``dualpilot mission`` flags besides the seed (controller, timing, scenario).
    radio : each link's impairment, both directions.
    outage_at_step : cut a vehicle's link once its record holds this step (None: never).
    outage_s : how long a cut lasts, s.
    speed_factor : simulated s per wall s (1: real time).
    timeout_s : a mission's time limit, wall s.
    stagger_s : wall s between two vehicles' starts.
    system2 : replicas of System 2 on the ground.
    """

    seeds: tuple[int, ...]
    mission: tuple[str, ...]
    radio: Impairment = Impairment()
    outage_at_step: int | None = None
    outage_s: float = 0.0
    speed_factor: float = 1.0
    timeout_s: float = 900.0
    stagger_s: float = 1.0
    system2: int = 2


@dataclass
class FlownVehicle:
    """One vehicle's mission: its records' directory, the air launcher's exit code, the outage
    it got (``at_step``, ``seconds``; empty: none) and its link's bytes over the mission."""

    uav: str
    seed: int
    run_dir: Path
    air_exit: int | None
    outage: dict[str, Any]
    wire: dict[str, Any]
    steps: int


def ground_argv(run_dir: Path, uav_ids: list[str], system2: int) -> list[str]:
    return [sys.executable, "-m", "services.launch", "--role", "ground",
            "--listen", f"tcp/0.0.0.0:{PORT}", "--out", str(run_dir / "ground"),
            "--uav-ids", ",".join(uav_ids), "--scale", f"system2={system2}",
            "--log-format", "text"]


def air_argv(endpoint: str, run_dir: Path, uav_id: str, seed: int,
             plan: FleetPlan) -> list[str]:
    return [sys.executable, "-m", "services.launch", "--role", "air", "--join", endpoint,
            "--uav-id", uav_id, "--out", str(run_dir), "--speed-factor",
            f"{plan.speed_factor:g}", "--timeout-s", f"{plan.timeout_s:g}", "--no-figures",
            "--log-format", "text", *plan.mission, "--seed", str(seed)]


def _ground_ready(run_dir: Path, ground: Proc, timeout_s: float) -> bool:
    """Wait until every ground service but the router has declared a liveliness token."""
    logs = run_dir / "ground" / "logs"
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and ground.popen.poll() is None:
        files = [p for p in logs.glob("*.log") if p.stem != "router"]
        if files and all("alive key=" in p.read_text(errors="replace") for p in files):
            return True
        time.sleep(0.5)
    return False


def fly_fleet(bed: TestBed, run_dir: Path, plan: FleetPlan) -> list[FlownVehicle]:
    """Fly ``plan`` across ``bed`` (up, of :func:`topology` with at least as many vehicles as
    seeds) into ``run_dir``; every process it started is stopped before it returns."""
    n = len(plan.seeds)
    run_dir.mkdir(parents=True, exist_ok=True)
    link = LinkPlan(radio=plan.radio, outage_s=plan.outage_s,
                    outage_at_step=plan.outage_at_step if plan.outage_s > 0 else None)
    for k in range(1, n + 1):
        bed.link(radio(k)).set(plan.radio)
    ground = bed.host(GROUND)
    g = ground.start("launch", ground_argv(run_dir, [uav(k) for k in range(1, n + 1)],
                                           plan.system2), log_path=run_dir / "ground.out")
    airs: list[Proc] = []
    watches: list[Watch] = []
    try:
        if not _ground_ready(run_dir, g, GROUND_READY_S):
            if g.popen.poll() is not None:
                tail = (run_dir / "ground.out").read_text(errors="replace")[-2000:]
                raise RuntimeError(f"the ground's launcher exited {g.popen.returncode}: {tail}")
            log.warning("the ground's services were not all alive within %.0f s; flying anyway",
                        GROUND_READY_S)
        for k, seed in enumerate(plan.seeds, start=1):
            vdir = run_dir / uav(k)
            vdir.mkdir(parents=True, exist_ok=True)
            endpoint = f"tcp/{ground.address(air(k))}:{PORT}"
            host = bed.host(air(k))
            airs.append(host.start("launch", air_argv(endpoint, vdir, uav(k), seed, plan),
                                   log_path=vdir / "air.out"))
            watches.append(Watch(bed, vdir, link, host=air(k), radio=radio(k)))
            _follow(watches, plan.stagger_s)
        deadline = time.monotonic() + plan.timeout_s + 60.0
        while any(a.popen.poll() is None for a in airs) and time.monotonic() < deadline:
            _follow(watches, 0.2)
        _follow(watches, 0.0)
    finally:
        exits = [bed.processes.stop(a) for a in airs]
        bed.processes.stop(g, grace_s=5.0)
        for proc in [*airs, g]:  # the next round's processes are a new list's
            bed.processes.procs.remove(proc)
    out = []
    for k, (seed, watch, code) in enumerate(zip(plan.seeds, watches, exits, strict=True),
                                             start=1):
        out.append(_report(uav(k), seed, watch, code, plan))
    return out


def _follow(watches: list[Watch], seconds: float) -> None:
    """Poll every vehicle's record (outage on cue, counters) for about ``seconds``."""
    end = time.monotonic() + seconds
    while True:
        for w in watches:
            w.poll()
        if time.monotonic() >= end:
            return
        time.sleep(min(0.2, max(0.0, end - time.monotonic())))


def _report(uav_id: str, seed: int, watch: Watch, code: int | None,
            plan: FleetPlan) -> FlownVehicle:
    """The vehicle's ``link.json`` (its radio's counters from its first step to its end)."""
    steps = sum(1 for e in step_lines(watch.run_dir) if e.get("kind") == "step")
    mission = (watch.last - watch.first if watch.first is not None and watch.last is not None
               else None)
    outage = {k: v for k, v in watch.outage.items() if k not in ("start", "end")}
    wire = wire_per_step(mission, steps)
    doc = {"uav": uav_id, "seed": seed, "steps": steps, "radio": plan.radio.wire(),
           "outage": outage, "wire_mission": wire,
           "counters_first_step": watch.first.wire() if watch.first else None,
           "counters_end": watch.last.wire() if watch.last else None}
    (watch.run_dir / "link.json").write_text(json.dumps(doc, indent=1) + "\n")
    return FlownVehicle(uav_id, seed, watch.run_dir, code, outage, wire, steps)


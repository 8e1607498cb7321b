"""A mission flown across the test bed's hosts, the air–ground link shaped and cut on cue.

:func:`fly` runs the ground host's part of the stack (``python -m services.launch --role
ground``: the router, the EWS, System 2) in ``ground`` and the air host's (``--role air``:
its router joining the ground's, uavsim, the supervisor, System 1; one mission) in ``air``,
shapes the radio link (:class:`LinkPlan`), takes it down for ``outage_s`` once the mission's
record reaches ``outage_at_step``, and leaves in the run directory, beside the mission's
records:

* ``ground/`` — the ground host's logs and traffic tables;
* ``link.json`` — what crossed the radio link: its interface counters over the mission (from
  the first step line to the end line) and over the whole run, per step, the payload per key
  expression and direction (services/testbed/linkbytes.py), the outage's times and the
  impairer's own counters.

The test bed's processes are stopped when it goes down; :func:`fly` stops the ground's part
itself once the air's has ended.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from services.testbed import linkbytes
from services.testbed.bed import TestBed
from services.testbed.impairment import Impairment

#: the mission the test bed flies by default: the forecast crosses the link, System 2
#: deliberates on the ground while System 1 flies onboard, planning time measured (the
#: link's delay is part of it)
MISSION = ("--controller", "concurrent+risk", "--seed", "26", "--timing", "measured")
#: the vehicle's id (the air launcher's own)
UAV = "uav1"


@dataclass(frozen=True)
class LinkPlan:
    """What the radio link does during the mission."""

    radio: Impairment = Impairment(delay_ms=50.0, jitter_ms=10.0, rate_mbit=1.0)
    telem: Impairment = Impairment()
    #: cut the radio link once the record holds this step's line (None: never)
    outage_at_step: int | None = None
    outage_s: float = 10.0


@dataclass(frozen=True)
class FlightPlan:
    """The mission (``dualpilot mission``'s flags), its pace and its time limit (wall s)."""

    mission: tuple[str, ...] = MISSION
    speed_factor: float = 2.0
    link: LinkPlan = field(default_factory=LinkPlan)
    timeout_s: float = 300.0


@dataclass
class Flown:
    """What :func:`fly` saw: the air launcher's exit code, the outage's wall times
    (monotonic s) and the step it began at, and ``link.json``'s content."""

    run_dir: Path
    air_exit: int | None
    outage: dict[str, Any]
    link: dict[str, Any]


def step_lines(run_dir: Path) -> list[dict[str, Any]]:
    """The record's lines so far (a line being written is skipped)."""
    path = run_dir / "steps.jsonl"
    if not path.is_file():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return out


def ground_argv(endpoint: str, run_dir: Path, uav_id: str) -> list[str]:
    return [sys.executable, "-m", "services.launch", "--role", "ground", "--listen", endpoint,
            "--out", str(run_dir / "ground"), "--uav-ids", uav_id, "--log-format", "text"]


def air_argv(endpoint: str, run_dir: Path, plan: FlightPlan) -> list[str]:
    return [sys.executable, "-m", "services.launch", "--role", "air", "--join", endpoint,
            "--out", str(run_dir), "--speed-factor", f"{plan.speed_factor:g}",
            "--timeout-s", f"{plan.timeout_s:g}", "--no-figures",
            "--log-format", "text", *plan.mission]


class Watch:
    """Follows the record: the interface counters at the first step and at the end, and the
    outage on cue (host ``host``'s link ``radio``: a fleet's vehicle has its own). Each poll
    reads only the lines written since the last."""

    def __init__(self, bed: TestBed, run_dir: Path, link: LinkPlan, host: str = "air",
                 radio: str = "radio"):
        self.bed, self.run_dir, self.link, self.radio = bed, run_dir, link, radio
        self.air_ns = bed.host(host).netns
        self.first: linkbytes.Counters | None = None
        self.last: linkbytes.Counters | None = None
        self.outage: dict[str, Any] = {}
        self.last_step: int | None = None
        self.ended = False
        self._offset = 0

    def _new_lines(self) -> list[dict[str, Any]]:
        """The record's whole lines written since the last call (a bad line is skipped)."""
        path = self.run_dir / "steps.jsonl"
        if not path.is_file():
            return []
        with path.open("rb") as fh:
            fh.seek(self._offset)
            data = fh.read()
        cut = data.rfind(b"\n")
        if cut < 0:
            return []
        self._offset += cut + 1
        out = []
        for line in data[:cut].splitlines():
            try:
                out.append(json.loads(line))
            except json.JSONDecodeError:
                continue
        return out

    def poll(self) -> None:
        for e in self._new_lines():
            if e.get("kind") == "step":
                self.last_step = max(int(e["t"]), self.last_step or 0)
            elif e.get("kind") == "end":
                self.ended = True
        if self.last_step is not None and self.first is None:
            self.first = linkbytes.counters(self.air_ns, self.radio)
        at = self.link.outage_at_step
        if (at is not None and not self.outage and self.last_step is not None
                and self.last_step >= at):
            start = time.monotonic()
            self.bed.link(self.radio).outage(self.link.outage_s)
            self.outage = {"at_step": self.last_step, "start": start,
                           "end": start + self.link.outage_s, "seconds": self.link.outage_s,
                           "wall_time_s": time.time()}
        if self.last is None and self.ended:
            self.last = linkbytes.counters(self.air_ns, self.radio)


def fly(bed: TestBed, run_dir: Path, plan: FlightPlan,
        during: Callable[[TestBed, Path], None] | None = None) -> Flown:
    """Fly ``plan`` across ``bed`` (up) into ``run_dir``; ``during`` is called about every
    0.1 s while the mission flies (a ground station's turn)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    bed.link("radio").set(plan.link.radio)
    bed.link("telem").set(plan.link.telem)
    ground, air = bed.host("ground"), bed.host("air")
    endpoint = f"tcp/{ground.address('air')}:7447"
    before = linkbytes.counters(air.netns, "radio")
    g = ground.start("launch", ground_argv(endpoint, run_dir, UAV),
                     log_path=run_dir / "ground.out")
    a = air.start("launch", air_argv(endpoint, run_dir, plan), log_path=run_dir / "air.out")
    watch = Watch(bed, run_dir, plan.link)
    deadline = time.monotonic() + plan.timeout_s + 60.0
    while a.popen.poll() is None and time.monotonic() < deadline:
        watch.poll()
        if during is not None:
            during(bed, run_dir)
        time.sleep(0.1)
    watch.poll()
    air_exit = bed.processes.stop(a)
    after = linkbytes.counters(air.netns, "radio")
    bed.processes.stop(g, grace_s=5.0)
    link = link_report(bed, run_dir, plan, watch, before, after)
    (run_dir / "link.json").write_text(json.dumps(link, indent=1) + "\n")
    return Flown(run_dir, air_exit, watch.outage, link)


def wire_per_step(c: linkbytes.Counters | None, steps: int) -> dict[str, Any]:
    """The air host's radio counters as air → ground and ground → air, in all and per step."""
    if c is None:
        return {}
    n = max(1, steps)
    return {"air_to_ground_bytes": c.tx_bytes, "ground_to_air_bytes": c.rx_bytes,
            "air_to_ground_packets": c.tx_packets, "ground_to_air_packets": c.rx_packets,
            "bytes_per_step": round((c.tx_bytes + c.rx_bytes) / n, 1),
            "air_to_ground_per_step": round(c.tx_bytes / n, 1),
            "ground_to_air_per_step": round(c.rx_bytes / n, 1)}


def link_report(bed: TestBed, run_dir: Path, plan: FlightPlan, watch: Watch,
                before: linkbytes.Counters, after: linkbytes.Counters) -> dict[str, Any]:
    """``link.json``: the wire counters, the payload per key expression, the outage."""
    steps = sum(1 for e in step_lines(run_dir) if e.get("kind") == "step")
    tables = linkbytes.read_tables([run_dir / "traffic", run_dir / "ground" / "traffic"])
    rows = linkbytes.per_step(linkbytes.crossing(tables, "air", "ground"), steps)
    mission = (watch.last - watch.first if watch.first is not None and watch.last is not None
               else None)
    return {
        "steps": steps, "mission": list(plan.mission), "speed_factor": plan.speed_factor,
        "radio": plan.link.radio.wire(), "telem": plan.link.telem.wire(),
        "outage": {k: v for k, v in watch.outage.items() if k not in ("start", "end")},
        "wire_mission": wire_per_step(mission, steps),
        "wire_run": wire_per_step(after - before, steps),
        "payload": rows, "payload_per_step": _totals(rows, steps),
        "processes": sorted(f"{t['host']}/{t['service']}" for t in tables),
        "impairer": _stats(bed),
    }


def _totals(rows: Sequence[dict[str, Any]], steps: int) -> dict[str, float]:
    n = max(1, steps)
    up = sum(r["bytes"] for r in rows if r["from"] == "air")
    down = sum(r["bytes"] for r in rows if r["from"] == "ground")
    return {"air_to_ground": round(up / n, 1), "ground_to_air": round(down / n, 1),
            "both": round((up + down) / n, 1)}


def _stats(bed: TestBed) -> dict[str, Any]:
    try:
        return bed.link("radio").stats()
    except Exception as err:  # the counters are a nicety: the report stands without them
        return {"error": str(err)}


def describe(flown: Flown) -> str:
    """A few lines for people: the mission's end and what crossed the link per step."""
    link = flown.link
    w = link.get("wire_mission") or link.get("wire_run", {})
    p = link.get("payload_per_step", {})
    lines = [f"air launcher exit {flown.air_exit}; {link.get('steps', 0)} steps",
             f"radio link per step (wire): {w.get('air_to_ground_per_step', 0):.0f} B air→ground, "
             f"{w.get('ground_to_air_per_step', 0):.0f} B ground→air",
             f"payload per step: {p.get('air_to_ground', 0):.0f} B up, "
             f"{p.get('ground_to_air', 0):.0f} B down"]
    for r in link.get("payload", [])[:8]:
        lines.append(f"  {r['from']:6s}→ {r['key']} {r['kind']}: {r['bytes_per_step']:.0f} B/step")
    if flown.outage:
        lines.append(f"outage: {flown.outage['seconds']:g} s from step {flown.outage['at_step']}")
    return "\n".join(lines)



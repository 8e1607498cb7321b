"""Whole missions across the test bed's hosts: the radio link cut, a ground station on a lossy link.

The stack is split as deployed (docs/deployment.md): the ground host runs its router, the EWS
and System 2 (``python -m services.launch --role ground``), the air host its router joining the
ground's, uavsim, the supervisor and System 1 (``--role air``); the radio link between them is
shaped (50 ms ± 10 ms, 1 Mbit/s) by the test bed (services/testbed). The mission is the test
bed's own (services/testbed/mission.py MISSION: concurrent+risk, seed 26, measured timing, at
twice real time).

1. The radio link goes down for 10 s mid-mission. The mission must go on and end (not abort);
   every step is in the record, in order; the steps of the outage name ``link_lost``; from
   its third step at the latest each plans with System 1 onboard and flies that fresh plan
   (the air role's ``s2_unavailable=system1``) on fires named stale, never with a setpoint
   gap of COM_OF_LOSS_T on the air side; after the outage the ground's services are alive
   again, the fires caught up and System 2 flies again (the Zenoh session across the link
   came back by itself: nothing was restarted).
2. A ground station (MAVProxy) on the gcs host, over its own telemetry link with 10 % loss each
   way, sees the vehicle, takes it over (the hold mode: the mission pauses, the hold is a fault
   of its step) and hands it back (the mission resumes and ends).

``make testbed-check`` runs the first with its run directory under ``runs/``
(``TESTBED_RUN_DIR``) and prints it.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from services import launch
from services.common import mavmodes
from services.testbed.bed import Host, TestBed
from services.testbed.impairment import Impairment
from services.testbed.mission import FlightPlan, Flown, LinkPlan, fly, step_lines
from tests.support.waits import check

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]
MAVPROXY = Path(sys.executable).parent / "mavproxy.py"
OUTAGE_AT, OUTAGE_S = 12, 10.0
COM_OF_LOSS_T_MS = 1000.0


def run_dir(tmp_path: Path) -> Path:
    """``TESTBED_RUN_DIR`` (make testbed-check: under runs/) or the test's own directory."""
    chosen = os.environ.get("TESTBED_RUN_DIR", "")
    return Path(chosen).resolve() if chosen else tmp_path / "run"


def records(flown: Flown) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    lines = step_lines(flown.run_dir)
    summary_path = flown.run_dir / "summary.json"
    check(summary_path.is_file(), "summary.json", [flown.run_dir / "air.out",
                                                    flown.run_dir / "ground.out"])
    return lines, json.loads(summary_path.read_text())


def onboard_steps(lost: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The steps of an outage from the first that System 1 planned (none: [])."""
    s1 = ["s1:ok" in e["plan_status"].split(";") for e in lost]
    return lost[s1.index(True):] if True in s1 else []


def test_a_mission_across_the_hosts_survives_a_10_s_outage_of_the_air_ground_link(
        testbed: TestBed, tmp_path: Path) -> None:
    out = run_dir(tmp_path)
    plan = FlightPlan(link=LinkPlan(outage_at_step=OUTAGE_AT, outage_s=OUTAGE_S))
    flown = fly(testbed, out, plan)
    print(f"\nrun directory: {out}")
    logs = [out / "air.out", out / "ground.out", *sorted((out / "logs").glob("*.log"))]
    lines, summary = records(flown)
    stack = summary["stack"]
    # the mission went on to its end: not aborted, an end line, every step once and in order
    check(flown.air_exit in (0, 3) and stack["aborted"] is None, "the mission to end",
          logs, {"exit": flown.air_exit, "aborted": stack["aborted"]})
    assert any(e.get("kind") == "end" for e in lines)
    steps = [e for e in lines if e.get("kind") == "step"]
    assert [e["t"] for e in steps] == list(range(len(steps))) == list(range(summary["steps"]))
    # the outage happened mid-mission and is in the record
    assert flown.outage and flown.outage["at_step"] >= OUTAGE_AT
    lost = [e for e in steps if any(f.startswith("link_lost") for f in e["faults"])]
    check(len(lost) >= 2, "steps naming link_lost", logs, [e["faults"] for e in steps])
    assert stack["faults"]["link_lost"] == len(lost)
    outages = stack["link"]["outages"]
    assert outages and outages[0]["first_step"] >= OUTAGE_AT
    assert 5.0 <= sum(o["wall_s"] for o in outages) <= 3 * OUTAGE_S, outages
    # System 1 flew onboard through it (or the vehicle braked): never System 2 across a dead
    # link, and the setpoint stream on the air side never paused for COM_OF_LOSS_T
    assert all(e["flown"] for e in steps), [e["t"] for e in steps if not e["flown"]]
    # no plan came across the dead link: after the step it died in, the steps flew onboard
    # (System 1's plan, or the rest of the last System 2 plan adopted before, or braking)
    crossed = [(e["t"], e["plan_status"]) for e in lost[1:]
               if {"s2:ok", "s2:adopted"} & set(e["plan_status"].split(";"))]
    assert not crossed, crossed
    assert all(e["after"] != e["state"] for e in lost), "the vehicle stopped in the outage"
    # System 1 flew onboard (the air role's s2_unavailable=system1): from the outage's third
    # step at the latest (the step the link died in, then the one whose System 2 request
    # timed out), every step of it planned with System 1, asked System 2 nothing new and
    # flew that fresh plan, on the stale fires named as such
    onboard = onboard_steps(lost)
    check(bool(onboard) and onboard[0]["t"] <= lost[0]["t"] + 2,
          "System 1 planning from the outage's third step at the latest", logs,
          [(e["t"], e["system"], e["plan_status"]) for e in lost])
    fresh = [(e["t"], e["system"], e["plan_status"], e["planning_time_s"]) for e in onboard]
    assert all(e["system"] == 1 and "s1:ok" in e["plan_status"].split(";")
               and "s2:launched" not in e["plan_status"].split(";")
               and e["planning_time_s"] > 0 for e in onboard), fresh
    assert all(e["fire_stale"] and "fire_stale" in e["faults"]
               for e in onboard if e["t"] > lost[0]["t"]), [e["faults"] for e in onboard]
    assert stack["stream"]["max_gap_ms"] < COM_OF_LOSS_T_MS, stack["stream"]
    assert not any(f.startswith("vehicle_hold") for e in steps for f in e["faults"])
    # after the outage: the ground's services alive again through the same processes, the
    # fires caught up (replayed by the EWS across the link)
    last_lost = max(e["t"] for e in lost)
    after = [e for e in steps if e["t"] > last_lost]
    check(after and after[-1]["ews_alive"] and "system2" in after[-1]["planners_alive"],
          "the ground's services alive after the outage", logs, after[-1:] if after else None)
    assert any(e.get("kind") == "fires_caught_up" for e in lines)
    assert not after[-1]["fire_stale"]
    # and System 2 planned again: a plan of it adopted and flown after the outage
    assert any(e["system"] == 2 and "s2:adopted" in e["plan_status"].split(";")
               for e in after), [(e["t"], e["system"], e["plan_status"]) for e in after]
    # what crossed the link per step, measured (link.json)
    link = json.loads((out / "link.json").read_text())
    assert link["steps"] == len(steps) and link["payload"]
    assert link["wire_mission"]["bytes_per_step"] > 0


class GroundStation:
    """MAVProxy on a test bed host, its commands on stdin, its output in ``log_path``."""

    def __init__(self, host: Host, master: str, workdir: Path):
        workdir.mkdir(parents=True, exist_ok=True)
        self.log_path = workdir / "mavproxy.log"
        self.fh = self.log_path.open("wb")
        self.proc = subprocess.Popen(
            host.argv([sys.executable, str(MAVPROXY), f"--master={master}", "--no-state",
                       f"--state-basedir={workdir}",
                       "--default-modules=mode,param,cmdlong,arm,link"]),
            cwd=workdir, stdin=subprocess.PIPE, stdout=self.fh, stderr=subprocess.STDOUT,
            start_new_session=True)

    def output(self) -> str:
        return self.log_path.read_text(errors="replace")

    def send(self, line: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write((line + "\n").encode())
        self.proc.stdin.flush()

    def stop(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(3)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self.fh.close()


#: the vehicle's flavour in docker-compose.yml (the air role's uavsim), its modes' names as
#: the record and MAVProxy write them
_FLAVOUR = launch.load_compose()["services"]["uavsim"]["environment"]["UAV_AUTOPILOT"]
MODES = mavmodes.ARDUPILOT_MODES if _FLAVOUR == "ardupilot" else mavmodes.PX4_MODES
FLY, HOLD = MODES.name(MODES.offboard), MODES.name(MODES.hold)
GCS_FLY, GCS_HOLD = ("GUIDED", "LOITER") if _FLAVOUR == "ardupilot" else ("OFFBOARD", "LOITER")


class TakeOver:
    """The ground station's turn, called while the mission flies: once the supervisor flies
    the vehicle, ask for the hold mode (again every 2 s until the vehicle says so: the link
    loses 10 %), hold 3 s, then ask for the offboard mode until the vehicle is back in it."""

    def __init__(self, gcs: GroundStation):
        self.gcs, self.phase, self.mark, self.asked = gcs, "wait", 0, 0.0
        self.held_at: float | None = None

    def seen(self, pattern: str) -> bool:
        return re.search(pattern, self.gcs.output()[self.mark:]) is not None

    def ask(self, command: str) -> None:
        if time.monotonic() - self.asked >= 2.0:
            self.gcs.send(command)
            self.asked = time.monotonic()

    def __call__(self, bed: TestBed, run_dir: Path) -> None:
        steps = [e for e in step_lines(run_dir) if e.get("kind") == "step"]
        if self.phase == "wait" and len(steps) >= 8 and self.seen(rf"Mode {GCS_FLY}"):
            self.phase, self.mark = "take", len(self.gcs.output())
        elif self.phase == "take":
            self.ask(f"mode {GCS_HOLD}")
            if self.seen(rf"Mode {GCS_HOLD}"):
                self.phase, self.held_at = "hold", time.monotonic()
                self.mark, self.asked = len(self.gcs.output()), 0.0
        elif self.phase == "hold" and self.held_at and time.monotonic() - self.held_at > 3.0:
            self.ask(f"mode {GCS_FLY}")
            if self.seen(rf"Mode {GCS_FLY}"):
                self.phase = "done"


@pytest.mark.skipif(not MAVPROXY.exists(), reason="MAVProxy is not installed (the dev extra)")
def test_a_ground_station_over_a_lossy_udp_link_sees_the_vehicle_and_takes_it_over(
        testbed: TestBed, tmp_path: Path) -> None:
    out = tmp_path / "run"
    air, gcs_host = testbed.host("air"), testbed.host("gcs")
    telem = Impairment(delay_ms=20.0, loss=0.10)
    plan = FlightPlan(link=LinkPlan(telem=telem))
    gcs = GroundStation(gcs_host, f"udpout:{air.address('gcs')}:14550", tmp_path / "gcs")
    turn = TakeOver(gcs)
    try:
        flown = fly(testbed, out, plan, during=turn)
    finally:
        gcs.stop()
    logs = [gcs.log_path, out / "air.out", out / "ground.out"]
    text = gcs.output()
    check("Detected vehicle 1:1" in text, "the ground station to see the vehicle", logs)
    check(turn.phase == "done", "the ground station to take the vehicle and hand it back", logs,
          turn.phase)
    lines, summary = records(flown)
    stack = summary["stack"]
    check(stack["aborted"] is None and any(e.get("kind") == "end" for e in lines),
          "the mission to end after the hand-back", logs, stack["aborted"])
    faults = [f for e in lines if e.get("kind") == "step" for f in e["faults"]]
    assert any(f.startswith("vehicle_hold") for f in faults), faults
    modes = [(c["mode"], c["armed"]) for c in stack["vehicle_modes"]]
    assert (HOLD, True) in modes and modes[modes.index((HOLD, True)) + 1] == (FLY, True)
    if not testbed.netem:  # the impairer's counters: the telemetry link lost frames both ways
        dirs = testbed.link("telem").stats()["directions"]
        assert dirs["gcs"]["lost"] > 0 and dirs["air"]["lost"] > 0, dirs

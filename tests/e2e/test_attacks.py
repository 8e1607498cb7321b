"""Faults and attacks on the real processes, loopback only, one test per finding.

A rogue Zenoh process (tests/e2e/rogue.py) plays a byzantine System 2, an
impostor planner or EWS beside the real ones, or a hung planner; a second
supervisor, a killed uavsim, a full tmpfs or a read-only directory, and
unsigned control on the ground-station port do the rest. The supervisor's
step record (steps.jsonl) and summary say what it did.
"""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.params import Timing
from dualpilot.mission.records import STEP_LOG, read_step_log
from services import launch
from services.common import bus, keys, mav, wire
from services.msgs import supervisor_pb2
from tests.support.waits import Logs, check, logs_in, wait_for

from . import rogue
from .conftest import alive, router_ready, run_process

pytestmark = [pytest.mark.slow, pytest.mark.timeout(150)]

EV = supervisor_pb2
SEED = 26
m = mav.mavlink


class Attack:
    """A running stack, its mission events and the rogue processes started beside it."""

    def __init__(self, stack: launch.Stack, session: Any):
        self.stack, self.session = stack, session
        self.live = bus.Liveliness(session, stack.cfg.uav_id)
        self.events: queue.Queue[Any] = queue.Queue()
        self.sub = session.declare_subscriber(
            keys.mission_event(stack.cfg.uav_id),
            lambda s: self.events.put(wire.parse(s.payload.to_bytes(), EV.MissionEvent)))

    @property
    def run_dir(self) -> Path:
        return self.stack.cfg.run_dir

    def rogue(self, *modes: str) -> None:
        """Start one rogue process per mode; return when each says it is ready."""
        env = dict(os.environ, PYTHONPATH=str(launch.REPO), PYTHONUNBUFFERED="1")
        procs = [self.stack.group.start(
            f"rogue-{mode}", [sys.executable, "-m", "tests.e2e.rogue", mode, "--uav",
                              self.stack.cfg.uav_id, "--connect", self.stack.endpoint],
            env, self.stack.logs / f"rogue-{mode}.log") for mode in modes]
        for mode, proc in zip(modes, procs, strict=True):
            def ready(mode: str = mode, proc: launch.Proc = proc) -> bool:
                return "ready" in self.log(f"rogue-{mode}") or proc.popen.poll() is not None

            # the rogue's own stdout: nothing on the bus to await
            wait_for(ready, 30, f"the rogue {mode} to print 'ready'", self.logs())
            check(proc.popen.poll() is None, f"the rogue {mode} to keep running once ready",
                  self.logs(), f"exit code {proc.popen.returncode}")

    def proc(self, name: str) -> launch.Proc:
        return [p for p in self.stack.group.procs if p.name == name][-1]

    def log(self, name: str) -> str:
        path = self.stack.logs / f"{name}.log"
        return path.read_text(errors="replace") if path.is_file() else ""

    def logs(self) -> Logs:
        """Every process's log of this run (the rogues' too)."""
        return logs_in(self.stack.logs)

    def event(self, kinds: tuple[int, ...], timeout_s: float,
              pred: Any = lambda e: True, what: str = "") -> Any:
        """The first mission event of one of ``kinds`` (with ``pred``) from now on."""
        last: list[Any] = []

        def matching() -> Any:
            try:
                ev = self.events.get(timeout=0.2)
            except queue.Empty:
                return None
            last[:] = [ev]
            return ev if ev.kind in kinds and pred(ev) else None

        names = "/".join(EV.MissionEventKind.Name(k) for k in kinds)
        return wait_for(matching, timeout_s, what or f"a mission event {names}", self.logs(),
                        period_s=0, last=lambda: last[0] if last else "no mission event")

    def end(self, timeout_s: float = 100.0) -> Any:
        return self.event((EV.MISSION_EVENT_KIND_ENDED, EV.MISSION_EVENT_KIND_ABORTED), timeout_s,
                          what="the mission's end (ENDED or ABORTED)")

    def ended(self, end: Any) -> None:
        """The mission ended (was not aborted)."""
        check(end.kind == EV.MISSION_EVENT_KIND_ENDED, "the mission to end, not abort",
              self.logs(), end)

    def record(self) -> list[dict[str, Any]]:
        return read_step_log(self.run_dir / STEP_LOG)

    def steps(self) -> list[dict[str, Any]]:
        return [e for e in self.record() if e["kind"] == "step"]


@contextmanager
def attacked(tmp_path: Path, name: str, controller: str = "cc", speed: float = 50.0,
             services: tuple[str, ...] = (), max_steps: int = 25,
             extra_env: dict[str, dict[str, str]] | None = None,
             scenario: str = "") -> Iterator[Attack]:
    settings: tuple[tuple[str, object], ...] = (("max_steps", max_steps),)
    if scenario:
        settings += (("scenario", scenario),)
    cfg = launch.StackConfig(run_dir=tmp_path / name, speed_factor=speed,
                             mission=MissionConfig.named(controller, seed=SEED,
                                                         timing=Timing.MEASURED,
                                                         mission_id=f"m-{name}",
                                                         settings=settings),
                             free_ports=True, uav_id=f"a-{name}", log_format="text",
                             services=services,
                             extra_env=extra_env or {}, deferred=("supervisor",))
    stack = launch.Stack(cfg)
    with stack:
        router_ready(stack.endpoint, logs_in(stack.logs))
        with launch.client_session(stack.endpoint) as session:
            attack = Attack(stack, session)
            if "supervisor" in stack.service_names():
                stack.start_deferred()  # the supervisor flies once the test is listening
            try:
                yield attack
            finally:
                attack.sub.undeclare()


ALL_BUT_S2 = ("ews", "system1", "supervisor", "uavsim")


def summary(run_dir: Path) -> dict[str, Any]:
    doc: dict[str, Any] = json.loads((run_dir / "summary.json").read_text())
    return doc


# -- 1. a byzantine planner: the run-time monitor ----------------------------------------------
def test_byzantine_system2_plans_are_never_flown(tmp_path: Path) -> None:
    with attacked(tmp_path, "byzantine", services=ALL_BUT_S2) as run:
        run.rogue("plan-byzantine")
        end = run.end()
        steps = run.steps()
    run.ended(end)
    asked = [e for e in steps if "s2:" in e["plan_status"]]
    assert asked, "System 2 was never asked"
    assert all("s2:unsafe[monitor:" in e["plan_status"] for e in asked), [
        e["plan_status"] for e in asked]
    assert not [e for e in steps if e["system"] == 2]
    assert all(abs(u) <= 7.5 for e in steps for u in e["control"])
    assert end.failure_cause != "fire_contact"
    assert summary(run.run_dir)["stack"]["monitor_rejected"] >= len(asked)


# -- 2. impostors beside the real services: only the token holder is trusted ------------------
def test_impostor_planner_and_ews_beside_the_real_ones_are_not_trusted(tmp_path: Path) -> None:
    """System 2 with the forecast: plans, fire states and forecasts from services without the
    tokens are refused and counted; every forecast planned on is the real EWS's. On grass-15
    the real EWS takes tens of ms to forecast, so the forgeries arrive first."""
    with attacked(tmp_path, "impostor", controller="s2+risk", speed=20.0, max_steps=40,
                  scenario="grass-15") as run:
        run.rogue("plan-impostor", "ews-impostor")
        end = run.end()
        steps = run.steps()
    run.ended(end)
    assert steps and not [e for e in steps if e.get("info", {}).get("source") == "impostor"]
    assert any(e["system"] == 2 for e in steps)
    assert any(e["fires_active"] > 0 for e in steps), "the rogue EWS's 'no fires' was believed"
    forecasts = [f for e in steps for f in e.get("forecast", [])]
    assert forecasts, "no forecast from the real EWS"
    assert all(f["compute_s"] != rogue.FORGED_COMPUTE_S for f in forecasts), forecasts
    stale = [f for e in steps for f in e.get("faults", []) if f.startswith("forecast_stale")]
    assert all("late:" in f for f in stale), stale  # none refused: the forgeries never arrive
    untrusted = summary(run.run_dir)["stack"]["untrusted"]
    uav = run.stack.cfg.uav_id
    assert untrusted.get(keys.plan(uav, 2), 0) > 0 and untrusted.get(keys.fire_command(uav), 0) > 0


def test_a_peer_without_the_token_cannot_answer_but_a_token_holder_can(tmp_path: Path) -> None:
    """The replier-id check itself (bus.request with trusted=...), on a bare router."""
    with attacked(tmp_path, "bus", services=("ews",)) as run:
        alive(run.live, ["ews"], 60, run.logs())
        run.rogue("ews-impostor")
        from services.msgs import fire_pb2

        cmd = fire_pb2.FireCommand(mission_id="probe")
        cmd.reset.seed, cmd.reset.area_size_m = 1, 1000.0
        wire.Stamper("test", run.stack.cfg.uav_id).stamp(cmd.header)
        holder = run.live.holder("ews")
        assert holder
        payload, enc = bus.request(run.session, keys.fire_command(run.stack.cfg.uav_id), cmd,
                                   10.0, trusted=holder)
        update = wire.parse(payload, fire_pb2.FireUpdate, enc)
        assert update.states and update.states[0].substep_s > 0
        with pytest.raises(TimeoutError, match="token holder|no reply"):
            bus.request(run.session, keys.fire_command(run.stack.cfg.uav_id), cmd, 2.0,
                        trusted="0" * 32)


# -- 3. a hung planner --------------------------------------------------------------------------
def test_hung_system2_costs_k_deadlines_then_is_unavailable(tmp_path: Path) -> None:
    with attacked(tmp_path, "hung", services=ALL_BUT_S2) as run:
        run.rogue("plan-hung")
        end = run.end(120)
        steps = run.steps()
    run.ended(end)
    # the logic: k deadlines missed, then unavailable (how long the mission took in wall
    # time is a figure of the machine, not of this logic)
    timeouts = [e["t"] for e in steps if "s2:timeout" in e["plan_status"]]
    assert 1 <= len(timeouts) <= 2, timeouts
    later = [e for e in steps if e["t"] > max(timeouts) and "s2:" in e["plan_status"]]
    assert later and all("s2:unavailable" in e["plan_status"] for e in later)


# -- 4. a second supervisor, a second offboard peer ----------------------------------------------
def test_second_supervisor_refuses_and_a_second_offboard_peer_is_ignored(tmp_path: Path) -> None:
    with attacked(tmp_path, "twice") as run:
        run.event((EV.MISSION_EVENT_KIND_STEP,), 60, lambda e: e.step >= 3, "step 3")
        second = run_process(run.stack.argv("supervisor"), 60, "the second supervisor",
                             run.logs(), env=run.stack.service_env("supervisor"))
        assert second.returncode == 1, second.stderr[-2000:]
        assert "another supervisor" in second.stderr, second.stderr[-3000:]
        port = int(run.stack.service_env("uavsim")["MAVLINK_URL"].rsplit(":", 1)[1])
        intruder = mav.connect(f"udpout:127.0.0.1:{port}", 1, 192)
        try:
            for _ in range(5):
                intruder.mav.set_position_target_local_ned_send(
                    0, 1, 1, m.MAV_FRAME_LOCAL_NED, 3576, 500, 500, -50, 0, 0, 0, 0, 0, 0, 0, 0)
        finally:
            intruder.close()
        end = run.end()
        record = run.record()
    run.ended(end)
    ts = [e["t"] for e in record if e["kind"] == "step"]
    assert ts == list(range(len(ts)))
    assert sum(e["kind"] == "end" for e in record) == 1
    check("rejected control" in run.log("uavsim"), "uavsim to log the second peer's rejected "
          "control", run.logs())


# -- 5. the vehicle lost for good ---------------------------------------------------------------
def test_killed_uavsim_ends_the_mission_in_bounded_time_with_an_end_line(tmp_path: Path) -> None:
    with attacked(tmp_path, "lost") as run:
        run.event((EV.MISSION_EVENT_KIND_STEP,), 60, lambda e: e.step >= 3, "step 3")
        uav = run.proc("uavsim")
        os.killpg(uav.popen.pid, signal.SIGKILL)
        # bounded: heartbeat loss (3 s) + vehicle_gone_s (5 s), well within the wait's 40 s;
        # how long it took is not asserted (a wall-clock figure)
        end = run.end(40)
        record = run.record()
    check(end.kind == EV.MISSION_EVENT_KIND_ENDED and end.failure_cause == "vehicle_lost",
          "the mission to end as vehicle_lost", run.logs(), end)
    assert record[-1]["kind"] == "end" and record[-1]["failure_cause"] == "vehicle_lost"


# -- 6. storage -----------------------------------------------------------------------------------
@contextmanager
def tmpfs(path: Path, size: str, ro: bool = False) -> Iterator[Path]:
    path.mkdir(parents=True, exist_ok=True)
    opts = f"size={size}" + (",ro" if ro else "")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(path)],
                          capture_output=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode()[:200]}")
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], check=False)


def test_full_disk_never_kills_uavsim_or_the_supervisor(tmp_path: Path) -> None:
    with tmpfs(tmp_path / "full-disk", "400k") as disk:
        (disk / "ballast").write_bytes(b"\0" * 250_000)
        env = {"supervisor": {"RUN_DIR": str(disk / "run")},
               "uavsim": {"TLOG_PATH": str(disk / "vehicle.tlog")}}
        with attacked(tmp_path, "full", extra_env=env, max_steps=40) as run:
            end = run.end()
            seen: list[Any] = []

            def tlog_rejected() -> Any:
                seen[:] = [bus.query_status(run.session, run.stack.cfg.uav_id, "uavsim")]
                return seen[0] if seen[0]["rejected"].get("storage/tlog") else None

            # the vehicle keeps sending telemetry: its tlog fills the disk too
            status = wait_for(tlog_rejected, 30, "uavsim's status to count a rejected "
                              "storage/tlog write", run.logs(), period_s=0.2,
                              last=lambda: seen[0]["rejected"] if seen else "no status")
            running = {p.name: p.popen.poll() is None for p in run.stack.group.procs}
            summary_path = disk / "run" / "summary.json"
            lines = (disk / "run" / STEP_LOG).read_text().splitlines()
            text = summary_path.read_text() if summary_path.exists() else ""
    check(running["uavsim"] and running["supervisor"], "uavsim and the supervisor to keep "
          "running on a full disk", logs_in(tmp_path / "full"), running)
    assert end.kind in (EV.MISSION_EVENT_KIND_ENDED, EV.MISSION_EVENT_KIND_ABORTED)
    if end.kind == EV.MISSION_EVENT_KIND_ABORTED:
        assert "storage" in end.message
    assert status["rejected"].get("storage/tlog", {}).get("write_error", 0) >= 1
    for line in lines[:-1]:  # whole lines only (the last may be the one cut)
        json.loads(line)
    if text:
        json.loads(text)  # never a truncated summary


def test_read_only_run_directory_refused_before_arming(tmp_path: Path) -> None:
    with tmpfs(tmp_path / "ro-disk", "64k", ro=True) as disk:
        env = {"supervisor": {"RUN_DIR": str(disk / "run")},
               "uavsim": {"TLOG_PATH": str(disk / "vehicle.tlog")}}
        with attacked(tmp_path, "ro", extra_env=env) as run:
            gcs_port = int(run.stack.service_env("uavsim")["GCS_URL"].rsplit(":", 1)[1])
            end = run.end(60)
            gcs = mav.connect(f"udpout:127.0.0.1:{gcs_port}", 255, 190)
            try:
                hb = recv(gcs, "HEARTBEAT", 10, "a HEARTBEAT on the ground-station port",
                          run.logs(), hello=True)
            finally:
                gcs.close()
            uav_alive = run.proc("uavsim").popen.poll() is None
            logs = run.logs()
    check(end.kind == EV.MISSION_EVENT_KIND_ABORTED and "not" in end.message,
          "the mission to abort, the run directory not writable", logs, end)
    assert not hb.base_mode & m.MAV_MODE_FLAG_SAFETY_ARMED, hb
    check(uav_alive, "uavsim to keep running", logs)


# -- 7. the ground-station link -------------------------------------------------------------------
def test_unsigned_control_on_the_gcs_port_is_refused(tmp_path: Path) -> None:
    env = {s: {"MAVLINK_SIGNING_PASSPHRASE": "attack-test"} for s in ("supervisor", "uavsim")}
    with attacked(tmp_path, "gcs", extra_env=env) as run:
        run.event((EV.MISSION_EVENT_KIND_STEP,), 60, lambda e: e.step >= 2, "step 2")
        gcs_port = int(run.stack.service_env("uavsim")["GCS_URL"].rsplit(":", 1)[1])
        gcs = mav.connect(f"udpout:127.0.0.1:{gcs_port}", 255, 190)
        try:
            gcs.mav.heartbeat_send(6, 8, 0, 0, 0)
            pos = recv(gcs, "LOCAL_POSITION_NED", 5, "a LOCAL_POSITION_NED on the "
                       "ground-station port", run.logs())
            for lead_ms in (1000, 590_000):
                for _ in range(5):
                    gcs.mav.set_position_target_local_ned_send(
                        pos.time_boot_ms + lead_ms, 1, 1, m.MAV_FRAME_LOCAL_NED, 3576,
                        pos.x + 60, pos.y + 60, -50, 0, 0, 0, 0, 0, 0, 0, 0)
            gcs.mav.command_long_send(1, 1, m.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                      0, 21196, 0, 0, 0, 0, 0)
        finally:
            gcs.close()
        end = run.end()
        steps = run.steps()
    run.ended(end)
    for e in steps:  # no 60 m jumps: every step within the speed limit of Eq. (1)
        if e["flown"]:
            assert all(abs(e["after"][k] - e["state"][k]) <= 15.0 + 1e-6 for k in (0, 1)), e
    check("unsigned" in run.log("uavsim"), "uavsim to log the unsigned control it refused",
          run.logs())


def test_a_setpoint_far_ahead_is_refused_and_never_moves_the_clock(tmp_path: Path) -> None:
    off, gcs_port = launch.free_port("udp"), launch.free_port("udp")
    env = dict(os.environ, PYTHONPATH=str(launch.REPO), PYTHONUNBUFFERED="1", LOG_FORMAT="text")
    group = launch.ProcessGroup()
    group.start("uavsim", [sys.executable, "-m", "services.uavsim", "--mavlink-url",
                           f"udpin:127.0.0.1:{off}", "--gcs-url",
                           f"udpin:127.0.0.1:{gcs_port}", "--zenoh", "off",
                           "--clock", "lockstep"], env,
                tmp_path / "uavsim.log")
    conn = mav.connect(f"udpout:127.0.0.1:{off}", 1, 191)
    logs = [tmp_path / "uavsim.log"]
    try:
        recv(conn, "HEARTBEAT", 10, "the vehicle's HEARTBEAT on the offboard port", logs,
             hello=True, mav_type=18)

        def position() -> Any:
            return recv(conn, "LOCAL_POSITION_NED", 5, "a LOCAL_POSITION_NED", logs)

        t = position().time_boot_ms
        for _ in range(20):  # a live stream, then GUIDED and arm (the offboard sequence)
            conn.mav.set_position_target_local_ned_send(t, 1, 1, m.MAV_FRAME_LOCAL_NED, 3576,
                                                        50, 50, -50, 0, 0, 0, 0, 0, 0, 0, 0)
            time.sleep(0.02)
        conn.mav.command_long_send(1, 1, m.MAV_CMD_DO_SET_MODE, 0, 1, 4, 0, 0, 0, 0, 0)
        conn.mav.command_long_send(1, 1, m.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
        recv(conn, "COMMAND_ACK", 5, "a COMMAND_ACK", logs)
        conn.mav.set_position_target_local_ned_send(t + 590_000, 1, 1, m.MAV_FRAME_LOCAL_NED,
                                                    3576, 60, 60, -50, 0, 0, 0, 0, 0, 0, 0, 0)
        conn.mav.set_position_target_local_ned_send(t + 1000, 1, 1, m.MAV_FRAME_LOCAL_NED,
                                                    3576, 51, 51, -50, 0, 0, 0, 0, 0, 0, 0, 0)
        stamps: list[int] = []

        def next_step() -> bool:
            stamps.append(position().time_boot_ms)
            return stamps[-1] == t + 1000

        # the next step is flown (and, below, the 590 s stamp never moved the clock)
        wait_for(next_step, 5, f"a LOCAL_POSITION_NED stamped {t + 1000} (the next step)",
                 logs, period_s=0, last=lambda: f"stamps {stamps}")
        assert max(stamps) <= t + 1000, stamps
    finally:
        conn.close()
        group.stop_all()
    check("more than one step" in (tmp_path / "uavsim.log").read_text(),
          "uavsim to log the refused setpoint due more than one step ahead", logs)


def recv(conn: Any, kind: str, timeout_s: float, what: str, logs: Logs, hello: bool = False,
         mav_type: int = 6) -> Any:
    """The next MAVLink ``kind`` on ``conn`` (with ``hello``: a HEARTBEAT of ``mav_type`` sent
    before each try, as a udpout peer speaks first)."""
    def got() -> Any:
        if hello:
            conn.mav.heartbeat_send(mav_type, 8, 0, 0, 0)
        return conn.recv_match(type=kind, blocking=True, timeout=0.2)

    return wait_for(got, timeout_s, what, logs, period_s=0)

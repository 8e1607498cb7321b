"""The supervisor's mission session: the one mission step over the stack's ports.

What is about being a process lives here; the step itself is
:class:`dualpilot.mission.step.Mission`, the same object the in-process loop
runs, with the ports of services/supervisor/ports.py. The session

* starts a mission: takes the vehicle (services/supervisor/link.py: setpoints,
  offboard mode, arm), downloads its mission as System 1's operator
  waypoints, freezes the spec with the vehicle's position as the start,
  resets the EWS and prepares the planners, or **resumes** one from the
  ``steps.jsonl`` a stopped supervisor left (the recorded decisions replayed,
  the EWS reset and replayed, the vehicle taken from where it is);
* between steps: pauses while the vehicle is not flying offboard (lost for
  3 s, or put in hold), takes a newly uploaded mission as the next revision
  of the operator waypoints, holds while no planner of the controller is
  alive (lockstep: nothing advances while paused);
* observes each step: the clock and Decision (``supervisor/decision``), the
  vehicle state, MissionEvents, ``steps.jsonl`` (dualpilot.mission.records.StepLog),
  ``latency.csv`` and the operator columns, each step's plans (``supervisor/plans``, for
  the live view); at the end ``summary.json``, ``steps.csv``, ``trace.json`` and
  ``mission.mcap``.
"""

from __future__ import annotations

import fcntl
import json
import logging
import os
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import cast

import numpy as np
import zenoh

from dualpilot.mission import monitor
from dualpilot.mission.local import SUPERVISORS
from dualpilot.mission.params import Controller, MissionParams, Timing
from dualpilot.mission.records import (
    STEP_LOG,
    StepLog,
    atomic_write,
    read_step_log,
    record_to_json,
    result_from_log,
    write_all,
)
from dualpilot.mission.result import MissionResult, StepRecord
from dualpilot.mission.step import Mission, systems_of
from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireParams
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.decision import Decision, SupervisorParams
from services.common import bus, keys, protobuf_codec, rejections, wire
from services.common.clock import SimClock
from services.common.log import fields
from services.msgs import common_pb2, supervisor_pb2, vehicle_pb2

from . import faults as fault_names
from .faults import FaultLog
from .link import OffboardError, VehicleLink
from .ports import Aborted, Bus, StackFires, StackParams, StackPlanners, StackVehicle
from .runlog import Latency, OperatorRecord, write_operator_columns

log = logging.getLogger(__name__)

__all__ = ["Aborted", "StackParams", "StackSession", "VehicleGone"]

#: the run directory's lock file: one supervisor at a time writes a run directory
LOCK_FILE = ".supervisor.lock"


class VehicleGone(Aborted):
    """The vehicle is lost for good: its token is gone and its heartbeat too (the mission ends)."""


class StorageFault(Aborted):
    """The step record could not be written (a full or read-only disk): the mission ends."""


class StackSession:
    """One mission flown through the services; ``run()`` flies it."""

    def __init__(
        self,
        session: zenoh.Session,
        link: VehicleLink,
        uav: str,
        mission_id: str,
        controller: Controller,
        spec: MissionSpec,
        timing: Timing,
        clock: SimClock,
        stop: threading.Event,
        waypoints: Array | None = None,
        params: MissionParams = MissionParams(),
        fire_params: FireParams = FireParams(),
        supervisor_params: SupervisorParams = SupervisorParams(),
        supervisor: str = "paper",
        stack: StackParams = StackParams(),
        live: bus.Liveliness | None = None,
        record_dir: Path | None = None,
    ):
        self.link = link
        self.controller = controller
        self.spec = spec
        self.timing = timing
        self.clock = clock
        self.stop = stop
        self.params = params
        self.fire_params = fire_params
        self.supervisor_params = supervisor_params
        self.supervisor_name = supervisor
        self.stack = stack
        self.live = live
        self.record_dir = record_dir
        self.waypoints = waypoints
        self.mission_rev = 0  # the vehicle's mission download last seen
        self.b = Bus(session, uav, mission_id, wire.Stamper("supervisor", uav), clock, stop,
                     stack, live, dt_s=spec.dynamics.dt_s)
        self.pubs = {
            name: session.declare_publisher(key) for name, key in (
                ("decision", keys.decision(uav)), ("state", keys.vehicle_state(uav)),
                ("event", keys.mission_event(uav)), ("clock", keys.clock(uav)),
                ("plans", keys.step_plans(uav)))
        }
        self.step_log: StepLog | None = None
        self.mission: Mission | None = None
        self.fires: StackFires | None = None
        self.planners: StackPlanners | None = None
        self.vehicle = StackVehicle(self.b, link, spec.dynamics.dt_s, self._ensure_offboard)
        self.operator: list[OperatorRecord] = []
        self.latency = Latency()
        self.resumed_at: int | None = None
        self.holding = ""
        self._tick = 0.0
        self._step_why: dict[str, object] = {}
        self._decision: tuple[Decision, int] | None = None
        self.lock_fh: object | None = None  # the run directory's lock (held while flying)
        self.monitor_rejected = 0  # plans the run-time monitor refused (dualpilot/mission/monitor)
        self.faults = FaultLog()  # wall-clock events that touched the mission (faults.py)
        self._holds_seen = 0
        self.storage_errors = 0
        self.storage_fault = ""

    @property
    def result(self) -> MissionResult | None:
        return None if self.mission is None else self.mission.result

    @property
    def state(self) -> Array:
        return self.mission.state if self.mission is not None else np.zeros(4)

    def _now(self) -> float:
        return self.clock.now_s

    # -- records and events -----------------------------------------------------------------------
    def _record(self, kind: str, **fields_: object) -> None:
        """Append a line to the step record (steps.jsonl), if there is one."""
        if self.step_log is not None and not self.step_log.fh.closed:
            try:
                self.step_log.write(kind, wall_time_s=round(time.time(), 3), **fields_)
            except (OSError, ValueError) as err:  # a full disk must not crash the supervisor
                self.storage_errors += 1
                if not self.storage_fault:
                    self.storage_fault = f"step record not written: {err}"
                    rejections.rejected("record", rejections.invalid(self.storage_fault), log,
                                        key="storage/steps.jsonl", reason="write_error")

    def _steps(self) -> int:
        return self.result.steps if self.result is not None else 0

    def _event(self, kind: supervisor_pb2.MissionEventKind, **kw: object) -> None:
        if kind != supervisor_pb2.MISSION_EVENT_KIND_STEP:
            self._record("event", event=supervisor_pb2.MissionEventKind.Name(kind).rsplit(
                "_", 1)[-1].lower(), **{k: v for k, v in kw.items() if k != "position"})
        m = supervisor_pb2.MissionEvent(kind=kind, mission_id=self.b.mission_id,
                                        controller=self.controller.value, seed=self.spec.seed)
        self.b.stamper.stamp(m.header, self._now())
        pos = kw.pop("position", None)
        for k, v in kw.items():
            setattr(m, k, v)
        if pos is not None:
            m.position.east_m, m.position.north_m = (float(v) for v in np.asarray(pos)[:2])
        bus.put(self.pubs["event"], "", m)

    def _publish_state(self, t: int) -> None:
        m = vehicle_pb2.VehicleState()
        self.b.stamper.stamp(m.header, self._now())
        protobuf_codec.state_to_msg(self.state, t, m, self.stack.altitude_m)
        bus.put(self.pubs["state"], "", m)

    # -- the vehicle ------------------------------------------------------------------------------
    def _take_vehicle(self) -> None:
        try:
            self.link.start_offboard(self.stop, self.stack.offboard_timeout_s)
        except OffboardError as err:
            raise Aborted(f"vehicle: {err}") from err
        if self.stop.is_set():
            raise Aborted("stopped")
        log.info("vehicle under offboard control", extra=fields(status=self.link.status()))

    def _ensure_offboard(self) -> None:
        """Pause while the vehicle is not flying offboard; take it again when it comes back."""
        if self.link.offboard():
            return
        t0 = time.monotonic()
        lost = not self.link.alive()
        if lost:
            self.faults.note(fault_names.VEHICLE_LOST)
        reason = ("vehicle lost: no heartbeat for 3 s" if lost
                  else f"vehicle not flying offboard ({self.link.status()})")
        log.warning("mission paused", extra=fields(reason=reason))
        self._event(supervisor_pb2.MISSION_EVENT_KIND_PAUSED, message=reason, step=self._steps())
        gone_since: float | None = None
        while not self.link.offboard():
            if self.stop.is_set():
                raise Aborted("stopped")
            gone = not self.link.alive() and not self.b.alive("uavsim")
            if not gone:
                gone_since = None
            elif gone_since is None:
                gone_since = time.monotonic()
            elif time.monotonic() - gone_since > self.stack.vehicle_gone_s:
                raise VehicleGone(f"vehicle lost: no heartbeat and its liveliness token gone "
                                  f"for {self.stack.vehicle_gone_s:g} s")
            if time.monotonic() - t0 > self.stack.pause_limit_s:
                raise Aborted(f"paused for more than {self.stack.pause_limit_s:g} s: {reason}")
            if not self.link.alive():
                if not lost:
                    self.faults.note(fault_names.VEHICLE_LOST)
                lost = True
            elif lost:  # back after a loss: take it again (the steps it still needs)
                lost = False
                try:
                    self.link.start_offboard(self.stop, self.stack.offboard_timeout_s)
                except OffboardError as err:
                    log.warning("could not take the vehicle back", extra=fields(error=str(err)))
            self.stop.wait(0.05)
        paused = time.monotonic() - t0
        log.info("mission resumed", extra=fields(paused_s=round(paused, 3)))
        self._event(supervisor_pb2.MISSION_EVENT_KIND_RESUMED,
                    message=f"paused {paused:.1f} s", step=self._steps())

    def _update_waypoints(self) -> None:
        """A mission newly downloaded from the vehicle becomes the operator waypoints."""
        rev, wps, mission_id = self.link.operator_waypoints()
        if rev == 0 or rev == self.mission_rev:
            return
        self.mission_rev = rev
        if not mission_id:
            return  # never uploaded: the --waypoints flag's stay
        area = self.spec.area_size_m
        if wps is not None and not all(0.0 <= v <= area for v in wps.ravel()):
            log.error("operator waypoints outside the area ignored", extra=fields(
                mission_id=mission_id, n=len(wps)))
            return
        same = (wps is None and self.waypoints is None) or (
            wps is not None and self.waypoints is not None and wps.shape == self.waypoints.shape
            and np.allclose(wps, self.waypoints))
        if same:
            return
        self.waypoints = wps
        n = 0 if wps is None else len(wps)
        log.info("operator waypoints from the vehicle", extra=fields(
            mission_id=mission_id, n=n, waypoints=";".join(
                f"{e:.1f},{north:.1f}" for e, north in (wps if wps is not None else []))))
        if self.planners is not None:  # System 1 applies them at its next plan
            self.planners.set_waypoints(wps, publish=True)
        self._event(supervisor_pb2.MISSION_EVENT_KIND_WAYPOINTS,
                    message=f"{n} operator waypoints (mission {mission_id:g})",
                    step=self._steps())

    def _hold_without_planners(self) -> None:
        """No planner of this controller alive and the vehicle at rest: pause (the vehicle holds,
        the lockstep clock and the fires wait) until one is back."""
        systems = systems_of(self.controller)
        names = [f"system{k}" for k in systems]
        if self.live is None or any(self.b.alive(n) for n in names):
            return
        if np.linalg.norm(self.state[self.spec.dynamics.dim:]) > 0.05:
            return  # still moving: this step brakes (no plan to fly)
        reason = f"holding: no planner alive ({', '.join(names)}: liveliness token gone)"
        self.holding = reason
        t0 = time.monotonic()
        log.warning("mission paused", extra=fields(reason=reason))
        self._event(supervisor_pb2.MISSION_EVENT_KIND_PAUSED, message=reason, step=self._steps())
        while not any(self.b.alive(n) for n in names):
            if self.stop.is_set():
                raise Aborted("stopped")
            if time.monotonic() - t0 > self.stack.pause_limit_s:
                raise Aborted(f"paused for more than {self.stack.pause_limit_s:g} s: {reason}")
            self.live.wait_any(names, 0.25, self.stop)
        back = [k for k in systems if self.b.alive(f"system{k}")]
        assert self.planners is not None
        try:  # a planner that came back has a fresh service: build this mission's planner
            self.planners.prepare(back)
            if self.planners.waypoints.revision:
                self.planners.publish_waypoints()
        except Aborted as err:
            log.warning("planner back but not ready", extra=fields(error=str(err)))
        self.holding = ""
        paused = time.monotonic() - t0
        names_back = ", ".join(f"system{k}" for k in back)
        log.info("mission resumed", extra=fields(paused_s=round(paused, 3), back=names_back))
        self._event(supervisor_pb2.MISSION_EVENT_KIND_RESUMED,
                    message=f"{names_back} back after {paused:.1f} s", step=self._steps())

    # -- start ------------------------------------------------------------------------------------
    def claim_run_dir(self) -> None:
        """Before the vehicle is taken: lock the run directory and check it is writable.

        The lock (``fcntl.flock``, exclusive) is held until the process ends, so
        a second supervisor never writes (or resumes) a record its owner is
        still writing; the probe file is written, fsynced and removed. Raises
        Aborted (nothing armed) otherwise.
        """
        if self.record_dir is None:
            return
        try:
            self.record_dir.mkdir(parents=True, exist_ok=True)
            fh = (self.record_dir / LOCK_FILE).open("a+")
        except OSError as err:
            raise Aborted(f"run directory {self.record_dir} not usable: {err}") from err
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            fh.close()
            raise Aborted(f"run directory {self.record_dir} is locked by another supervisor"
                          ) from err
        self.lock_fh = fh
        probe = self.record_dir / f".probe.{os.getpid()}"
        try:
            with probe.open("w") as pf:
                pf.write("x" * 4096)
                pf.flush()
                os.fsync(pf.fileno())
            probe.unlink()
        except OSError as err:
            probe.unlink(missing_ok=True)
            raise Aborted(f"run directory {self.record_dir} not writable: {err}") from err

    def start(self) -> None:
        """Take the vehicle, then start the mission from its state or resume its record."""
        self.claim_run_dir()
        self._take_vehicle()
        if not self.link.wait_mission(self.stack.mission_wait_s, self.stop):
            log.warning("the vehicle's mission was not downloaded before the start")
        self._update_waypoints()
        got = self.link.wait_state(0, self.stack.vehicle_timeout_s, self.stop)
        if got is None:
            raise Aborted("no LOCAL_POSITION_NED from the vehicle")
        prior = self._prior_record()
        vehicle_ms, x0 = got
        if prior is None:  # at rest at boot: the in-process mission's hover_state(start)
            self.spec = replace(self.spec, start=(float(x0[0]), float(x0[1])))
        else:
            head = next(e for e in prior if e.get("kind") == "mission")
            start = cast(list[float], head["start"])
            self.spec = replace(self.spec, start=(float(start[0]), float(start[1])))
        self.fires = StackFires(self.b, self.spec, self.fire_params, self._caught_up)
        self.planners = StackPlanners(self.b, self.spec, systems_of(self.controller),
                                      {1: SUPERVISORS[self.supervisor_name]})
        if self.waypoints is not None:
            self.planners.set_waypoints(self.waypoints, publish=False)
        if prior is not None:
            self._resume(prior, vehicle_ms, x0)
            return
        self.vehicle.base_ms = vehicle_ms
        self.fires.reset()
        self.fire_params = self.fires.params
        self.mission = self._mission(x0)
        self._prepare()
        self._open_record()
        self._publish_state(0)
        self._event(supervisor_pb2.MISSION_EVENT_KIND_STARTED, position=self.state,
                    message=f"timing={self.timing.value} speed_factor={self.clock.speed_factor}")
        log.info("mission started", extra=fields(
            mission=self.b.mission_id, controller=self.controller.value, seed=self.spec.seed,
            timing=self.timing.value, start_east_m=float(x0[0]), start_north_m=float(x0[1])))

    def _mission(self, state: Array) -> Mission:
        assert self.fires is not None and self.planners is not None
        try:
            return Mission(self.controller, self.spec, self.fires, self.planners, self.vehicle,
                           state, timing=self.timing, params=self.params,
                           fire_params=self.fire_params,
                           supervisor_params=self.supervisor_params, observer=self,
                           supervisor=self.supervisor_name)
        except ValueError as err:
            raise Aborted(str(err)) from err

    def _prepare(self) -> None:
        assert self.planners is not None
        if self.planners.waypoints.revision:
            self.planners.publish_waypoints()
        self.planners.prepare(systems_of(self.controller))
        bus.settle_heap()  # everything the mission needs is imported and built

    def _open_record(self) -> None:
        """Start ``steps.jsonl`` in the run directory: the mission line first."""
        if self.record_dir is None:
            return
        path = self.record_dir / STEP_LOG
        fresh = self.resumed_at is None
        if fresh and path.exists():
            path.replace(path.with_suffix(f".{int(time.time())}.jsonl"))  # another mission's
        self.step_log = StepLog(path, flush_every_s=self.stack.record_flush_s)
        if fresh:
            s = self.spec
            self._record("mission", mission_id=self.b.mission_id,
                         controller=self.controller.value, seed=s.seed, timing=self.timing.value,
                         start=list(s.start),
                         goal=[s.goal.center_x, s.goal.center_y, s.goal.width, s.goal.height],
                         area_size_m=s.area_size_m, d_safe_m=s.d_safe_m,
                         clearance_m=s.clearance_m, substep_s=self.fire_params.substep_s,
                         dt_s=s.dynamics.dt_s, speed_factor=self.clock.speed_factor,
                         ignition_clearance_m=self.params.ignition_clearance_m)

    def _prior_record(self) -> list[dict[str, object]] | None:
        """This mission's record left by a supervisor that stopped before its end, if any."""
        if self.record_dir is None or not (self.record_dir / STEP_LOG).is_file():
            return None
        try:
            entries = read_step_log(self.record_dir / STEP_LOG)
        except (OSError, UnicodeDecodeError) as err:
            log.warning("unreadable step record: a new mission", extra=fields(error=str(err)))
            return None
        head = next((e for e in entries if e.get("kind") == "mission"), None)
        if head is None or head.get("mission_id") != self.b.mission_id or any(
                e.get("kind") == "end" for e in entries):
            return None
        return entries

    def _resume(self, entries: list[dict[str, object]], vehicle_ms: int, x: Array) -> None:
        """Pick the mission up where its record ends, from the vehicle's state now."""
        assert self.fires is not None
        result = result_from_log(entries, self.spec.dynamics.dt_s)  # type: ignore[arg-type]
        result.spec = self.spec
        head = next(e for e in entries if e.get("kind") == "mission")
        steps = [e for e in entries if e.get("kind") == "step"]
        clear = self.params.ignition_clearance_m
        self.fires.history = [
            (rec.t, rec.fire_substeps, None if clear is None else (rec.state[:2].copy(), clear))
            for rec in result.records]
        sim_s = float(steps[-1].get("sim_time_s", 0.0)) if steps else 0.0  # type: ignore[arg-type]
        self.clock.now_s = sim_s
        self.vehicle.base_ms = vehicle_ms - round(sim_s * 1000)
        self.fires.params = replace(self.fires.params, substep_s=float(
            head.get("substep_s", self.fire_params.substep_s)))  # type: ignore[arg-type]
        self.fire_params = self.fires.params
        self.resumed_at = result.steps
        self.fires.replay()
        self.mission = self._mission(x)
        self.mission.resume(result)
        self._prepare()
        self._open_record()
        self._publish_state(result.steps)
        msg = (f"supervisor restarted: mission picked up at step {result.steps} from the "
               f"vehicle's state ({x[0]:.1f}, {x[1]:.1f})")
        log.info("mission resumed from its record", extra=fields(
            mission=self.b.mission_id, step=result.steps,
            fire_substeps=sum(n for _, n, _ in self.fires.history)))
        self._event(supervisor_pb2.MISSION_EVENT_KIND_RESUMED, message=msg,
                    step=result.steps, position=self.state)

    def _caught_up(self, owed: int, fires_active: int) -> None:
        self._record("fires_caught_up", owed_substeps=owed, fires_active=fires_active)

    # -- the step's observer ----------------------------------------------------------------------
    def decided(self, t: int, decision: Decision, commanded: int) -> None:
        assert self.fires is not None
        self._decision = (decision, commanded)
        alive = [k for k in (1, 2) if self.b.alive(f"system{k}")]
        self._step_why = {
            "fire_age_s": self.fires.age_s(), "fire_stale": self.fires.stale(),
            "fire_margin_m": round(self.fires.margin_m(), 3),
            "planners_alive": [f"system{k}" for k in alive], "ews_alive": self.b.alive("ews"),
            "commanded_system": commanded}

    def commanded(self, t: int, flown: int, info: dict[str, object]) -> None:
        """The setpoint has left: publish the step's start (off the control path)."""
        assert self.planners is not None and self._decision is not None
        p = self.planners
        self.latency.add(t, self.vehicle.sent - self._tick, p.compute, p.requests,
                         p.request_wall, p.service_time)
        rejected = p.last_info.get(1, {}).get("operator_rejected")
        op = OperatorRecord(t, 0 if self.waypoints is None else len(self.waypoints),
                            str(info.get("source", "")) if flown == 1 else "",
                            bool(rejected), str(rejected or ""))
        self.operator.append(op)
        decision, wanted = self._decision
        clock_msg = common_pb2.Clock()
        self.b.clock_msg(clock_msg)
        self.b.stamper.stamp(clock_msg.header, self._now())
        bus.put(self.pubs["clock"], "", clock_msg)
        msg = protobuf_codec.decision_to_msg(decision, wanted, self.b.stamper, self._now())
        msg.plan_source, msg.operator_rejected = op.source, op.rejected
        msg.operator_waypoints, msg.operator_note = op.waypoints, op.note[:500]
        why = self._step_why
        msg.fire_stale = bool(why["fire_stale"])
        msg.fire_age_s = float(why["fire_age_s"])  # type: ignore[arg-type]
        msg.fire_margin_m = float(why["fire_margin_m"])  # type: ignore[arg-type]
        bus.put(self.pubs["decision"], "", msg)

    def _hold_reason(self) -> str:
        alive = any(self.b.alive(f"system{k}") for k in systems_of(self.controller))
        return "no OK plan" if alive else "no planner alive"

    def _step_faults(self) -> list[str]:
        """The named faults since the last step record (services/supervisor/faults.py)."""
        link = self.link
        for reason in link.hold_reasons[self._holds_seen:link.holds]:
            self.faults.note(fault_names.VEHICLE_HOLD, reason)
        self._holds_seen = link.holds
        misses = self.planners.deadline_misses if self.planners is not None else 0
        self.faults.counters(vehicle_moved=link.moved_without_step, plan_deadline=misses)
        if self._step_why.get("fire_stale"):
            self.faults.note(fault_names.FIRE_STALE)
        found = self.faults.take()
        if found:
            log.warning("step touched by a fault", extra=fields(faults="; ".join(found)))
        return found

    def recorded(self, record: StepRecord, flown: bool) -> None:
        # the live view (services/viewer)
        bus.put(self.pubs["plans"], "", protobuf_codec.step_plans_msg(
            record, self.b.mission_id, self.spec, self.b.stamper, self._now()))
        rejected = record.plan_status.count(f"[{monitor.TAG}:")
        if rejected:
            self.monitor_rejected += rejected
            log.warning("plan refused by the run-time monitor", extra=fields(
                step=record.t, plan_status=record.plan_status, total=self.monitor_rejected))
        why = dict(self._step_why)
        why["faults"] = self._step_faults()
        if record.system == 0:
            why["hold_reason"] = self._hold_reason()
        if not flown:
            self._record("step", **record_to_json(record), flown=False,
                         sim_time_s=self.clock.now_s, **why)
            return
        self._publish_state(record.t + 1)
        self._record("step", **record_to_json(record), flown=True, sim_time_s=self.clock.now_s,
                     after=[float(v) for v in self.state], **why)
        self.clock.sleep_until_now(self.stop)  # the flight lasts ΔT of simulated time

    def ended(self, record: StepRecord, success: bool, cause: str) -> None:
        assert self.result is not None
        self._record("end", success=success, failure_cause=cause, steps=self.result.steps,
                     final_state=[float(v) for v in self.state])
        self._step_event(record)
        log.info("mission ended", extra=fields(success=success, cause=cause,
                                               steps=self.result.steps))

    def _step_event(self, record: StepRecord, note: str = "") -> None:
        assert self.result is not None and self.fires is not None
        self._event(supervisor_pb2.MISSION_EVENT_KIND_STEP, step=record.t,
                    flown_system=record.system, position=self.state,
                    fires_active=len(self.fires.current.regions), plan_status=record.plan_status,
                    mission_time_s=self.result.mission_time_s, message=note)

    # -- the loop ---------------------------------------------------------------------------------
    def step(self) -> StepRecord | None:
        """Between-step duties, then the mission's one step."""
        assert self.mission is not None and self.planners is not None
        if self.mission.done:
            return None
        self.check_storage()
        self._ensure_offboard()
        self._update_waypoints()
        self._hold_without_planners()
        self._tick = time.perf_counter()
        self.clock.start_step()
        self.planners.begin_step()
        record = self.mission.step()
        if record is not None and not self.mission.done:
            why = self._step_why
            note = (f"fire data stale: {why['fire_age_s']:g} s old, hulls grown by "
                    f"{why['fire_margin_m']:.1f} m" if why.get("fire_stale") else "")
            if record.system == 0:
                note = "; ".join(filter(None, [note, f"braking: {self._hold_reason()}"]))
            self._step_event(record, note)
        return record

    def run(self) -> MissionResult:
        self.start()
        while self.step() is not None:
            pass
        assert self.result is not None
        return self.result

    def end_lost(self, cause: str, reason: str) -> None:
        """The mission ends without a last step (the vehicle lost for good): the ``end`` line."""
        if self.result is None:
            return
        self.result.success, self.result.failure_cause = False, cause
        self._record("end", success=False, failure_cause=cause, steps=self.result.steps,
                     final_state=[float(v) for v in self.state], reason=reason)
        log.error("mission ended", extra=fields(cause=cause, reason=reason,
                                                steps=self.result.steps))

    def check_storage(self) -> None:
        """Raise StorageFault after a record write error (policy: the mission ends, the
        vehicle holds: the supervisor stops commanding new targets)."""
        if self.storage_fault:
            raise StorageFault(f"storage fault: {self.storage_fault}")

    def close_record(self) -> None:
        if self.planners is not None:
            self.planners.close()
        if self.step_log is not None:
            self.step_log.close()
            if self.step_log.failed is not None and not self.storage_fault:
                self.storage_fault = f"step record not written: {self.step_log.failed}"

    def announce_end(self, run_dir: str, aborted: str = "") -> None:
        r = self.result
        if aborted or r is None:
            self._event(supervisor_pb2.MISSION_EVENT_KIND_ABORTED, message=aborted[:1000],
                        success=False, failure_cause="aborted")
            return
        self._event(supervisor_pb2.MISSION_EVENT_KIND_ENDED, step=r.steps, success=r.success,
                    failure_cause=r.failure_cause, mission_time_s=r.mission_time_s,
                    position=self.state, message=run_dir)

    def write(self, out: Path, extra: dict[str, object]) -> list[Path]:
        """summary.json, steps.csv, trace.json (dualpilot.mission.records) and latency.csv."""
        assert self.result is not None
        paths = write_all(self.result, out, uav=self.b.uav)
        write_operator_columns(self.operator, out)
        summary = json.loads((out / "summary.json").read_text())
        summary["stack"] = {
            "mission_id": self.b.mission_id, "transport": "zenoh + mavlink",
            "speed_factor": self.clock.speed_factor or "unpaced",
            "setpoint_overhead": self.latency.overhead_ms(),
            "setpoints_sent": self.link.sent,
            "rejected_messages": dict(rejections.REJECTED.by_label),
            "monitor_rejected": self.monitor_rejected, "untrusted": _untrusted_counts(),
            "storage_errors": self.storage_errors, "faults": dict(self.faults.totals),
            "planner_failovers": self.planners.failovers if self.planners else 0,
            "stream": self.link.stream_stats(),
            **extra,
        }
        atomic_write(out / "summary.json", json.dumps(summary, indent=2, default=str) + "\n")
        paths.append(self.latency.write(out))
        return paths


def _untrusted_counts() -> dict[str, int]:
    """Replies and liveliness claims refused as not from the token holder, per key."""
    return {key: reasons[bus.UNTRUSTED] for key, reasons in rejections.REJECTED.snapshot().items()
            if bus.UNTRUSTED in reasons}

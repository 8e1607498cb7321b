"""The stack's observer of the mission step: records, publications, latency and named faults.

The step (dualpilot.mission.step.Mission) calls it as it goes
(:class:`dualpilot.mission.ports.StepObserver`): when the decision is made,
when the setpoint has left, when the step is recorded and when the mission
ends. It never steers: it writes the run record (services/supervisor/record.py),
publishes (services/supervisor/publish.py), measures each step's latency and
names the faults that touched it (services/supervisor/faults.py).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any, Protocol

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.result import Ending, MissionResult, StepRecord
from dualpilot.model.dynamics import Array
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import Decision
from services.common.convert.supervisor import DecisionNotes, EventKind, MissionEvent
from services.common.log import fields

from . import faults as fault_names
from .airlink import LinkWatch
from .faults import FaultLog
from .link import VehicleLink
from .ports import StackBus, StackFires, StackPlanners, StackVehicle
from .publish import Publications
from .record import RunRecord
from .runlog import OperatorRecord

log = logging.getLogger("services.supervisor.session")


class MissionView(Protocol):
    """What the observer reads of the session (services/supervisor/session.py)."""

    config: MissionConfig
    spec: MissionSpec
    fires: StackFires | None
    planners: StackPlanners | None
    vehicle: StackVehicle

    @property
    def waypoints_n(self) -> int: ...

    @property
    def state(self) -> Array: ...

    @property
    def result(self) -> MissionResult | None: ...


@dataclass
class StackObserver:
    """Observes one mission's steps for the stack."""

    b: StackBus
    link: VehicleLink
    record: RunRecord
    pubs: Publications
    mission: MissionView
    #: the air–ground link's watch (a split deployment; None: every service on this host)
    airlink: LinkWatch | None = None
    faults: FaultLog = field(default_factory=FaultLog, init=False)
    #: plans the run-time monitor refused (dualpilot/mission/monitor)
    monitor_rejected: int = field(default=0, init=False)
    tick: float = field(default=0.0, init=False)  # perf_counter at the step's start (latency)
    _why: dict[str, object] = field(default_factory=dict, init=False)
    _decision: tuple[Decision, int] | None = field(default=None, init=False)
    _holds_seen: int = field(default=0, init=False)
    _modes_seen: int = field(default=0, init=False)

    # -- events -------------------------------------------------------------------------------
    def event(self, kind: EventKind, **values: object) -> None:
        """A MissionEvent, and (but for STEP) an ``event`` line in the record."""
        m = self.mission
        if kind is not EventKind.STEP:
            self.record.line("event", event=kind.word,
                             **{k: v for k, v in values.items() if k != "position"})
        pos: Any = values.pop("position", None)
        ev = MissionEvent(kind, self.b.mission_id, m.config.controller.value, m.spec.seed,
                          position=None if pos is None else (float(pos[0]), float(pos[1])),
                          **values)  # type: ignore[arg-type]
        self.pubs.event(ev)

    def step_event(self, record: StepRecord, note: str = "") -> None:
        m = self.mission
        assert m.result is not None and m.fires is not None
        self.event(EventKind.STEP, step=record.t, flown_system=record.system,
                   position=m.state, fires_active=len(m.fires.current.regions),
                   plan_status=record.plan_status, mission_time_s=m.result.mission_time_s,
                   message=note)

    # -- the step's observer ------------------------------------------------------------------
    def decided(self, t: int, decision: Decision, commanded: int) -> None:
        fires = self.mission.fires
        assert fires is not None
        self._decision = (decision, commanded)
        alive = [k for k in (1, 2) if self.b.alive(f"system{k}")]
        self._why = {
            "fire_age_s": fires.age_s(), "fire_stale": fires.stale(),
            "fire_margin_m": round(fires.margin_m(), 3),
            "planners_alive": [f"system{k}" for k in alive], "ews_alive": self.b.alive("ews"),
            "commanded_system": commanded}

    def commanded(self, t: int, flown: int, info: dict[str, object]) -> None:
        """The setpoint has left: the step's latency, the clock and the decision (published
        off the control path)."""
        p = self.mission.planners
        assert p is not None and self._decision is not None
        pool = p.pool
        self.record.latency.add(t, self.mission.vehicle.sent - self.tick, p.compute,
                                pool.requests, pool.request_wall_s, pool.service_s)
        self.record.latency.requests.extend(pool.take_answered())
        rejected = p.last_info.get(1, {}).get("operator_rejected")
        op = OperatorRecord(t, self.mission.waypoints_n,
                            str(info.get("source", "")) if flown == 1 else "",
                            bool(rejected), str(rejected or ""))
        self.record.operator.append(op)
        decision, wanted = self._decision
        why = self._why
        notes = DecisionNotes(op.source, op.rejected, op.waypoints, op.note,
                              bool(why["fire_stale"]), float(why["fire_age_s"]),  # type: ignore[arg-type]
                              float(why["fire_margin_m"]))  # type: ignore[arg-type]
        self.pubs.step_started(decision, wanted, notes)

    def hold_reason(self) -> str:
        alive = any(self.b.alive(f"system{k}") for k in self.mission.config.systems())
        return "no OK plan" if alive else "no planner alive"

    def _step_faults(self, t: int) -> list[str]:
        """The named faults since the last step record (services/supervisor/faults.py)."""
        status = self.link.status
        for reason in status.hold_reasons[self._holds_seen:status.holds]:
            self.faults.note(fault_names.VEHICLE_HOLD, reason)
        self._holds_seen = status.holds
        planners = self.mission.planners
        misses = planners.pool.deadline_misses if planners is not None else 0
        self.faults.counters(vehicle_moved=self.link.position.moved_without_step,
                             plan_deadline=misses)
        if self._why.get("fire_stale"):
            self.faults.note(fault_names.FIRE_STALE)
        fires = self.mission.fires
        for why in fires.forecasts.take_faults() if fires is not None else ():
            self.faults.note(fault_names.FORECAST_STALE, why)
        if self.airlink is not None:  # what the air–ground link did during the step
            behind = self.airlink.params.services
            state, why = self.airlink.step(t, [s for s in behind if not self.b.alive(s)])
            if state in (fault_names.LINK_DEGRADED, fault_names.LINK_LOST):
                self.faults.note(state, why)
        found = self.faults.take()
        if found:
            log.warning("step touched by a fault", extra=fields(faults="; ".join(found)))
        return found

    def modes(self) -> None:
        """A ``vehicle_mode`` event line for every change of the vehicle's mode or arming
        since the last one (its autopilot's name, and the STATUSTEXT that explained it)."""
        status = self.link.status
        changes = status.mode_changes
        for ch in changes[self._modes_seen:]:
            self.record.line("event", event="vehicle_mode", mode=ch.mode, armed=ch.armed,
                             autopilot=status.modes.family if status.modes else "",
                             text=ch.text)
        self._modes_seen = len(changes)

    def recorded(self, record: StepRecord, flown: bool) -> None:
        self.modes()
        self.pubs.plans(record, self.mission.spec)  # the live view (services/viewer)
        rejected = sum(a.refused_by_monitor for a in record.answers)
        if rejected:
            self.monitor_rejected += rejected
            log.warning("plan refused by the run-time monitor", extra=fields(
                step=record.t, plan_status=record.plan_status, total=self.monitor_rejected))
        why = dict(self._why)
        why["faults"] = self._step_faults(record.t)
        fires = self.mission.fires
        costs = fires.forecasts.take_costs() if fires is not None else []
        if costs:
            why["forecast"] = costs
        if record.system == 0:
            why["hold_reason"] = self.hold_reason()
        if not flown:
            self.record.step(record, False, sim_time_s=self.b.clock.now_s, **why)
            return
        state = self.mission.state
        self.pubs.state(state, record.t + 1)
        self.record.step(record, True, sim_time_s=self.b.clock.now_s,
                         after=[float(v) for v in state], **why)
        self.b.clock.sleep_until_now(self.b.stop)  # the flight lasts ΔT of simulated time

    def ended(self, record: StepRecord, ending: Ending) -> None:
        result = self.mission.result
        assert result is not None
        self.modes()
        self.record.line("end", success=ending.success, failure_cause=ending.failure_cause,
                         steps=result.steps, final_state=[float(v) for v in self.mission.state])
        self.step_event(record)
        log.info("mission ended", extra=fields(success=ending.success,
                                               cause=ending.failure_cause, steps=result.steps))

    def step_note(self, record: StepRecord) -> str:
        """The STEP event's note: stale fire data, braking and why."""
        why = self._why
        note = (f"fire data stale: {why['fire_age_s']:g} s old, hulls grown by "
                f"{why['fire_margin_m']:.1f} m" if why.get("fire_stale") else "")
        if record.system == 0:
            note = "; ".join(filter(None, [note, f"braking: {self.hold_reason()}"]))
        return note

    def began(self) -> None:
        """A step starts now (its latency is measured from here)."""
        self.tick = time.perf_counter()

"""supervisor.proto ↔ core types: decisions, mission events and the live view's step plans.

Decoders check counts, finiteness and ranges (services/common/limits.py) and raise
:class:`~services.common.rejections.CodecError` for a bad message.
"""

from __future__ import annotations

import enum
import math
import re
from dataclasses import dataclass

import numpy as np

from dualpilot.mission.answers import PlanView, statuses_by_system
from dualpilot.mission.result import StepRecord
from dualpilot.model.dynamics import Array
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import Decision
from services.common.convert.common import (
    packed_from_msg,
    packed_to_msg,
    polygon_from_msg,
    polygon_to_msg,
)
from services.common.convert.plan import (
    objective_from_msg,
    objective_to_msg,
    spec_from_msg,
    spec_to_msg,
)
from services.common.limits import (
    MAX_ABS_M,
    MAX_HORIZON,
    MAX_RISK_ZONES,
    MAX_TEXT,
    check_count,
    check_floats,
    check_text,
    finite,
)
from services.common.rejections import Reason, invalid
from services.common.wire import Stamper
from services.msgs import supervisor_pb2


@dataclass(frozen=True)
class DecisionNotes:
    """What the stack adds to a step's decision: System 1's reference path, the operator's
    waypoints, and the fire data the decision used (stale: grown by ``fire_margin_m``)."""

    plan_source: str = ""  # "operator", "rrt", or "" (System 2 flew, or nothing)
    operator_rejected: bool = False
    operator_waypoints: int = 0
    operator_note: str = ""
    fire_stale: bool = False
    fire_age_s: float = 0.0
    fire_margin_m: float = 0.0


def decision_to_msg(d: Decision, commanded_system: int, stamper: Stamper,
                    sim_time_s: float, notes: DecisionNotes = DecisionNotes()
                    ) -> supervisor_pb2.Decision:
    m = supervisor_pb2.Decision(step=d.t, d_t_m=float(d.d_t), attention=d.attention,
                                system=d.system, objective=objective_to_msg(d.objective),
                                commanded_system=commanded_system,
                                plan_source=notes.plan_source,
                                operator_rejected=notes.operator_rejected,
                                operator_waypoints=notes.operator_waypoints,
                                operator_note=notes.operator_note[:500],
                                fire_stale=notes.fire_stale, fire_age_s=notes.fire_age_s,
                                fire_margin_m=notes.fire_margin_m)
    stamper.stamp(m.header, sim_time_s)
    m.xi.extend(float(v) for v in d.xi)
    m.p.extend(float(v) for v in d.p)
    m.psi.extend(float(v) for v in d.psi)
    return m


def decision_from_msg(m: supervisor_pb2.Decision) -> Decision:
    if len(m.xi) != 3 or len(m.p) != 3 or len(m.psi) != 2:
        raise invalid("a decision has 3 ξ, 3 p and 2 ψ", Reason.SIZE)
    xi = finite(m.xi, "xi", 1e6)
    p = finite(m.p, "p", 1.0)
    psi = finite(m.psi, "psi", 1e6)
    if np.any(xi <= 0):
        raise invalid(f"ξ (Dirichlet concentrations) must be > 0, got {xi}", Reason.OUT_OF_RANGE)
    if np.any(p < 0) or abs(float(p.sum()) - 1.0) > 1e-6:
        raise invalid(f"p must be a probability vector, got {p}", Reason.OUT_OF_RANGE)
    if math.isnan(m.d_t_m):
        raise invalid("d_t is NaN", Reason.NOT_FINITE)
    if m.d_t_m < 0:
        raise invalid(f"d_t must be >= 0 (inf allowed), got {m.d_t_m}", Reason.OUT_OF_RANGE)
    if m.attention not in (1, 2, 3) or m.system not in (1, 2):
        raise invalid(f"attention {m.attention} / system {m.system} out of range",
                      Reason.OUT_OF_RANGE)
    objective = objective_from_msg(m.objective)
    assert objective is not None
    return Decision(t=int(m.step), d_t=float(m.d_t_m), xi=xi, p=p, attention=int(m.attention),
                    psi=psi, system=int(m.system), objective=objective)


#: one status of a system at a step: a word (a plan status, "unavailable", the concurrent
#: supervisor's "adopted", ...) and the run-time monitor's optional note
_PLAN_STATUS = re.compile(r"^[a-z_]{1,32}(\[[^\]]{0,1000}\])?$")


@dataclass(frozen=True)
class StepPlans:
    """A validated StepPlans message in core types: both systems' plans at a step."""

    mission_id: str
    step: int
    time_s: float  # τ_t (s)
    flown: int  # 0: none
    plans: tuple[PlanView, ...]  # systems 1 and 2; status "" for a system not asked
    spec: MissionSpec
    #: the risk zones the flown plan was made against (vertices, m) and their α (none: 0)
    risk_zones: tuple[Array, ...] = ()
    risk_alpha: float = 0.0


def step_plans_msg(record: StepRecord, mission_id: str, spec: MissionSpec, stamper: Stamper,
                   sim_time_s: float) -> supervisor_pb2.StepPlans:
    """A recorded step's plans: each asked system's status, the flown plan's positions."""
    m = supervisor_pb2.StepPlans(mission_id=mission_id, step=record.t,
                                 step_time_s=float(record.time_s), flown_system=record.system)
    stamper.stamp(m.header, sim_time_s)
    spec_to_msg(mission_id, spec, m.mission)
    statuses = statuses_by_system(record.answers)
    if record.system and record.system not in statuses:
        statuses[record.system] = ""  # flown, not asked at this step (a kept plan)
    for system, status in statuses.items():
        sp = m.plans.add(system=system, status=status[:MAX_TEXT])
        if system == record.system:
            packed_to_msg(np.asarray(record.planned_positions)[:, :2], sp.positions_m)
    if record.risk is not None:
        m.risk_alpha = record.risk.alpha
        for zone in record.risk.zones[:MAX_RISK_ZONES]:
            polygon_to_msg(zone, m.risk_zones.add())
    return m


def step_plans_from_msg(m: supervisor_pb2.StepPlans) -> StepPlans:
    """Rejected: a system other than 1 or 2 (or twice), a status that is not one, positions for
    a plan that was not flown, a flown system without its plan, a bad spec or time."""
    if not m.HasField("mission"):
        raise invalid("step plans without the mission spec")
    mission_id, spec = spec_from_msg(m.mission)
    check_floats([m.step_time_s], "step_time_s", 1e12)
    if m.step_time_s < 0:
        raise invalid(f"step_time_s must be >= 0, got {m.step_time_s}", Reason.OUT_OF_RANGE)
    if m.flown_system not in (0, 1, 2):
        raise invalid(f"flown_system {m.flown_system} out of range", Reason.OUT_OF_RANGE)
    check_count(len(m.plans), "plans", 2)
    got: dict[int, PlanView] = {}
    for sp in m.plans:
        if sp.system not in (1, 2) or sp.system in got:
            raise invalid(f"plan of system {sp.system} (once each of 1 and 2)",
                          Reason.OUT_OF_RANGE)
        status = check_text(sp.status, "plan status", MAX_TEXT)
        parts = status.split(";") if status else []
        if any(not _PLAN_STATUS.match(p) for p in parts) or (
                not parts and sp.system != m.flown_system):
            raise invalid(f"plan status {status[:80]!r} is not a status")
        pts = packed_from_msg(sp.positions_m, "plan positions", 2, MAX_HORIZON + 1, MAX_ABS_M)
        if len(pts) and sp.system != m.flown_system:
            raise invalid(f"positions for system {sp.system}'s plan, which was not flown")
        got[sp.system] = PlanView(int(sp.system), status, pts, sp.system == m.flown_system)
    if m.flown_system and (m.flown_system not in got or not len(got[m.flown_system].positions)):
        raise invalid(f"system {m.flown_system} flew but its plan's positions are missing")
    empty = np.empty((0, 2))
    plans = tuple(got.get(k, PlanView(k, "", empty, False)) for k in (1, 2))
    zones, alpha = _risk_zones(m)
    return StepPlans(mission_id, int(m.step), float(m.step_time_s), int(m.flown_system), plans,
                     spec, zones, alpha)


def _risk_zones(m: supervisor_pb2.StepPlans) -> tuple[tuple[Array, ...], float]:
    """The risk zones' vertices and α; rejected: more than MAX_RISK_ZONES, a bad polygon, an
    α outside [0, 1), zones without a plan flown."""
    check_count(len(m.risk_zones), "risk zones", MAX_RISK_ZONES)
    check_floats([m.risk_alpha], "risk_alpha", 1.0)
    if not 0.0 <= m.risk_alpha < 1.0:
        raise invalid(f"risk_alpha must be in [0, 1), got {m.risk_alpha}", Reason.OUT_OF_RANGE)
    if len(m.risk_zones) and not m.flown_system:
        raise invalid("risk zones for a step that flew no plan")
    zones = tuple(polygon_from_msg(z, f"risk zone {i}").vertices
                  for i, z in enumerate(m.risk_zones))
    return zones, float(m.risk_alpha)


def check_mission_event(m: supervisor_pb2.MissionEvent) -> supervisor_pb2.MissionEvent:
    """A MissionEvent a viewer may show: a known kind, short texts, a finite position."""
    if m.kind not in supervisor_pb2.MissionEventKind.values() or (
            m.kind == supervisor_pb2.MISSION_EVENT_KIND_UNSPECIFIED):
        raise invalid(f"unknown mission event kind {m.kind}", Reason.OUT_OF_RANGE)
    for name, limit in (("mission_id", 256), ("controller", 16), ("failure_cause", 256),
                        ("plan_status", MAX_TEXT), ("message", MAX_TEXT)):
        check_text(getattr(m, name), f"mission event {name}", limit)
    check_floats([m.position.east_m, m.position.north_m, m.mission_time_s],
                  "mission event position/time", MAX_ABS_M)
    if m.flown_system not in (0, 1, 2):
        raise invalid(f"flown_system {m.flown_system} out of range", Reason.OUT_OF_RANGE)
    return m



# -- mission events --------------------------------------------------------------------------------
class EventKind(enum.Enum):
    """What a MissionEvent announces (supervisor.proto MissionEventKind)."""

    STARTED = supervisor_pb2.MISSION_EVENT_KIND_STARTED
    STEP = supervisor_pb2.MISSION_EVENT_KIND_STEP
    ENDED = supervisor_pb2.MISSION_EVENT_KIND_ENDED
    ABORTED = supervisor_pb2.MISSION_EVENT_KIND_ABORTED
    PAUSED = supervisor_pb2.MISSION_EVENT_KIND_PAUSED
    RESUMED = supervisor_pb2.MISSION_EVENT_KIND_RESUMED
    WAYPOINTS = supervisor_pb2.MISSION_EVENT_KIND_WAYPOINTS

    @property
    def word(self) -> str:
        """The kind as the step record's ``event`` lines name it ("paused", …)."""
        return self.name.lower()


@dataclass(frozen=True)
class MissionEvent:
    """One mission event in core types: what happened, to which mission, at which step."""

    kind: EventKind
    mission_id: str
    controller: str
    seed: int
    step: int = 0
    success: bool = False
    failure_cause: str = ""
    mission_time_s: float = 0.0
    flown_system: int = 0  # STEP: the system whose plan was flown (0: braked)
    position: tuple[float, float] | None = None  # the position after the step (m)
    fires_active: int = 0
    plan_status: str = ""
    message: str = ""


def mission_event_msg(ev: MissionEvent, stamper: Stamper, sim_time_s: float
                      ) -> supervisor_pb2.MissionEvent:
    """A mission event on the wire (texts cut to their limits)."""
    m = supervisor_pb2.MissionEvent(
        kind=ev.kind.value, mission_id=ev.mission_id, controller=ev.controller[:16],
        seed=ev.seed, step=ev.step, success=ev.success, failure_cause=ev.failure_cause[:256],
        mission_time_s=ev.mission_time_s, flown_system=ev.flown_system,
        fires_active=ev.fires_active, plan_status=ev.plan_status[:MAX_TEXT],
        message=ev.message[:MAX_TEXT])
    stamper.stamp(m.header, sim_time_s)
    if ev.position is not None:
        m.position.east_m, m.position.north_m = ev.position
    return m

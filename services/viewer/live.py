"""One vehicle's live scene: the stack's messages, as they arrive, drawn on its Foxglove channels
and in the web page's picture.

The channels and how each view is drawn are dualpilot/viz/foxglove.py's, the
ones mission.mcap has; the web page's :class:`~services.viewer.picture.VehicleScene`
takes the same calls. A step's decision channel joins the Decision and the
StepPlans of that step (whichever arrives second logs it), so it carries the
flown system and the step's simulated start time as mission.mcap does. Log
times are the senders' wall clocks (Header.wall_time_ns): one clock for a
whole fleet, whose vehicles' simulated clocks differ.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireSnapshot
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.paper.decision import Decision
from dualpilot.viz.foxglove import VehicleChannels
from dualpilot.viz.scene import (
    RiskView,
    area_view,
    decision_doc,
    end_text,
    fire_view,
    occupancy_view,
    start_text,
    step_text,
)
from services.common.convert.supervisor import StepPlans
from services.msgs import supervisor_pb2

from .picture import VehicleScene

#: steps kept while a step's Decision waits for its StepPlans (or the other way round)
JOIN_WINDOW = 64


def log_time_ns(header: Any) -> int:
    """A message's log time: its sender's wall clock (ns), else this process's now."""
    stamp = int(getattr(header, "wall_time_ns", 0))
    return stamp if stamp > 0 else time.time_ns()


class LiveVehicle:
    """What the viewer knows of one vehicle's mission, and where it draws it: its Foxglove
    channels and (with a web page) its scene in the page's picture."""

    def __init__(self, uav: str, context: Any, offset_m: tuple[float, float],
                 scene: VehicleScene | None = None):
        self.uav = uav
        self.ch = VehicleChannels(uav, context, offset_m)
        self.scene = scene
        self.sinks: tuple[Any, ...] = (self.ch,) if scene is None else (self.ch, scene)
        self.spec = MissionSpec()  # until the supervisor's first StepPlans names the mission's
        self.mission_id = ""
        self.path: list[Array] = []
        self.decisions: dict[int, tuple[Decision, int]] = {}
        self.plans: dict[int, StepPlans] = {}
        self.logged = 0  # messages logged on the channels

    def _new_mission(self, mission_id: str) -> None:
        if mission_id and mission_id != self.mission_id:
            self.mission_id = mission_id
            self.path.clear()
            self.decisions.clear()
            self.plans.clear()
            if self.scene is not None:
                self.scene.new_mission()

    def _join(self, t: int, t_ns: int) -> None:
        if t in self.decisions and t in self.plans:
            (d, commanded), sp = self.decisions.pop(t), self.plans.pop(t)
            doc = decision_doc(d, commanded, sp.flown, sp.time_s)
            for s in self.sinks:
                s.decision(doc, t_ns)
            self.logged += 1
        for store in (self.decisions, self.plans):
            for old in [k for k in store if k < t - JOIN_WINDOW]:
                del store[old]

    # -- one handler per key ----------------------------------------------------------------------
    def decision(self, d: Decision, commanded: int, t_ns: int) -> None:
        self.decisions[d.t] = (d, commanded)
        self._join(d.t, t_ns)

    def step_plans(self, sp: StepPlans, t_ns: int) -> None:
        self._new_mission(sp.mission_id)
        self.spec = sp.spec
        self.plans[sp.step] = sp
        area, risk = area_view(sp.spec), RiskView(sp.risk_zones, sp.risk_alpha)
        for s in self.sinks:
            s.transform(t_ns)
            s.area(area, t_ns)
            s.plans(sp.plans, sp.step, t_ns)
            s.risk(risk, sp.step, t_ns)
        self.logged += 5
        self._join(sp.step, t_ns)

    def state(self, x: Array, step: int, t_ns: int) -> None:
        if step == 0:
            self.path.clear()
        self.path.append(np.asarray(x[:3] if len(x) == 6 else x[:2], dtype=float))  # 3-D: z
        path = np.array(self.path)
        for s in self.sinks:
            s.vehicle(x, step, self.spec.d_safe_m, t_ns)
            s.path(path, t_ns)
        self.logged += 2

    def fires(self, snapshot: FireSnapshot, t_ns: int) -> None:
        view = fire_view(snapshot)
        for s in self.sinks:
            s.fires(view, t_ns)
        self.logged += 1

    def forecast(self, fc: OccupancyForecast, t_ns: int) -> None:
        view = occupancy_view(fc)
        for s in self.sinks:
            s.forecast(view, t_ns)
        self.logged += 1

    def event(self, ev: supervisor_pb2.MissionEvent, t_ns: int) -> None:
        kind = ev.kind
        if kind == supervisor_pb2.MISSION_EVENT_KIND_STARTED:
            self._new_mission(ev.mission_id)
            text, level = start_text(ev.controller, ev.seed, ev.message), "info"
        elif kind == supervisor_pb2.MISSION_EVENT_KIND_STEP:
            text = step_text(ev.step, ev.flown_system, ev.plan_status, ev.message)
            level = "info" if ev.flown_system else "warning"
        elif kind == supervisor_pb2.MISSION_EVENT_KIND_ENDED:
            text = end_text(ev.success, ev.failure_cause, ev.step)
            level = "info" if ev.success else "error"
        elif kind == supervisor_pb2.MISSION_EVENT_KIND_ABORTED:
            text, level = f"mission aborted: {ev.message}", "error"
        else:
            name = supervisor_pb2.MissionEventKind.Name(kind).rsplit("_", 1)[-1].lower()
            text = f"{name} at step {ev.step}: {ev.message}"
            level = "warning" if kind == supervisor_pb2.MISSION_EVENT_KIND_PAUSED else "info"
        for s in self.sinks:
            s.event(text, t_ns, level)
        self.logged += 1

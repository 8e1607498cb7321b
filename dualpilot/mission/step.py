"""The one mission step of Sec. IV: supervisor → planner → one control → fires.

Each step t:

1. the fire port's snapshot gives the active regions and the hulls △(C^i_{1:t});
2. the supervisor computes Ξ_t from t and d_t, samples P_t and A_t, updates
   Ψ_t and picks S_t (``cc``); ``s1`` / ``s2`` run the same supervisor but force
   the system, so all three controllers see the same attention stream;
3. the chosen system plans from the current state (``cc``: the other one if
   the plan is not OK); while it computes, the UAV hovers and the fires
   propagate ⌈T_s / T_f⌉ sub-steps (T_s measured, or the paper's 155 ms / 5 s).
   Steps 2–3 are the supervisor's one planning call, built by name
   (:mod:`dualpilot.supervisor.registry`: the paper's, above, or another);
4. the plan's x_{t+1|t} is commanded at once, due after the planning interval
   and ΔT; the fires advance; the mission fails if an active region came
   within d_safe of the idle UAV;
5. the vehicle flies one step of Eq. (1): failure if its motion passes within
   d_safe of an active region, success on entering G. In-process the vehicle is a
   plant (:mod:`dualpilot.mission.flight`): Eq. (1) exactly by default, or a
   multirotor whose true path is judged at every integration step (a breach its
   plan did not make is a ``tracking_breach``); the planners plan from its
   measured state, the failure rules judge its true position.

A plan that is not OK is never flown: with no OK plan the UAV brakes, or under
``no_plan = "escape"`` flies away from a hull too near to plan from
(:func:`~dualpilot.mission.braking.no_plan_control`).
The step is written once; :mod:`dualpilot.mission.local` runs it in one process,
``services/supervisor`` over Zenoh and MAVLink.

In 3-D (``spec.dim == 3``, docs/three_d.md) positions are [x, y, z] (z up) and every
region is its front's cuboid C_t (:class:`~dualpilot.model.prism.Cuboid`): d_t of
Eq. (KSI) is the Euclidean distance to the nearest cuboid, as the paper writes it
(d_t = ‖x_t^p − ŷ_t^p‖₂), d_safe and the failure rules are measured to the cuboids, and G
is the goal box (:attr:`~dualpilot.spec.MissionSpec.goal_box`). A snapshot or region
without a top (the stack's until its wire carries them) is a cuboid taller than the band
(:attr:`~dualpilot.spec.MissionSpec.above_ceiling_m`). With every cuboid taller than the
band, a UAV in the band gets the planar distances bit for bit: the 2-D mission.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from dualpilot.mission.braking import brake_control, no_plan_control
from dualpilot.mission.config import MissionConfig
from dualpilot.mission.flight import judge_flight, tracking_errors, true_position
from dualpilot.mission.monitor import PLANNER_RISK
from dualpilot.mission.params import MissionParams, Timing
from dualpilot.mission.ports import (
    FirePort,
    ForecastPlannerPort,
    ForecastPort,
    KeepOut,
    PlannerPort,
    StepObserver,
    VehiclePort,
)
from dualpilot.mission.result import Ending, MissionResult, StepRecord
from dualpilot.model.dynamics import Array, step
from dualpilot.model.fire import FireSnapshot, Region, substeps_for
from dualpilot.model.geometry import Rect
from dualpilot.model.prism import Cuboid
from dualpilot.model.risk import ForecastView, RiskNote, risk_note
from dualpilot.spec import MissionSpec, Stream
from dualpilot.supervisor.interface import Planned
from dualpilot.supervisor.paper.decision import DecisionDynamics
from dualpilot.supervisor.registry import build_supervisor


def nearest_region_distance(position: Array, regions: tuple[Region, ...]) -> float:
    """Distance (m) from ``position`` to the nearest region (rectangles in the plane, cuboids
    in 3-D); inf when there is none."""
    return min((r.distance(position) for r in regions), default=float("inf"))


def _segment_distance(region: Region, p0: Array, p1: Array) -> float:
    if isinstance(region, Cuboid):
        return region.segment_distance(p0, p1)
    return region.polytope().segment_distance(p0, p1)


def segment_region_distance(p0: Array, p1: Array, regions: tuple[Region, ...]) -> float:
    """Distance (m) from the flown segment p0–p1 to the nearest region; inf when there is none."""
    return min((_segment_distance(r, p0, p1) for r in regions), default=float("inf"))


def _box_gap2(region: Region, lo: list[float], hi: list[float]) -> float:
    """The squared gap (m²) between the segment's box [lo, hi] and the region's box."""
    bounds = region.bounds3 if isinstance(region, Cuboid) else region.bounds
    n = len(bounds) // 2
    gap2 = 0.0
    for a in range(n):
        g = max(0.0, bounds[a] - hi[a], lo[a] - bounds[n + a])
        gap2 += g * g
    return gap2


def segment_within(p0: Array, p1: Array, regions: tuple[Region, ...], d_m: float) -> bool:
    """Whether the segment p0–p1 passes within ``d_m`` (m) of a region: the exact distance
    (:func:`segment_region_distance`) of the regions whose box gap to the segment's box (the
    altitude gap too, for a cuboid), a lower bound on it, is below ``d_m``."""
    a = [float(v) for v in p0]
    b = [float(v) for v in p1]
    lo = [min(u, v) for u, v in zip(a, b, strict=True)]
    hi = [max(u, v) for u, v in zip(a, b, strict=True)]
    near = tuple(r for r in regions if _box_gap2(r, lo, hi) < d_m * d_m)
    return segment_region_distance(p0, p1, near) < d_m


def hull_distance(position: Array, snapshot: FireSnapshot) -> float:
    """Distance (m) from ``position`` to the nearest hull △(C^i_{1:t}) (inf: none): polygons
    in the plane, prisms (a 3-D snapshot with tops)."""
    hulls = snapshot.hull_prisms() if snapshot.has_tops else snapshot.hulls
    return min((h.distance(position) for h in hulls), default=float("inf"))


def attention_distance(
    position: Array, snapshot: FireSnapshot, t: int, params: MissionParams
) -> float:
    """d_t of Eq. (KSI) under ``params.d_t_reading`` (m; inf when no region counts): to the
    nearest region, rectangle or (3-D, a snapshot with tops) cuboid.

    Fronts are stamped with the step during whose sub-steps they ignited, so
    at step t's decision the fronts that emerged since the last one ("newborn")
    carry ``born_step == t - 1``.
    """
    if params.d_t_reading == "hull":
        return hull_distance(position, snapshot)
    regions = snapshot.current()
    if params.d_t_reading == "newborn":
        regions = tuple(
            r for r, b in zip(regions, snapshot.born_steps, strict=True) if b == t - 1
        )
    return nearest_region_distance(position, regions)


def counted_regions(snapshot: FireSnapshot, t: int, params: MissionParams, d_safe_m: float,
                    previous: dict[int, float]) -> tuple[Region, ...]:
    """The regions whose coming within d_safe fails the mission at step t (``failure_rule``).

    "any": every active region; "newborn": those born during step t; "become":
    those whose distance was >= ``d_safe_m`` at the previous check
    (``previous``: front id → distance (m), see :func:`remember_distances`).
    """
    rule = params.failure_rule
    regions = snapshot.current()
    if rule == "any":
        return regions
    fronts = zip(regions, snapshot.front_ids, snapshot.born_steps, strict=True)
    if rule == "newborn":
        return tuple(r for r, _, b in fronts if b == t)
    return tuple(r for r, i, _ in fronts if previous.get(i, 0.0) >= d_safe_m)


def remember_distances(position: Array, snapshot: FireSnapshot,
                       previous: dict[int, float]) -> None:
    """Each active front's distance (m) from ``position``, for the "become" rule's next check."""
    previous.clear()
    previous.update((i, r.distance(position))
                    for r, i in zip(snapshot.current(), snapshot.front_ids, strict=True))


def flight_outcome(
    p0: Array, p1: Array, regions: tuple[Region, ...], steps: int, spec: MissionSpec,
    params: MissionParams,
) -> Ending | None:
    """After flying p0 → p1: how the mission ended (in G, fire contact, the step limit), or
    None to go on."""
    if segment_within(p0, p1, regions, spec.flight_d_safe_m):
        return Ending.FIRE_CONTACT
    if spec.in_goal(p1):
        return Ending.GOAL
    if steps >= params.max_steps:
        return Ending.STEP_LIMIT
    return None


@dataclass(frozen=True)
class MissionPorts:
    """The three ports the step talks to (in-process: dualpilot/mission/local.py; the stack's:
    services/supervisor/ports/)."""

    fires: FirePort
    planners: PlannerPort
    vehicle: VehiclePort


class Mission:
    """One mission of a :class:`MissionConfig` over three ports; ``run()`` flies it, ``step()``
    one tick.

    ``spec`` is the frozen spec the mission flies (the config's, with the vehicle's position
    as the start in the stack); ``state`` is the vehicle's state at the start (at rest at the
    spec's start in-process; as the vehicle reports it in the stack).
    """

    def __init__(self, config: MissionConfig, spec: MissionSpec, ports: MissionPorts,
                 state: Array, observer: StepObserver | None = None):
        reading = config.reading()
        self.config = config
        self.controller = config.controller
        self.spec = spec
        self.dyn = spec.dynamics
        self.dim = spec.dim
        self.fires, self.planners, self.vehicle = ports.fires, ports.planners, ports.vehicle
        self.timing = config.timing
        self.params = reading.mission
        self.fire_params = reading.fire
        self.observer = observer
        #: the paper's decision dynamics: the attention stream and Ψ, whichever supervisor
        #: plans
        self.decision_dynamics = DecisionDynamics(spec.rng(Stream.SUPERVISOR),
                                                  reading.supervisor)
        #: the supervisor (by name: dualpilot/supervisor/registry.py)
        self.supervisor = build_supervisor(config, spec)
        # the forecast is asked only by risk-aware planners and the forecast threat rule
        can = isinstance(self.fires, ForecastPort)
        self.forecast_systems = frozenset(
            s for s in (1, 2) if can and isinstance(self.planners, ForecastPlannerPort)
            and self.planners.uses_forecast(s))
        self.sim_time_s = 0.0  # simulated time: the fires' sub-steps and the flights
        self.state = np.asarray(state, dtype=float).copy()
        self.prev_control = np.zeros(self.dyn.dim)
        self.result = MissionResult(controller=config.controller.value,
                                    timing=config.timing.value, spec=spec,
                                    controller_name=config.controller_name)
        self.done = False
        #: front id → distance (m) at the last fire check (the "become" failure rule)
        self.front_distances: dict[int, float] = {}
        first = self._snapshot()
        if self._within_d_safe(first.current()):
            raise ValueError("the start lies within d_safe of a fire")
        remember_distances(self._position(), first, self.front_distances)

    def resume(self, result: MissionResult) -> None:
        """Continue a mission whose steps are in ``result`` (a restarted supervisor).

        Each recorded decision is replayed, so the attention stream and Ψ go on
        as if the mission had never stopped.
        """
        for rec in result.records:
            self.decision_dynamics.decide(rec.t, rec.d_t)
        if result.records:
            last = result.records[-1]
            self.prev_control = np.asarray(last.control, dtype=float)
            # the clock after the last recorded step: its planning, flight and motion sub-steps
            substeps = last.fire_substeps + self.params.fire_substeps_per_motion
            self.sim_time_s = last.time_s + substeps * self.fire_params.substep_s + self.dyn.dt_s
        self.result = result

    # -- one tick -------------------------------------------------------------------
    def _position(self) -> Array:
        """Where the UAV truly is (m), shape (dim,): what the failure rules judge (a plant's
        true position; the measured state plans)."""
        return true_position(self.vehicle, self.state[: self.dim])

    def _snapshot(self) -> FireSnapshot:
        """The fire port's snapshot; in 3-D one without tops has fires taller than the band."""
        snap = self.fires.snapshot()
        return snap.with_tops(self.spec.above_ceiling_m) if self.dim == 3 else snap

    def _regions(self, regions: tuple[Region, ...]) -> tuple[Region, ...]:
        """A sub-step's regions; in 3-D a rectangle without a top is taller than the band."""
        if self.dim != 3:
            return regions
        top = self.spec.above_ceiling_m
        return tuple(Cuboid(r, top) if isinstance(r, Rect) else r for r in regions)

    def _within_d_safe(self, regions: tuple[Region, ...]) -> bool:
        return nearest_region_distance(self._position(), regions) < self.spec.flight_d_safe_m

    def _keep_out(self) -> KeepOut | None:
        clear = self.params.ignition_clearance_m
        return None if clear is None else (self._position().copy(), clear)

    def _counted(self, t: int, snapshot: FireSnapshot) -> tuple[Region, ...]:
        return counted_regions(snapshot, t, self.params, self.spec.flight_d_safe_m,
                               self.front_distances)

    def _fire_fails(self, t: int, snapshot: FireSnapshot) -> bool:
        """The failure rule at the idle UAV; remembers the distances for the next check."""
        failed = self._within_d_safe(self._counted(t, snapshot))
        remember_distances(self._position(), snapshot, self.front_distances)
        return failed

    def _caught(self, t: int, n: int) -> bool:
        """Advance ``n`` sub-steps with the UAV idle; True if the failure rule is met.

        The rules other than "any" need each sub-step's fronts (ids, birth
        steps), so the fires then advance one sub-step at a time.
        """
        if self.params.failure_rule == "any":
            return any(self._within_d_safe(self._regions(r))
                       for r in self.fires.advance(t, n, self._keep_out()))
        caught = False
        for _ in range(n):
            if self.fires.advance(t, 1, self._keep_out()):
                caught = self._fire_fails(t, self._snapshot()) or caught
        return caught

    def substeps_per_step(self, system: int) -> int:
        """The sub-steps a step takes when ``system`` plans it: ⌈T_s / T_f⌉ (the paper's T_s, or
        its last measured one) plus those while the UAV moves."""
        times = self.result.planning_time_s[f"s{system}"]
        t_s = (times[-1] if times and self.timing is Timing.MEASURED
               else self.params.paper_planning_time_s[system - 1])
        return substeps_for(t_s, self.fire_params) + self.params.fire_substeps_per_motion

    def record_time(self, system: int, seconds: float) -> None:
        """One answer's compute time (s) of ``system``'s planner, for the result."""
        self.result.planning_time_s[f"s{system}"].append(seconds)

    def forecast_view(self, system: int) -> ForecastView | None:
        """The fire port's forecast for a plan of ``system`` (None when it is not used)."""
        if system not in self.forecast_systems:
            return None
        n = self.substeps_per_step(system)
        fc = cast(ForecastPort, self.fires).forecast(n)
        return None if fc is None else ForecastView(fc, n)

    def step(self) -> StepRecord | None:
        """Run one step; returns its record, or None when the mission is over."""
        if self.done:
            return None
        t = self.result.steps
        started_s = self.sim_time_s
        snapshot = self._snapshot()
        if self.result.records and self._within_d_safe(self._counted(t, snapshot)):
            # fire data that caught up (the stack's EWS was back) reached the UAV
            return self._finish(Ending.FIRE_WHILE_STALE, self.result.records[-1])
        d_t = attention_distance(self._position(), snapshot, t, self.params)
        planned = self.supervisor.plan(self, t, d_t, snapshot)
        n_sub = substeps_for(planned.planning_s, self.fire_params)
        control, target, positions, info = self._command(planned)
        # the setpoint leaves as soon as the plan is known, due after the planning
        # interval and one ΔT of flight
        self.vehicle.command(target, control, n_sub * self.fire_params.substep_s + self.dyn.dt_s)
        flown = planned.plan.system if planned.plan is not None else 0
        if self.observer is not None:
            self.observer.commanded(t, flown, info)
        caught = self._caught(t, n_sub)
        self.sim_time_s += n_sub * self.fire_params.substep_s
        record = StepRecord(
            t=t, state=self.state.copy(), control=control, decision=planned.decision,
            system=flown, answers=tuple(planned.answers),
            planning_time_s=planned.planning_s, fire_substeps=n_sub, d_t=d_t,
            fires_active=len(snapshot.regions), planned_positions=positions, snapshot=snapshot,
            info=info, time_s=started_s, risk=self._risk_note(planned),
            cost=None if planned.plan is None else planned.plan.cost,
            bound=None if planned.plan is None else planned.plan.bound,
        )
        self.result.records.append(record)
        if caught:  # the vehicle's step towards this setpoint does not count
            if self.observer is not None:
                self.observer.recorded(record, False)
            return self._finish(Ending.FIRE_WHILE_PLANNING, record)
        return self._fly(t, control, flown, record)

    @staticmethod
    def _risk_note(planned: Planned) -> RiskNote | None:
        """What the flown plan was made against, for the records (None: no forecast)."""
        if planned.plan is None or planned.forecast is None:
            return None
        return risk_note(planned.forecast, PLANNER_RISK, len(planned.plan.states) - 1)

    def _command(self, planned: Planned) -> tuple[Array, Array, Array, dict[str, object]]:
        """(control, target x_{t+1}, planned positions, info) of the plan to fly; with none,
        braking (Eq. 1's braking force, no positions) or, under ``no_plan = "escape"``, an
        escape (``info["source"] = "escape"``, steps.csv's ``source``)."""
        plan = planned.plan
        if plan is not None:
            info = dict(plan.info)
            control = np.asarray(plan.controls[0], dtype=float)
            target = np.asarray(plan.states[1], dtype=float)
            positions = np.asarray(plan.states[:, : self.dyn.dim])
        else:
            info = {}
            control, escaped = self._no_plan_control()
            if escaped:
                info["source"] = "escape"
            target = step(self.state, control, self.dyn)
            positions = np.empty((0, self.dyn.dim))
        if planned.note:
            info["supervisor"] = planned.note
        return control, target, positions, info

    def _no_plan_control(self) -> tuple[Array, bool]:
        """The force (N) flown with no OK plan, and whether it is an escape (``no_plan``)."""
        if self.params.no_plan == "brake":
            return brake_control(self.state, self.dyn), False
        snapshot = self._snapshot()
        return no_plan_control(self.state, self.dyn, lambda p: hull_distance(p, snapshot),
                               self.spec.clearance_m, self.spec.area)

    def _fly(self, t: int, control: Array, flown: int, record: StepRecord) -> StepRecord:
        """The vehicle's step of Eq. (1) towards the setpoint, then the flight's outcome."""
        prev_pos = self._position().copy()
        self.state = np.asarray(self.vehicle.observe(), dtype=float)
        self.result.add_flight(control, self.prev_control, self.dyn.dt_s)
        self.sim_time_s += self.dyn.dt_s
        self.supervisor.after_flight(flown, prev_pos, self._position(),
                                     float(np.sum((control - self.prev_control) ** 2)))
        self.prev_control = control
        if self.observer is not None:
            self.observer.recorded(record, True)
        motion = self.params.fire_substeps_per_motion
        self.sim_time_s += motion * self.fire_params.substep_s
        if motion and self._caught(t, motion):
            return self._finish(Ending.FIRE_IN_FLIGHT, record)
        after = self._snapshot()
        contact, left = judge_flight(self.vehicle, self._counted(t, after),
                                     self.spec.flight_d_safe_m)
        outcome = contact or flight_outcome(prev_pos, self._position(), left,
                                            self.result.steps, self.spec, self.params)
        remember_distances(self._position(), after, self.front_distances)
        return record if outcome is None else self._finish(outcome, record)

    def _finish(self, ending: Ending, record: StepRecord) -> StepRecord:
        self.done = True
        self.result.ending = ending
        self.result.final_state = self.state.copy()
        self.result.sim_time_s = self.sim_time_s
        self.result.tracking_error_m = tracking_errors(self.vehicle)
        if self.observer is not None:
            self.observer.ended(record, ending)
        return record

    def run(self) -> MissionResult:
        while self.step() is not None:
            pass
        return self.result

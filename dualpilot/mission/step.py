"""The closed-loop mission of Sec. IV: supervisor → planner → one control → fires.

Each step t:

1. the EWS snapshot gives the active regions and the hulls △(C^i_{1:t});
2. the supervisor computes Ξ_t from t and d_t, samples P_t and A_t, updates
   Ψ_t and picks S_t (``cc``); ``s1`` / ``s2`` run the same supervisor but force
   the system, so all three controllers see the same attention stream;
3. the chosen system plans from the current state; while it computes, the UAV
   hovers and the fires propagate ⌈T_s / T_f⌉ sub-steps (T_s measured, or the
   paper's 155 ms / 5 s); the mission fails if an active region comes within
   d_safe of the UAV;
4. the UAV applies the plan's first control for ΔT (Eq. 1); it fails if its
   motion passes within d_safe of an active region, succeeds on entering G.

A plan that is not OK is never flown: the other system is asked (fallback),
and if that fails too the UAV brakes towards a hover.
"""

from __future__ import annotations

import enum
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from dualpilot.model.dynamics import Array, DynamicsParams, hover_state, step
from dualpilot.model.fire import FireField, FireParams, FireSnapshot, substeps_for
from dualpilot.model.geometry import Rect
from dualpilot.plan import Objective, Plan, Planner, PlanStatus
from dualpilot.supervisor.decision import Decision, Supervisor, SupervisorParams


class Controller(enum.Enum):
    CC = "cc"
    S1 = "s1"
    S2 = "s2"


class Timing(enum.Enum):
    MEASURED = "measured"
    PAPER = "paper"


@dataclass(frozen=True)
class MissionParams:
    """Sec. IV values; ``paper_planning_time_s`` are the paper's S1/S2 averages."""

    d_safe_m: float = 20.0
    #: Clearance the planners keep from hulls (= System1Params.clearance_m, P2's ε).
    planner_clearance_m: float = 25.0
    max_steps: int = 150
    paper_planning_time_s: tuple[float, float] = (0.155, 5.0)
    #: Fire sub-steps while the UAV moves for ΔT. The paper propagates fires only
    #: while a plan is computed (0); 2 would also let fires evolve in flight.
    fire_substeps_per_motion: int = 0
    #: Reading of d_t in Eq. (KSI): "active" (nearest active region) or
    #: "newborn" (only regions born at this step; inf otherwise).
    d_t_reading: str = "active"
    fallback: bool = True
    #: None: fronts ignite anywhere (b_t uniform over the area), so one can
    #: ignite on the UAV, a failure no planner can avoid. A distance (m): no
    #: front ignites with its region that close to the UAV, so failures are
    #: only those the paper attributes to slow planning (a front reaching the
    #: hovering UAV). See the README's evaluation section.
    ignition_clearance_m: float | None = None

    def __post_init__(self) -> None:
        if self.max_steps < 1 or self.d_safe_m < 0:
            raise ValueError("max_steps >= 1 and d_safe_m >= 0 are required")
        if self.d_t_reading not in ("active", "newborn"):
            raise ValueError(f"d_t_reading must be 'active' or 'newborn', not {self.d_t_reading!r}")


@dataclass(frozen=True)
class MissionConfig:
    """Where the mission starts and ends (Sec. IV-A defaults)."""

    start: tuple[float, float] = (50.0, 50.0)
    goal: Rect = Rect(900.0, 900.0, 100.0, 100.0)
    area_size_m: float = 1000.0

    def __post_init__(self) -> None:
        area = Rect(self.area_size_m / 2, self.area_size_m / 2, self.area_size_m, self.area_size_m)
        if not self.goal.inside(area):
            raise ValueError(f"goal {self.goal} lies outside the {self.area_size_m} m area")
        if not area.contains(np.array(self.start)):
            raise ValueError(f"start {self.start} lies outside the area")

    @staticmethod
    def random(rng: np.random.Generator, area_size_m: float = 1000.0) -> MissionConfig:
        """A random configuration: start near one corner, goal near the opposite one."""
        start = rng.uniform(25.0, 200.0, size=2)
        gc = rng.uniform(area_size_m - 250.0, area_size_m - 75.0, size=2)
        return MissionConfig(
            start=(float(start[0]), float(start[1])),
            goal=Rect(float(gc[0]), float(gc[1]), 100.0, 100.0),
            area_size_m=area_size_m,
        )


@dataclass(frozen=True)
class StepRecord:
    """Everything that happened at one step (for steps.csv, trace.json and the figures)."""

    t: int
    state: Array  # before the control
    control: Array
    decision: Decision
    system: int  # the system whose plan was flown (0: none, braked)
    plan_status: str
    planning_time_s: float
    fire_substeps: int
    d_t: float
    fires_active: int
    planned_positions: Array
    snapshot: FireSnapshot
    info: dict[str, object] = field(default_factory=dict)


@dataclass
class MissionResult:
    controller: str
    seed: int
    timing: str
    config: MissionConfig
    success: bool = False
    failure_cause: str = ""
    steps: int = 0
    mission_time_s: float = 0.0
    energy: float = 0.0
    planning_time_s: dict[str, list[float]] = field(default_factory=lambda: {"s1": [], "s2": []})
    switches: int = 0
    records: list[StepRecord] = field(default_factory=list)
    final_state: Array | None = None

    def add_flight(self, control: Array, prev_control: Array, dt_s: float) -> None:
        """Account one flown step (its record already appended): energy, switches, time.

        Energy is Σ‖u_t − u_{t−1}‖²; a switch is a change of the system in
        control, braking steps (system 0) do not count.
        """
        self.energy += float(np.sum((np.asarray(control) - np.asarray(prev_control)) ** 2))
        flown = self.records[-1].system
        earlier = next((r.system for r in reversed(self.records[:-1]) if r.system), 0)
        if flown and earlier and flown != earlier:
            self.switches += 1
        self.steps += 1
        self.mission_time_s = self.steps * dt_s

    def summary(self) -> dict[str, object]:
        return {
            "controller": self.controller,
            "seed": self.seed,
            "timing": self.timing,
            "success": self.success,
            "failure_cause": self.failure_cause,
            "steps": self.steps,
            "mission_time_s": self.mission_time_s,
            "energy": self.energy,
            "planning_time_s": self.planning_time_s,
            "switches": self.switches,
            "start": list(self.config.start),
            "goal": {
                "center": [self.config.goal.center_x, self.config.goal.center_y],
                "size": [self.config.goal.width, self.config.goal.height],
            },
        }


PlannerFactory = Callable[[int], Planner]


def nearest_region_distance(position: Array, regions: tuple[Rect, ...]) -> float:
    """Distance (m) from ``position`` to the nearest region; inf when there is none."""
    return min((r.distance(position) for r in regions), default=float("inf"))


def segment_region_distance(p0: Array, p1: Array, regions: tuple[Rect, ...]) -> float:
    """Distance (m) from the flown segment p0–p1 to the nearest region; inf when there is none."""
    return min((r.polytope().segment_distance(p0, p1) for r in regions), default=float("inf"))


def attention_distance(
    position: Array, snapshot: FireSnapshot, t: int, params: MissionParams
) -> float:
    """d_t of Eq. (KSI) under ``params.d_t_reading`` (m; inf when no region counts)."""
    regions = snapshot.regions
    if params.d_t_reading == "newborn":
        regions = tuple(
            r for r, b in zip(snapshot.regions, snapshot.born_steps, strict=True) if b == t
        )
    return nearest_region_distance(position, regions)


def planning_time(plan: Plan, timing: Timing, params: MissionParams) -> float:
    """T_s of a plan: measured, or the paper's 155 ms / 5 s for System 1 / 2."""
    if timing is Timing.PAPER:
        return params.paper_planning_time_s[plan.system - 1]
    return plan.compute_time_s


def planning_order(controller: Controller, chosen: int, params: MissionParams) -> list[int]:
    """Systems to ask this step: the one in control, then (CC with fallback) the other."""
    wanted = {Controller.CC: chosen, Controller.S1: 1, Controller.S2: 2}[controller]
    fallback = params.fallback and controller is Controller.CC
    return [wanted, 3 - wanted] if fallback else [wanted]


def flight_outcome(
    p0: Array,
    p1: Array,
    regions: tuple[Rect, ...],
    steps: int,
    config: MissionConfig,
    params: MissionParams,
) -> str | None:
    """After flying p0 → p1: a failure cause, "" for success (in G), None to go on."""
    if segment_region_distance(p0, p1, regions) < params.d_safe_m:
        return "fire_contact"
    if config.goal.contains(p1):
        return ""
    if steps >= params.max_steps:
        return "step_limit"
    return None


def brake_control(state: Array, dyn: DynamicsParams) -> Array:
    """The force that brings the velocity to zero in one ΔT, clipped to U."""
    v = state[dyn.dim :]
    u = -dyn.mass_kg * (1.0 - dyn.zeta) * v / dyn.dt_s
    return np.asarray(np.clip(u, -dyn.u_max_n, dyn.u_max_n))


class Mission:
    """One mission with one controller. ``run()`` flies it; ``step()`` is one tick."""

    def __init__(
        self,
        controller: Controller,
        planners: dict[int, Planner],
        seed: int,
        timing: Timing = Timing.PAPER,
        config: MissionConfig = MissionConfig(),
        params: MissionParams = MissionParams(),
        dynamics: DynamicsParams = DynamicsParams(),
        fire_params: FireParams = FireParams(),
        supervisor_params: SupervisorParams = SupervisorParams(),
    ):
        self.controller = controller
        self.planners = planners
        self.timing = timing
        self.config = config
        self.params = params
        self.dyn = dynamics
        fire_rng, sup_rng = (
            np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2)
        )
        self.fire_rng = fire_rng
        self.fires = FireField(params=fire_params)
        self.supervisor = Supervisor(sup_rng, supervisor_params)
        self.state = hover_state(np.array(config.start), dynamics)
        self.prev_control = np.zeros(dynamics.dim)
        self.result = MissionResult(
            controller=controller.value, seed=seed, timing=timing.value, config=config
        )
        self.done = False
        snapshot = self.fires.snapshot()
        if nearest_region_distance(self.state[:2], snapshot.regions) < params.d_safe_m:
            raise ValueError("the start lies within d_safe of a fire")

    # -- one tick -------------------------------------------------------------------
    def _d_t(self, t: int, snapshot: FireSnapshot) -> float:
        return attention_distance(self.state[:2], snapshot, t, self.params)

    def _planning_time(self, plan: Plan) -> float:
        return planning_time(plan, self.timing, self.params)

    def _plan_with(self, system: int, snapshot: FireSnapshot, objective: Objective) -> Plan:
        planner = self.planners[system]
        t0 = time.perf_counter()
        try:
            obstacles = snapshot.obstacles_for(self.state[:2], self.params.planner_clearance_m)
            plan = planner.plan(self.state, obstacles, objective, self.prev_control)
        except ValueError as err:  # bad input to the planner: not flyable, not fatal
            plan = Plan.failed(system, PlanStatus.INVALID_INPUT, time.perf_counter() - t0, str(err))
        self.result.planning_time_s[f"s{system}"].append(plan.compute_time_s)
        return plan

    def _propagate(self, n: int, t: int) -> bool:
        """Propagate the fires ``n`` sub-steps with the UAV idle; False if it gets caught."""
        clear = self.params.ignition_clearance_m
        keep_out = None if clear is None else (self.state[:2].copy(), clear)
        for _ in range(n):
            self.fires.substep(self.fire_rng, t, keep_out=keep_out)
            d = nearest_region_distance(self.state[:2], self.fires.snapshot().regions)
            if d < self.params.d_safe_m:
                return False
        return True

    def step(self) -> StepRecord | None:
        """Run one step; returns its record, or None when the mission is over."""
        if self.done:
            return None
        t = self.result.steps
        snapshot = self.fires.snapshot()
        d_t = self._d_t(t, snapshot)
        decision = self.supervisor.decide(t, d_t)
        order = planning_order(self.controller, decision.system, self.params)
        plan: Plan | None = None
        planning_time = 0.0
        statuses = []
        for system in order:
            candidate = self._plan_with(system, snapshot, decision.objective)
            planning_time += self._planning_time(candidate)
            statuses.append(f"s{system}:{candidate.status.value}")
            if candidate.ok:
                plan = candidate
                break
        n_sub = substeps_for(planning_time, self.fires.params)
        caught = not self._propagate(n_sub, t)

        if plan is not None:
            control = np.asarray(plan.controls[0], dtype=float)
            flown = plan.system
            planned = np.asarray(plan.states[:, : self.dyn.dim])
            info = dict(plan.info)
        else:
            control = brake_control(self.state, self.dyn)
            flown = 0
            planned = np.empty((0, self.dyn.dim))
            info = {}
        record = StepRecord(
            t=t,
            state=self.state.copy(),
            control=control,
            decision=decision,
            system=flown,
            plan_status=";".join(statuses),
            planning_time_s=planning_time,
            fire_substeps=n_sub,
            d_t=d_t,
            fires_active=len(snapshot.regions),
            planned_positions=planned,
            snapshot=snapshot,
            info=info,
        )
        self.result.records.append(record)
        if caught:
            return self._finish(False, "fire_while_planning", record)

        prev_pos = self.state[:2].copy()
        self.state = step(self.state, control, self.dyn)
        self.result.add_flight(control, self.prev_control, self.dyn.dt_s)
        self.prev_control = control
        if self.params.fire_substeps_per_motion and not self._propagate(
            self.params.fire_substeps_per_motion, t
        ):
            return self._finish(False, "fire_in_flight", record)
        outcome = flight_outcome(
            prev_pos, self.state[:2], self.fires.snapshot().regions, self.result.steps,
            self.config, self.params,
        )
        return record if outcome is None else self._finish(outcome == "", outcome, record)

    def _finish(self, success: bool, cause: str, record: StepRecord) -> StepRecord:
        self.done = True
        self.result.success = success
        self.result.failure_cause = cause
        self.result.final_state = self.state.copy()
        return record

    def run(self) -> MissionResult:
        while self.step() is not None:
            pass
        return self.result

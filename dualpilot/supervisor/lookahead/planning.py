"""The lookahead supervisor in the mission step: its state over a mission.

The rule is in :mod:`dualpilot.supervisor.lookahead.rule`: the concurrent supervisor
(:class:`~dualpilot.supervisor.concurrent.planning.ConcurrentSupervisor`) chooses, and its
choice is flown only if it is sound on the known future; else the supervisor's space-time
plan is flown, kept while it stays clear, for at most ``guard_steps`` steps. It runs the
cognitive controller only (the registry's "lookahead", :data:`ENTRY`,
:mod:`dualpilot.supervisor.registry`). In 3-D, where every front and forecast cell is as
tall as the band, the known future is the footprints' and the space-time plans are planar,
flown at the UAV's altitude (:mod:`dualpilot.supervisor.lookahead.vertical`); else it keeps
each box's top and the search runs over the band (:mod:`dualpilot.spacetime.plan3`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from dualpilot.mission.answers import Answer
from dualpilot.mission.answers import SystemStatus as S
from dualpilot.mission.params import Controller, MissionParams, Timing
from dualpilot.mission.ports import FirePort, ForecastPort, PlannerPort
from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireParams, FireSnapshot
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.prism import Prism
from dualpilot.plan import Plan
from dualpilot.spacetime.known import growing, growth_per_substep, known_future, known_future3
from dualpilot.spacetime.plan import FutureBoxes, arrival, lattice_plan, plan_clear
from dualpilot.spacetime.plan3 import lattice_plan3, plan_clear3
from dualpilot.spacetime.smooth import smooth
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.concurrent.planning import ConcurrentSupervisor
from dualpilot.supervisor.concurrent.rule import (
    Choice,
    ConcurrentParams,
    Flown,
    Obstacles,
    check_near,
)
from dualpilot.supervisor.interface import (
    Planned,
    StepView,
    Supervisor,
    SupervisorEntry,
    SupervisorSettings,
)
from dualpilot.supervisor.lookahead.rule import LookaheadParams
from dualpilot.supervisor.lookahead.vertical import (
    footprints,
    lift_plan,
    low,
    low_clear,
    planar,
    planar_spec,
    spanning,
)
from dualpilot.supervisor.paper.decision import SupervisorParams

#: the notes of the supervisor's own plans' answers in the records ("s1:ok[space-time]")
SPACE_TIME, ESCAPE = "[space-time]", "[escape]"


class LookaheadSupervisor(ConcurrentSupervisor):
    """The concurrent supervisor's choice, guarded by the known future (module docstring)."""

    def __init__(self, spec: MissionSpec, timing: Timing, mission: MissionParams,
                 fire: FireParams, supervisor: SupervisorParams,
                 params: ConcurrentParams = ConcurrentParams(),
                 lookahead: LookaheadParams = LookaheadParams()):
        super().__init__(spec, timing, mission, fire, supervisor, params)
        self.lookahead = lookahead
        #: the space-time plan being flown, and the steps flown of it
        self.guard: Flown | None = None
        self.guarded = 0
        self.fires: FirePort | None = None
        self.max_steps = mission.max_steps
        #: how far a region's edge can move in a sub-step (m), for escapes
        self.growth_m = growth_per_substep(fire)
        #: the mission the lattice plans in: its plane in 3-D
        self.flat_spec = spec if spec.dim == 2 else planar_spec(spec)
        #: 3-D: the known future of the prisms that span the band (None: every prism does, the
        #: search's future) and the low prisms of now, for :meth:`sound`
        self.tall: FutureBoxes | None = None
        self.low: tuple[Prism, ...] = ()
        #: 3-D: the known future's cuboids (rows with tops) when a front or a forecast cell
        #: is lower than the band (None: the planar search and rules, :meth:`known`)
        self.cuboids: FutureBoxes | None = None

    def plan(self, step: StepView, t: int, d_t: float, snapshot: FireSnapshot) -> Planned:
        """Step t as the concurrent supervisor's (it calls :meth:`choose`)."""
        self.fires = step.fires
        return super().plan(step, t, d_t, snapshot)

    def choose(self, t: int, sim_s: float, state: Array, prev_control: Array,
               snapshot: FireSnapshot, seen: FireSnapshot, planners: PlannerPort,
               record_time: Callable[[int, float], None],
               forecast: Callable[[int], OccupancyForecast | None] | None = None) -> Choice:
        """The space-time plan being flown while it stays sound; else the concurrent
        supervisor's choice if it is sound on the known future; else a new space-time plan
        (else the concurrent supervisor's choice all the same)."""
        spec = self.spec
        obstacles = seen.obstacles(state[: spec.dynamics.dim], spec.clearance_m)
        known = self.known(t, obstacles)
        d = spec.d_safe_m + self.lookahead.margin_m
        kept = self._kept_guard(state, known, obstacles, d)
        if kept is not None:
            return Choice(plan=kept, note="space-time kept")
        self.guard = None
        choice = super().choose(t, sim_s, state, prev_control, snapshot, seen, planners,
                                record_time, forecast)
        if choice.plan is not None and self.sound(choice.plan, state, known, d):
            return choice
        guard = self.search(t, state, prev_control, known, obstacles, d, record_time)
        if guard is not None:
            self.guard, self.guarded = Flown(guard, 0, frozenset(snapshot.front_ids)), 0
            return self._fly_own(choice, guard, SPACE_TIME, "space-time")
        if choice.plan is None:  # boxed in: the UAV would brake
            escape = self.escape(t, state, obstacles, d, record_time)
            if escape is not None:
                return self._fly_own(choice, escape, ESCAPE, "escape")
        return choice

    def _fly_own(self, choice: Choice, plan: Plan, note: str, what: str) -> Choice:
        """Fly the supervisor's own plan: answered as System 1's, a deliberation along the
        old plan dropped (it is stale)."""
        choice.answers.append(Answer(1, S.OK, note))
        choice.wait_s += self.response_s(1, plan)
        self.flown, self.pending = None, None
        choice.plan, choice.note = plan, what
        return choice

    # -- the known future and what is sound on it ----------------------------------------------
    def known(self, t: int, obstacles: Obstacles) -> FutureBoxes:
        """The known future from step t to the step limit (:mod:`dualpilot.spacetime.known`),
        of every obstacle's footprint in 3-D; the prisms that span the band and the low ones
        are kept apart for :meth:`sound`. In 3-D, when a front or a forecast cell (its height
        by ``risk_zone_height``) is lower than the ceiling, the cuboids' future
        (:attr:`cuboids`) too."""
        per_step = self._step_substeps()
        fires = self.fires
        fc = fires.forecast(per_step) if isinstance(fires, ForecastPort) else None
        substeps = (self.max_steps - t + 1) * per_step
        alpha = self.lookahead.alpha
        band = self.spec.band
        self.low = low(obstacles, band)
        self.cuboids = None
        if self.spec.dim == 3 and (self.low or not self.spec.zone_heights.planar):
            cuboids = known_future3(obstacles, fc, substeps, alpha, self.spec.zone_heights,
                                    per_step)
            if len(cuboids.boxes) and cuboids.boxes[:, 4].min() < band.ceiling_m:
                self.cuboids = cuboids
        self.tall = None if not self.low else known_future(
            spanning(obstacles, band), fc, substeps, alpha, per_step)
        return known_future(footprints(obstacles), fc, substeps, alpha, per_step)

    def sound(self, plan: Plan, state: Array, known: FutureBoxes, d: float) -> bool:
        """Whether ``plan`` is clear of the known future over its next ``check_steps`` flights,
        or until it lands in G within ``arrive_steps``, and has not stalled outside G."""
        p = self.lookahead
        arrives = arrival(plan, self.spec)
        if arrives is None and float(np.linalg.norm(state[:2] - self.spec.goal.center)) < (
                p.stall_radius_m):
            return False
        steps = arrives if arrives is not None and arrives <= p.arrive_steps else p.check_steps
        if self.cuboids is not None:
            return plan_clear3(plan, self.cuboids, d, steps)
        if self.tall is None:
            return plan_clear(plan, known, d, steps)
        return plan_clear(plan, self.tall, d, steps) and low_clear(plan, self.low, d, steps)

    def _kept_guard(self, state: Array, known: FutureBoxes, obstacles: Obstacles,
                    d: float) -> Plan | None:
        """The rest of the space-time plan being flown, while it starts at the UAV's state, is
        sound and verifies, for at most ``guard_steps`` steps."""
        if self.guard is None or self.guarded >= self.lookahead.guard_steps:
            return None
        rest = self.guard.remainder(state)
        if rest is None or not np.allclose(rest.states[0], state, atol=1e-6):
            return None
        if not self.sound(rest, state, known, d) or check_near(
                rest, state, obstacles, self.spec, self.params.check_steps):
            return None
        return rest

    # -- the space-time search -------------------------------------------------------------------
    def search(self, t: int, state: Array, prev_control: Array, known: FutureBoxes,
               obstacles: Obstacles, d: float,
               record_time: Callable[[int, float], None]) -> Plan | None:
        """A space-time plan into G on the known future, smoothed when it can be (in 3-D over
        the cuboids, from the UAV's state, flown as found; over fronts all as tall as the band
        planar, flown at the UAV's altitude); timed as a System 1 answer. None when none is
        found or it does not verify."""
        spec = self.spec
        t0 = time.perf_counter()
        if self.cuboids is not None:
            plan, _ = lattice_plan3(state, self.cuboids, spec, self.lookahead.stages3,
                                    self.max_steps - t, d)
        else:
            plan = self._lattice(t, planar(state), prev_control[:2], known, d)
            if plan is not None and spec.dim == 3:
                plan = lift_plan(plan, state, spec.dynamics)
        seconds = time.perf_counter() - t0
        record_time(1, seconds)
        if plan is None or check_near(plan, state, obstacles, spec, self.params.check_steps):
            return None
        return Plan(plan.system, plan.status, plan.states, plan.controls, seconds,
                    info=plan.info)

    def _lattice(self, t: int, state: Array, prev_control: Array, known: FutureBoxes,
                 d: float) -> Plan | None:
        """The lattice plan: found keeping the tube's margin more and smoothed in it, else
        found keeping ``d`` and flown as it is (``state`` planar, its plane's mission)."""
        p, spec = self.lookahead, self.flat_spec
        steps = self.max_steps - t
        wide = d + math.sqrt(2.0) * p.tube_m
        static = known.boxes[known.offsets[0]:known.offsets[1]]  # the hulls: every sub-step
        for stage in p.stages:
            found, _ = lattice_plan(state, known, spec, stage, steps, wide, static)
            if found is not None:
                smoothed = smooth(found, spec, prev_control, p.tube_m)
                if smoothed is not None and arrival(smoothed, spec) is not None and plan_clear(
                        smoothed, known, d):
                    return smoothed
                return found
        for stage in p.stages:
            found, _ = lattice_plan(state, known, spec, stage, steps, d, static)
            if found is not None:
                return found
        return None

    def escape(self, t: int, state: Array, obstacles: Obstacles, d: float,
               record_time: Callable[[int, float], None]) -> Plan | None:
        """``escape_steps`` flights anywhere that keep ``d`` from the obstacles of now, each
        grown as fast as a front can grow (:func:`~dualpilot.spacetime.known.growing`);
        timed as a System 1 answer."""
        p, spec = self.lookahead, self.spec
        t0 = time.perf_counter()
        per_step = self._step_substeps()
        near = growing(footprints(obstacles), (p.escape_steps + 1) * per_step, self.growth_m,
                       per_step)
        plan, _ = lattice_plan(planar(state), near, self.flat_spec, p.escape_stage,
                               self.max_steps - t, d, survive=p.escape_steps)
        if plan is not None and spec.dim == 3:
            plan = lift_plan(plan, state, spec.dynamics)
        seconds = time.perf_counter() - t0
        record_time(1, seconds)
        if plan is None or check_near(plan, state, obstacles, spec, self.params.check_steps):
            return None
        return Plan(plan.system, plan.status, plan.states, plan.controls, seconds,
                    info={**plan.info, "planner": "escape"})

    def after_flight(self, system: int, p0: Array, p1: Array, du2: float) -> None:
        """One step flown: as the concurrent supervisor's, and along the space-time plan."""
        super().after_flight(system, p0, p1, du2)
        if self.guard is not None:
            self.guard.offset += 1
            self.guarded += 1


def _build(config: SupervisorSettings, spec: MissionSpec) -> Supervisor:
    reading = config.reading()
    return LookaheadSupervisor(spec, config.timing, reading.mission, reading.fire,
                               reading.supervisor, config.concurrent)


#: The registry's "lookahead" supervisor (System 1 tracking under the Δu penalty, as the
#: concurrent supervisor's).
ENTRY = SupervisorEntry(_build, frozenset({Controller.CC}), "rrt+du",
                        "the concurrent choice, guarded by the known future",
                        dims=frozenset({2, 3}))

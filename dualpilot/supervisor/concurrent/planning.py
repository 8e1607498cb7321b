"""The concurrent supervisor in the mission step: its state over a mission.

The rule is in :mod:`dualpilot.supervisor.concurrent.rule`; this is its state over
a mission: the plan being flown, the System 2 plan being deliberated, the
online Q. Times are simulated seconds of the mission (the step's clock). In 3-D the
obstacles are the fronts' prisms (:meth:`~dualpilot.model.fire.FireSnapshot.obstacles`).
:class:`ConcurrentSupervisor` is the registry's "concurrent" supervisor (:data:`ENTRY`,
:mod:`dualpilot.supervisor.registry`); it runs the cognitive controller only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from dualpilot.mission import monitor
from dualpilot.mission.answers import Answer
from dualpilot.mission.answers import SystemStatus as S
from dualpilot.mission.braking import braking_plan
from dualpilot.mission.params import Controller, MissionParams, Timing
from dualpilot.mission.ports import ForecastPort, PlannerPort, PlanRequest
from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireParams, FireSnapshot, substeps_for
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.risk import ForecastView, risk_map
from dualpilot.model.stale_fire import grown_snapshot
from dualpilot.plan import Objective, Plan
from dualpilot.spec import MissionSpec
from dualpilot.supervisor.concurrent.rule import (
    Choice,
    ConcurrentParams,
    Deliberation,
    Flown,
    Obstacles,
    OnlineQ,
    check_near,
    forecast_threatened,
    reanchor,
    steps_until,
    threatened,
    wait_hazard,
)
from dualpilot.supervisor.interface import (
    Planned,
    StepView,
    Supervisor,
    SupervisorEntry,
    SupervisorSettings,
)
from dualpilot.supervisor.paper.attention import xi
from dualpilot.supervisor.paper.decision import Decision, SupervisorParams


class ConcurrentSupervisor:
    """Chooses, each step, what the UAV flies; keeps System 2 deliberating in the background."""

    def __init__(self, spec: MissionSpec, timing: Timing, mission: MissionParams,
                 fire: FireParams, supervisor: SupervisorParams,
                 params: ConcurrentParams = ConcurrentParams()):
        self.spec = spec
        self.timing = timing
        self.mission = mission
        self.fire = fire
        self.supervisor = supervisor
        self.params = params
        dyn = spec.dynamics
        self.q = OnlineQ(supervisor.q_matrix, params, dyn.dt_s, dyn.v_max_mps)
        self.flown: Flown | None = None
        self.pending: Deliberation | None = None
        self.s2_expected_s = mission.paper_planning_time_s[1] if timing is Timing.PAPER else 0.0
        self.objective = Objective.MISSION_TIME
        self.utilities = np.zeros(2)
        self.p_mean = np.full(3, 1 / 3)
        #: this step's forecast as its plans see it (None: not used)
        self.view: ForecastView | None = None

    # -- the step's one planning call ------------------------------------------------------------
    def plan(self, step: StepView, t: int, d_t: float, snapshot: FireSnapshot) -> Planned:
        """Step t: the decision (:meth:`decide`), what the UAV flies (:meth:`choose`), checked
        by the run-time monitor as the paper's plans are; the planning interval is the time
        the UAV waited for answers this step."""
        flying = 0 if self.flown is None else self.flown.plan.system
        paper = step.decision_dynamics.decide(t, d_t)  # the attention stream: S2's objective
        decision = self.decide(t, d_t, flying, paper.objective)
        seen = grown_snapshot(snapshot, step.fires.margin_m())  # stale data: grown
        # the forecast: for the forecast threat rule and the risk-aware planners
        uses = self.params.threat == "forecast" or bool(step.forecast_systems)
        fires = step.fires
        forecast = fires.forecast if uses and isinstance(fires, ForecastPort) else None
        choice = self.choose(t, step.sim_time_s, step.state, step.prev_control, snapshot, seen,
                             step.planners, step.record_time, forecast)
        if choice.plan is not None:  # the run-time monitor has the last word, as for the paper's
            obstacles = seen.obstacles(step.state[: step.spec.dim], step.spec.clearance_m)
            k = self.params.check_steps  # a kept plan is re-checked every step
            verdict = monitor.check_plan(choice.plan.states[: k + 1], choice.plan.controls[:k],
                                         step.state, obstacles, step.spec)
            if not verdict.ok:
                choice.answers.append(monitor.refusal(choice.plan.system, verdict))
                choice.plan = None
                self.flown = None
        if choice.plan is not None:
            decision = replace(decision, system=choice.plan.system)
        if step.observer is not None:
            step.observer.decided(t, decision, decision.system)
        view = self.flown.view if choice.plan is not None and self.flown is not None else None
        return Planned(decision, choice.plan, choice.answers, choice.wait_s, choice.note, view)

    # -- what the record shows as the decision ---------------------------------------------------
    def decide(self, t: int, d_t: float, system_hint: int, objective: Objective) -> Decision:
        """Ξ_t (Eq. KSI), its mean p̄ = Ξ/ΣΞ, the attribute it favours, and Σ p̄ Q_t per system.

        System 2's objective is the paper's attention's (``objective``, drawn by the
        paper's supervisor from the same stream as for the S2-only agent).
        """
        xi_t = xi(t, d_t, self.supervisor.attention)
        self.p_mean = xi_t / xi_t.sum()
        a = int(np.argmax(self.p_mean))
        self.objective = objective
        self.utilities = np.array([self.q.utility(s, self.p_mean) for s in (1, 2)])
        return Decision(t=t, d_t=d_t, xi=xi_t, p=self.p_mean.copy(), attention=a + 1,
                        psi=self.utilities.copy(), system=system_hint or 1,
                        objective=self.objective)

    # -- times -----------------------------------------------------------------------------------
    def response_s(self, system: int, plan: Plan) -> float:
        """T_s of a plan: the paper's 155 ms / 5 s, or its measured compute time."""
        if self.timing is Timing.PAPER:
            return self.mission.paper_planning_time_s[system - 1]
        return plan.compute_time_s

    def _step_substeps(self) -> int:
        """The fire sub-steps of a step that waits only for System 1."""
        t_s1 = self.mission.paper_planning_time_s[0] if self.timing is Timing.PAPER else 0.0
        return substeps_for(t_s1, self.fire) + self.mission.fire_substeps_per_motion

    def _step_s(self) -> float:
        """The simulated length of a step that waits only for System 1 (s)."""
        return self._step_substeps() * self.fire.substep_s + self.spec.dynamics.dt_s

    # -- one step --------------------------------------------------------------------------------
    def choose(self, t: int, sim_s: float, state: Array, prev_control: Array,
               snapshot: FireSnapshot, seen: FireSnapshot, planners: PlannerPort,
               record_time: Callable[[int, float], None],
               forecast: Callable[[int], OccupancyForecast | None] | None = None) -> Choice:
        """What the UAV flies from ``state`` at step t (``seen``: the fires planners avoid).

        ``forecast(n)`` gives the fire forecast for steps of n sub-steps, for the forecast
        threat rule and the risk-aware planners (None: neither is used).
        """
        p, spec = self.params, self.spec
        obstacles = seen.obstacles(state[: spec.dynamics.dim], spec.clearance_m)
        choice = Choice(plan=None)
        known_now = frozenset(snapshot.front_ids)
        n_step = self._step_substeps()
        fc = forecast(n_step) if forecast is not None else None
        self.view = None if fc is None else ForecastView(fc, n_step)
        risk = (risk_map(self.view, p.risk, spec) if self.view is not None
                and p.threat == "forecast" else None)
        margin = spec.clearance_m if p.threat_margin_m is None else p.threat_margin_m

        def safe(f: Flown) -> bool:
            if threatened(f.plan, seen, f.known, margin, p.check_steps):
                return False
            return risk is None or not forecast_threatened(f.plan, risk, margin, p.check_steps)

        # without System 2 (its port says so), System 1 plans every step: "system1"
        onboard = p.s2_unavailable == "system1" and not planners.available(2)
        due = self._collect(t, sim_s, state, obstacles, planners, choice, record_time)
        kept = self._kept(state, obstacles, choice)
        options = [] if onboard else [f for f in (due, kept) if f is not None and safe(f)]
        if not options:
            options = self._ask_now(t, state, prev_control, obstacles, planners, choice,
                                    record_time, known_now, kept)
        self._fly(options, due, choice)
        if self.pending is not None and self.flown is not None and threatened(
                self.flown.plan, seen, self.pending.known, margin, p.check_steps):
            self.pending = None  # deliberating on a picture without a front that matters
            choice.answers.append(Answer(2, S.RESTARTED))
        if self.pending is None and not onboard:
            self._launch(t, sim_s, state, seen, known_now, planners, choice)
        return choice

    def _ask_now(self, t: int, state: Array, prev_control: Array,
                 obstacles: Obstacles, planners: PlannerPort, choice: Choice,
                 record_time: Callable[[int, float], None], known: frozenset[int],
                 kept: Flown | None) -> list[Flown]:
        """Nothing safe to fly: System 1 now; else the kept plan if it still verifies; else,
        with no deliberation pending, System 2 now when its wait's hazard is worth it."""
        fresh = self._ask(1, t, state, prev_control, obstacles, planners, choice, record_time)
        if fresh is not None:
            return [Flown(fresh, 0, known, self.view)]
        if kept is not None:  # System 1 has nothing: the known plan, if still safe
            return [kept]
        if self.pending is not None:
            return []
        spec = self.spec
        n = substeps_for(self.s2_expected_s, self.fire)
        if wait_hazard(n, self.fire, spec.area_size_m, spec.d_safe_m) > self.params.max_wait_hazard:
            return []
        slow = self._ask(2, t, state, prev_control, obstacles, planners, choice, record_time)
        return [] if slow is None else [Flown(slow, 0, known, self.view)]

    def _fly(self, options: list[Flown], due: Flown | None, choice: Choice) -> None:
        """Fly the best of ``options`` (nothing when there is none); say whether the due
        System 2 plan was adopted and whether the system in control changed."""
        if not options:
            self.flown = None
            return
        chosen = self._best(options)
        if due is not None and any(o is due for o in options):  # identity: plans hold arrays
            choice.answers.append(Answer(2, S.ADOPTED if chosen is due else S.DECLINED))
        if self.flown is not None and chosen.plan.system != self.flown.plan.system:
            choice.note = f"switch s{self.flown.plan.system}->s{chosen.plan.system}"
        self.flown = chosen
        choice.plan = chosen.plan

    def _best(self, options: list[Flown]) -> Flown:
        """The option of the system with the larger Σ p̄ Q; the system flying keeps a margin."""
        current = 0 if self.flown is None else self.flown.plan.system

        def score(f: Flown) -> float:
            bonus = self.params.switch_margin if f.plan.system == current else 0.0
            return self.utilities[f.plan.system - 1] + bonus

        return max(options, key=score)

    def _collect(self, t: int, sim_s: float, state: Array, obstacles: Obstacles,
                 planners: PlannerPort, choice: Choice,
                 record_time: Callable[[int, float], None]) -> Flown | None:
        """The deliberated System 2 plan, once due: re-anchored and verified, or None."""
        d = self.pending
        if d is None or t < d.due_t or sim_s + 1e-9 < d.ready_s:
            return None
        self.pending = None
        got = planners.collect(d.ticket)
        record_time(2, got.compute_time_s)
        if self.timing is Timing.MEASURED:
            self.s2_expected_s = 0.7 * self.s2_expected_s + 0.3 * got.compute_time_s
        self.q.response(2, self.response_s(2, got))
        if not got.ok:
            choice.answers.append(Answer(2, S.of(got.status)))
            return None
        if self._breaks_risk(got, d.view, choice):
            return None
        late = t - d.due_t
        plan = got if not late else replace(got, states=got.states[late:],
                                            controls=got.controls[late:])
        anchored = reanchor(plan, state, self.params, self.spec)
        if anchored is None:
            choice.answers.append(Answer(2, S.STALE_START))
            return None
        why = check_near(anchored, state, obstacles, self.spec, self.params.check_steps)
        if why:
            choice.answers.append(Answer(2, S.UNSAFE_AT_ADOPTION))
            choice.note = f"s2 plan refused: {why}"
            return None
        return Flown(anchored, 0, d.known, d.view)

    def _kept(self, state: Array, obstacles: Obstacles,
              choice: Choice) -> Flown | None:
        """The flown plan's remainder from the UAV's state, if it still verifies."""
        if self.flown is None:
            return None
        rest = self.flown.remainder(state)
        anchored = None if rest is None else reanchor(rest, state, self.params, self.spec)
        if anchored is None or check_near(anchored, state, obstacles, self.spec,
                                          self.params.check_steps):
            return None
        return Flown(anchored, 0, self.flown.known, self.flown.view)

    def _ask(self, system: int, t: int, state: Array, prev_control: Array,
             obstacles: Obstacles, planners: PlannerPort, choice: Choice,
             record_time: Callable[[int, float], None]) -> Plan | None:
        """A plan now (the UAV waits its response time); None unless it is OK and verifies."""
        if not planners.available(system):
            choice.answers.append(Answer(system, S.UNAVAILABLE))
            return None
        plan = planners.plan(PlanRequest(t=t, system=system, state=state.copy(),
                                         prev_control=prev_control, obstacles=obstacles,
                                         objective=self.objective, forecast=self.view))
        record_time(system, plan.compute_time_s)
        wait = self.response_s(system, plan)
        choice.wait_s += wait
        self.q.response(system, wait)
        risky = plan.ok and self._breaks_risk(plan, self.view, choice)
        if not risky:
            choice.answers.append(Answer(system, S.of(plan.status)))
        if risky or not plan.ok or check_near(plan, state, obstacles, self.spec,
                                              self.params.check_steps):
            return None
        return plan

    def _breaks_risk(self, plan: Plan, view: ForecastView | None, choice: Choice) -> bool:
        """The run-time monitor's check of the forecast zones the plan says it met (a refusal
        is recorded as the monitor's)."""
        verdict = monitor.check_risk(plan, view, self.spec)
        if not verdict.ok:
            choice.answers.append(monitor.refusal(plan.system, verdict))
        return not verdict.ok

    def _launch(self, t: int, sim_s: float, state: Array, seen: FireSnapshot,
                known: frozenset[int], planners: PlannerPort, choice: Choice) -> None:
        """Start System 2 from the state the UAV reaches when its plan will be due: along the
        flown plan, or braking when nothing is flown."""
        if not planners.available(2):
            return
        k = steps_until(self.s2_expected_s, self._step_s())
        plan = self.flown.plan if self.flown is not None else braking_plan(
            state, k, self.spec.dynamics)
        if k >= len(plan.states):
            return
        x_hat = plan.states[k]
        dim = self.spec.dynamics.dim
        try:
            obstacles = seen.obstacles(x_hat[:dim], self.spec.clearance_m)
        except ValueError:
            return
        view = None if self.view is None else replace(
            self.view, offset_substeps=k * self.view.substeps_per_step)
        ticket = planners.launch(PlanRequest(
            t=t + k, system=2, state=x_hat.copy(), prev_control=plan.controls[k - 1].copy(),
            obstacles=obstacles, objective=self.objective, forecast=view))
        self.pending = Deliberation(ticket=ticket, due_t=t + k, ready_s=sim_s + self.s2_expected_s,
                                    known=known, view=view)
        choice.answers.append(Answer(2, S.LAUNCHED))

    def after_flight(self, system: int, p0: Array, p1: Array, du2: float) -> None:
        """One step flown by ``system`` from p0 to p1 (m, the spec's dimension) with
        ‖u_t − u_{t−1}‖² = du2; progress is towards G_o (at its altitude in 3-D)."""
        goal = self.spec.goal_center
        progress = float(np.linalg.norm(goal - p0) - np.linalg.norm(goal - p1))
        if system:
            self.q.flown(system, progress, du2)
        if self.flown is not None:
            self.flown.offset += 1


def _build(config: SupervisorSettings, spec: MissionSpec) -> Supervisor:
    reading = config.reading()
    return ConcurrentSupervisor(spec, config.timing, reading.mission, reading.fire,
                                reading.supervisor, config.concurrent)


#: The registry's "concurrent" supervisor. It hands over between the systems every few
#: steps, so its System 1 tracks with the Δu penalty (dualpilot/system1/lqr.py: "rrt+du").
ENTRY = SupervisorEntry(_build, frozenset({Controller.CC}), "rrt+du",
                        "System 2 deliberates while the UAV flies; System 1 answers at once",
                        dims=frozenset({2, 3}))

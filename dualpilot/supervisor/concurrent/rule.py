"""A concurrent supervisor: System 2 deliberates while the UAV flies; System 1 answers at once.

The paper's supervisor (:mod:`dualpilot.supervisor.paper`) waits for the
plan of the system it picks: System 2's 5 s are ten fire sub-steps with the
UAV hovering, and the fronts that end missions ignite in that wait. This
supervisor never waits for System 2:

* **Deliberate while flying.** System 2 is launched in the background from
  the state x̂ the UAV will reach when its plan is due (the flown plan's
  state k steps ahead, k from System 2's response time and the step length)
  with u_{t|t} the control the flown plan applies just before, so its Δu term
  starts from the control actually applied (Eq. S2). When it is due, its plan
  is adopted only if it starts where the UAV is (re-anchored within a
  tolerance, else discarded) and it verifies against the fires of that
  moment (Eq. 1, limits, d_safe from the current obstacles over the next
  ``check_steps``).
* **Fly what is safe and knew the fires.** A plan is kept (its remainder
  flown, no planner asked) while it verifies and no front it did not know
  comes within the planners' clearance of its next steps; a front the flown
  plan did not know threatening it, or no plan that verifies, asks System 1
  at once (its response time is the only wait).
* **Weigh the risk of waiting.** Waiting T_s for a plan lets the fires run
  ⌈T_s/T_f⌉ sub-steps; the hazard of that wait is the probability that a
  front ignites within reach of the UAV (:func:`wait_hazard`). System 2 is
  waited for only when no safe plan exists and its wait's hazard is below
  ``max_wait_hazard``; otherwise System 1 answers.
* **Threats on the forecast** (``threat = "forecast"``). Also a plan whose next
  ``check_steps`` steps come within the margin of their own risk zones (the
  cells whose forecast occupancy exceeds α while the UAV is there,
  :mod:`dualpilot.model.risk`) is threatened: known fronts count too, by
  where they are going, not only where they have been.
* **Without System 2** (``s2_unavailable = "system1"``). While System 2 cannot be
  asked (its port says it is unavailable: a split deployment's dead air–ground link),
  System 1 plans every step from the fires the step has, stale ones grown by their
  credible spread, instead of the rest of the last System 2 plan: that plan was made
  on a picture no System 2 will correct. Once System 2 is available again it is
  launched as before.
* **Q online.** The performance matrix Q of Eq. (Psi) is updated after every
  step from measured response time, progress and energy (:class:`OnlineQ`);
  when a kept plan and a due plan are both safe, the system with the larger
  utility over the mission-time and energy attributes, weighted by the
  attention's mean p̄ = Ξ_t / ΣΞ_t (:meth:`OnlineQ.utility`), flies, with a
  hysteresis margin so that a switch must pay for itself.

In 3-D (``spec.dim == 3``, docs/three_d.md, 8) the obstacles are prisms and every distance
is the exact 3-D one (a front below the plan's altitude threatens it only within the
margin in 3-D); a plan is verified with the altitude band; the forecast's risk zones are
as tall as the spec's ``zone_heights`` (the run-time monitor's ``check_risk`` reading,
:func:`dualpilot.model.risk.risk_map`): under the default ``"band"`` as tall as every
altitude, the forecast threat rule reading the plan's ground track; with heights the
exact 3-D distances of the plan's positions.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from math import ceil
from typing import Literal

import numpy as np

from dualpilot.mission.answers import Answer
from dualpilot.model.dynamics import Array, rollout
from dualpilot.model.fire import FireParams, FireSnapshot
from dualpilot.model.geometry import Polytope, path_clearance
from dualpilot.model.prism import Prism
from dualpilot.model.risk import ForecastView, RiskMap, RiskParams, path_risk_clearance
from dualpilot.model.segment3 import prism_path_clearance
from dualpilot.plan import Plan
from dualpilot.spec import MissionSpec
from dualpilot.verify import verify_trajectory

#: What a planner avoids: polygons (2-D) or the fronts' prisms (3-D).
Obstacles = tuple[Polytope, ...] | tuple[Prism, ...]


@dataclass(frozen=True)
class ConcurrentParams:
    """The concurrent supervisor's settings (lengths m, speeds m/s, times s)."""

    #: a front the flown plan did not know, within this distance of its next ``check_steps``
    #: (None: the spec's clearance, the margin System 2 keeps from the fronts it knows),
    #: hands over to System 1
    threat_margin_m: float | None = None
    #: steps of a plan verified against the current obstacles before it is (kept) flown
    check_steps: int = 10
    #: a due System 2 plan (or the flown plan's remainder) starting this close to the UAV's
    #: state is re-anchored (:func:`reanchor`)
    reanchor_tol_m: float = 2.0
    reanchor_tol_mps: float = 1.0
    #: the re-anchoring tolerances (:meth:`tolerances`): "fixed", the two above whatever
    #: flies; "tube", the larger of those and the spec's tube (``tracking_margin_m``,
    #: ``tracking_margin_mps``), the flying plant's error model (a reading of the plant,
    #: docs/plant.md; the same as "fixed" for the ideal plant, whose tube is 0)
    reanchor_tol: Literal["fixed", "tube"] = "fixed"
    #: wait for System 2 only while its wait's hazard (:func:`wait_hazard`) is below this
    max_wait_hazard: float = 0.01
    #: rate of the online update of Q (EMA weight of the newest measurement)
    q_rate: float = 0.2
    #: a switch between two safe plans must raise Σ p̄ Q by more than this
    switch_margin: float = 0.05
    #: energy scale of the energy attribute (N²): score 1 / (1 + ‖Δu‖² / scale)
    energy_scale_n2: float = 4.0
    #: what threatens a plan: fronts it did not know ("current", the rule above), or also the
    #: forecast's risk zones along it ("forecast", at ``risk.alpha``)
    threat: Literal["current", "forecast"] = "current"
    risk: RiskParams = field(default_factory=RiskParams)
    #: what flies while System 2 is unavailable (its planner port says so: gone, demoted
    #: after missed deadlines, behind a dead air–ground link): "keep" the rest of the flown
    #: plan while it is safe, System 1 asked only when it is not (the rule above); "system1":
    #: System 1 plans every step, onboard, on the fires the step has (stale ones grown), and
    #: System 2 is asked again once it is available (docs/deployment.md: the air role's)
    s2_unavailable: Literal["keep", "system1"] = "keep"

    def __post_init__(self) -> None:
        if min(self.threat_margin_m or 0.0, self.reanchor_tol_m, self.reanchor_tol_mps) < 0:
            raise ValueError("radii and tolerances must be >= 0")
        if self.check_steps < 1 or not 0 < self.q_rate <= 1 or self.energy_scale_n2 <= 0:
            raise ValueError("check_steps >= 1, 0 < q_rate <= 1 and energy_scale_n2 > 0")
        if not 0 <= self.max_wait_hazard <= 1:
            raise ValueError("max_wait_hazard must be in [0, 1]")
        if self.threat not in ("current", "forecast"):
            raise ValueError(f"threat must be 'current' or 'forecast', not {self.threat!r}")
        if self.s2_unavailable not in ("keep", "system1"):
            raise ValueError("s2_unavailable must be 'keep' or 'system1', not "
                             f"{self.s2_unavailable!r}")
        if self.reanchor_tol not in ("fixed", "tube"):
            raise ValueError(f"reanchor_tol must be 'fixed' or 'tube', not {self.reanchor_tol!r}")

    def tolerances(self, spec: MissionSpec) -> tuple[float, float]:
        """(m, m/s): how far the UAV's state may be from a plan's start, in position and in
        velocity (Euclidean), for the plan to be re-anchored (:func:`reanchor`).

        "fixed": (``reanchor_tol_m``, ``reanchor_tol_mps``), made for Eq. (1)'s vehicle,
        which flies its plan exactly. "tube": at least the spec's tube,
        (max(``reanchor_tol_m``, ``tracking_margin_m``), max(``reanchor_tol_mps``,
        ``tracking_margin_mps``)): a flying plant lags Eq. (1) by up to its tube, and a plan
        that expected it there is no more off than its own flight will be (8.58 m and
        3.686 m/s for the multirotor at ``gps_sigma_m`` = 1.5, moderate turbulence; 2 m and
        1 m/s for the ideal plant, as "fixed").
        """
        if self.reanchor_tol == "fixed":
            return self.reanchor_tol_m, self.reanchor_tol_mps
        return (max(self.reanchor_tol_m, spec.tracking_margin_m),
                max(self.reanchor_tol_mps, spec.tracking_margin_mps))


def wait_hazard(n_substeps: int, fire: FireParams, area_size_m: float, d_safe_m: float,
                speed_mps: float = 0.0, wait_s: float = 0.0) -> float:
    """P(a front ignites within reach of the UAV during a wait of ``n_substeps`` sub-steps).

    A newborn front's region (sides U[side_min, side_max]) comes within
    d_safe of the UAV when its centre lies in the square of half-side
    side_max/2 + d_safe (+ the UAV's travel during the wait) around it; with
    centres uniform over the area, the chance per sub-step is p_b times that
    square's share of the area (an upper bound), and the wait's hazard is
    1 − (1 − p)^n.
    """
    if n_substeps < 0 or not area_size_m > 0:
        raise ValueError("n_substeps >= 0 and area_size_m > 0 are required")
    half = fire.side_max_m / 2 + d_safe_m + speed_mps * wait_s
    share = min(1.0, (2 * half) ** 2 / area_size_m**2)
    return float(1.0 - (1.0 - fire.p_birth * share) ** n_substeps)


class OnlineQ:
    """Q(s, a) of Eq. (Psi), updated from measurements (rows: systems; columns: response time,
    mission progress, energy), each attribute scored in [0, 1]."""

    def __init__(self, q0: Array, params: ConcurrentParams, dt_s: float, v_max_mps: float):
        self.q = np.array(q0, dtype=float)
        self.params = params
        self.dt_s = dt_s
        self.v_max_mps = v_max_mps

    def _update(self, system: int, attribute: int, score: float) -> None:
        b = self.params.q_rate
        self.q[system - 1, attribute] = (1 - b) * self.q[system - 1, attribute] + b * score

    def response(self, system: int, response_s: float) -> None:
        """A plan of ``system`` took ``response_s`` (s): score 1 / (1 + T_s / ΔT)."""
        self._update(system, 0, 1.0 / (1.0 + response_s / self.dt_s))

    def flown(self, system: int, progress_m: float, du2_n2: float) -> None:
        """One step flown by ``system``: progress towards G (m) and ‖u_t − u_{t−1}‖² (N²).

        Progress is scored against v_max·ΔT, the most a step can make under
        ``speed_limit = "norm"`` (per axis a diagonal step can make √2 times more: score 1).
        """
        self._update(system, 1, float(np.clip(progress_m / (self.v_max_mps * self.dt_s), 0, 1)))
        self._update(system, 2, 1.0 / (1.0 + du2_n2 / self.params.energy_scale_n2))

    def utility(self, system: int, p_mean: Array) -> float:
        """Σ_a w_a Q(s, a) over mission progress and energy, w = (p̄_2, p̄_3) / (p̄_2 + p̄_3)
        for the attention's mean p̄ = Ξ / ΣΞ.

        Between two safe plans the response-time attribute does not decide: System 2's
        latency is hidden by deliberating while the UAV flies, and a front that needs a
        fast answer is the threat rule's (System 1 answers at once).
        """
        w = np.asarray(p_mean[1:], dtype=float)
        return float(self.q[system - 1, 1:] @ (w / w.sum()))


@dataclass
class Flown:
    """A plan being flown: ``offset`` steps of it are done; ``known`` the front ids it knew."""

    plan: Plan
    offset: int
    known: frozenset[int]
    view: ForecastView | None = None  # the forecast it was made on (a risk-aware plan)

    def remainder(self, state: Array) -> Plan | None:
        """The rest of the plan from ``state`` (None when it has run out)."""
        if self.offset + 1 >= len(self.plan.states):
            return None
        return replace(self.plan, states=self.plan.states[self.offset:],
                       controls=self.plan.controls[self.offset:])


@dataclass
class Deliberation:
    """A System 2 plan being computed in the background."""

    ticket: object
    due_t: int  # the step its plan is for (its first state is the predicted x̂ of that step)
    ready_s: float  # simulated time it is ready (launch + response time)
    known: frozenset[int]  # the front ids the fires it plans against had
    view: ForecastView | None = None  # the forecast it plans on (a risk-aware System 2)


@dataclass
class Choice:
    """What the concurrent supervisor decided at one step."""

    plan: Plan | None
    answers: list[Answer] = field(default_factory=list)
    wait_s: float = 0.0  # the time the UAV waited for a planner this step
    note: str = ""


def threatened(plan: Plan, seen: FireSnapshot, known: frozenset[int], margin_m: float,
               steps: int) -> bool:
    """A front not in ``known`` comes within ``margin_m`` of the next ``steps`` of ``plan``.

    ``seen`` gives the obstacles (hull, or region where the hull grew around the
    plan's start) of every front; only those the plan did not know count: the
    others it was planned to keep the clearance from.
    """
    dim = plan.states.shape[1] // 2
    pts = plan.states[: steps + 1, :dim]
    unknown = [o for o, fid in zip(seen.obstacles(pts[0], margin_m), seen.front_ids,
                                   strict=False) if fid not in known]
    if not unknown:
        return False
    if dim == 3:  # prisms: the exact 3-D distances
        return prism_path_clearance(pts, [o for o in unknown if isinstance(o, Prism)]) < margin_m
    return path_clearance(pts, [o for o in unknown if isinstance(o, Polytope)]) < margin_m


def forecast_threatened(plan: Plan, risk: RiskMap, margin_m: float, steps: int) -> bool:
    """A segment p_{τ−1}–p_τ of the next ``steps`` steps of ``plan`` comes within ``margin_m``
    of step τ's risk zones (row τ of the plan is τ steps from now); in 3-D its ground track
    against footprints, its positions against zones with heights."""
    dim = plan.states.shape[1] // 2
    return path_risk_clearance(risk, plan.states[: steps + 1, :dim]) < margin_m


def check_near(plan: Plan, state: Array, obstacles: Obstacles, spec: MissionSpec,
               steps: int) -> str:
    """"" when ``plan`` starts at ``state`` and its next ``steps`` steps verify (in 3-D against
    prisms and within the band); else why not."""
    if not plan.ok or len(plan.states) < 2:
        return "no plan"
    if not np.allclose(plan.states[0], state, atol=1e-6):
        return "does not start at the UAV's state"
    k = min(steps, len(plan.controls))
    verdict = verify_trajectory(plan.states[: k + 1], plan.controls[:k], obstacles,
                                spec.dynamics, spec.d_safe_m,
                                band=spec.band if spec.dim == 3 else None)
    return "" if verdict.ok else verdict.reason


def reanchor(plan: Plan, state: Array, params: ConcurrentParams,
             spec: MissionSpec) -> Plan | None:
    """``plan`` moved to start at ``state`` (its controls rolled out again by Eq. 1), or None
    when ``state`` is farther than the re-anchoring tolerances
    (:meth:`ConcurrentParams.tolerances`) from the plan's start.

    The tolerances decide which plans are worth re-checking, never whether one is safe:
    every re-anchored plan is verified before it flies, twice. The supervisor flies it only
    if :func:`check_near` passes (its next ``check_steps`` steps of Eq. (1) and the limits,
    every segment keeping ``spec.d_safe_m``, the paper's d_safe plus the tube, from the
    current obstacles, in 3-D within the band), and the run-time monitor then checks the
    same steps again (:func:`dualpilot.mission.monitor.check_plan`: it starts at the measured
    state, follows Eq. (1), keeps the limits, the area and d_safe with the tube).
    """
    n = spec.dynamics.dim
    tol_m, tol_mps = params.tolerances(spec)
    d = np.asarray(state, dtype=float) - plan.states[0]
    if np.linalg.norm(d[:n]) > tol_m or np.linalg.norm(d[n:]) > tol_mps:
        return None
    if not np.any(d):
        return plan
    return replace(plan, states=rollout(np.asarray(state, dtype=float), plan.controls,
                                        spec.dynamics))


def steps_until(response_s: float, step_s: float) -> int:
    """Steps after which a plan launched now with response time ``response_s`` is ready."""
    return max(1, ceil(response_s / step_s - 1e-9))


__all__ = ["Choice", "ConcurrentParams", "Deliberation", "Flown", "Obstacles", "OnlineQ",
           "check_near",
           "forecast_threatened", "reanchor", "threatened", "steps_until", "wait_hazard"]

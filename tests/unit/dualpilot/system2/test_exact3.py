"""System 2's exact (P2) in 3-D, as the paper writes it (docs/three_d.md, 6. System 2, Exact).

Each cuboid is its six faces (α_l, β_l) with Σ_{l=1..6} b ≤ 5, Eq. (1) has 3×3 blocks and
the band bounds every planned altitude. Short horizons (T = 20) and one or two cuboids keep
SCIP fast. The values the plans are held to are worked out apart from the MIQP: convex QPs
of Eq. (1) written here and solved by Clarabel (no obstacle, or "always above the top"), and
the 2-D exact optimum on the cuboids' rectangles.
"""

from __future__ import annotations

import dataclasses

import cvxpy as cp
import numpy as np
import pytest

from dualpilot.mission.monitor import check
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.dynamics import DynamicsParams, rollout, transition_matrices
from dualpilot.model.geometry import Rect
from dualpilot.model.prism import Prism
from dualpilot.plan import Objective, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.system2.exact import ExactSystem2
from dualpilot.system2.problem import System2Params, verify_p2_plan

T = 20
DYN3 = DynamicsParams(dim=3)
SPEC3 = MissionSpec(dynamics=DYN3)
SPEC2 = MissionSpec()
EPS = SPEC3.clearance_m  # 25 m
BAND = SPEC3.band  # [20, 120] m, start and G_o at 50 m
#: a 100 m square on the diagonal from (100, 100) to the goal (900, 900): the straight line
#: crosses it
RECT = Rect(260.0, 260.0, 100.0, 100.0)
X0 = np.array([100.0, 100.0, 50.0, 0.0, 0.0, 0.0])


def params(**kw: object) -> System2Params:
    base: dict[str, object] = {"horizon": T, "max_hulls": 2, "max_faces": 4,
                               "time_limit_s": 60.0}
    base.update(kw)
    return System2Params(**base)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def planner() -> ExactSystem2:
    return ExactSystem2(SPEC3, params())


@pytest.fixture(scope="module")
def planner2() -> ExactSystem2:
    return ExactSystem2(SPEC2, params())


def cuboid(top: float, rect: Rect = RECT) -> Prism:
    return Prism.cuboid(rect, 0.0, top)


def qp_solution(x0: np.ndarray, objective: Objective, z_min: float | None = None,
                from_step: int = 1) -> tuple[float, np.ndarray]:
    """(P2) without obstacles as a convex QP in 3-D (Clarabel): the area and the band as
    bounds, ``z_min`` a floor on the altitudes of p_τ for τ ≥ ``from_step``; its optimum
    and planned positions (T, 3)."""
    phi, gamma = transition_matrices(DYN3)
    k1, k2 = System2Params().kappa(objective)
    x = cp.Variable((T + 1, 6))
    u = cp.Variable((T, 3))
    cons = [x[0] == x0, cp.abs(u) <= DYN3.u_max_n, cp.abs(x[1:, 3:]) <= DYN3.v_max_mps,
            x[1:, :2] >= 0.0, x[1:, :2] <= SPEC3.area_size_m,
            x[1:, 2] >= BAND.floor_m, x[1:, 2] <= BAND.ceiling_m]
    if z_min is not None:
        cons.append(x[from_step:, 2] >= z_min)
    cons += [x[k + 1] == phi @ x[k] + gamma @ u[k] for k in range(T)]
    goal = np.array([900.0, 900.0, 50.0])
    du = cp.vstack([u[0], u[1:] - u[:-1]])
    obj = k1 * cp.sum_squares(x[1:, :3] - np.ones((T, 1)) @ goal[None, :])
    prob = cp.Problem(cp.Minimize(obj + k2 * cp.sum_squares(du)), cons)
    prob.solve(solver=cp.CLARABEL)
    assert prob.status == cp.OPTIMAL
    return float(prob.value), np.asarray(x.value)[1:, :3]


def qp_value(x0: np.ndarray, objective: Objective) -> float:
    return qp_solution(x0, objective)[0]


def over_footprint(states: np.ndarray, rect: Rect, grow: float) -> np.ndarray:
    """Which planned positions lie over ``rect`` grown by ``grow`` (m)."""
    x0, y0, x1, y1 = rect.bounds
    p = states[1:, :2]
    return ((p[:, 0] >= x0 - grow) & (p[:, 0] <= x1 + grow)
            & (p[:, 1] >= y0 - grow) & (p[:, 1] <= y1 + grow))


def assert_checked(plan, x0: np.ndarray, hulls: tuple[Prism, ...], spec: MissionSpec) -> None:
    """Eq. (1) in 3-D, U and X, the band, the independent check of every fast 3-D plan and
    the run-time monitor."""
    assert plan.states.shape == (T + 1, 6) and plan.controls.shape == (T, 3)
    assert np.allclose(plan.states, rollout(x0, plan.controls, spec.dynamics), atol=1e-9)
    assert np.all(np.abs(plan.controls) <= DYN3.u_max_n + 1e-9)
    z = plan.states[1:, 2]
    assert np.all(z >= spec.band.floor_m - 1e-6) and np.all(z <= spec.band.ceiling_m + 1e-6)
    verdict = verify_p2_plan(plan.states, plan.controls, hulls, spec.dynamics, EPS,
                             spec.d_safe_m, spec.area_size_m, tol=0.1, rolled_out=True,
                             band=spec.band)
    assert verdict.ok, verdict.reason
    assert check(plan, x0, hulls, spec).ok


@pytest.mark.parametrize("objective", list(Objective))
def test_a_cuboid_below_the_flight_is_no_obstacle(planner: ExactSystem2,
                                                  objective: Objective) -> None:
    """Top 20 m: top + ε = 45 m < 50 m, and 30 m ≥ d_safe above it: the free optimum."""
    low = cuboid(20.0)
    plan = planner.plan(X0, (low,), objective)
    assert plan.ok and plan.info["optimal"] is True, plan.message
    assert plan.cost == pytest.approx(qp_value(X0, objective), rel=1e-5)
    assert np.any(over_footprint(plan.states, RECT, 0.0))  # it flies straight over it
    assert_checked(plan, X0, (low,), SPEC3)


def test_a_low_cuboid_in_the_way_is_passed_over(planner: ExactSystem2) -> None:
    """Top 30 m: over it the plan keeps z ≥ 55 m (the top face with ε); a 5 m climb costs
    less than the way around, which the same cuboid taller than the ceiling forces."""
    low, tall = cuboid(30.0), cuboid(SPEC3.above_ceiling_m)
    over = planner.plan(X0, (low,))
    around = planner.plan(X0, (tall,))
    assert over.ok and around.ok and over.info["optimal"] and around.info["optimal"]
    assert over.cost is not None and around.cost is not None
    assert_checked(over, X0, (low,), SPEC3)
    assert_checked(around, X0, (tall,), SPEC3)
    inside = over_footprint(over.states, RECT, 0.0)
    assert np.any(inside)
    assert np.all(over.states[1:][inside, 2] >= 30.0 + EPS - 0.1)
    # between the free optimum and "above 55 m from the 4th step on", a plan that keeps
    # ε from one of the six faces at every τ: a feasible point of (P2)
    assert qp_value(X0, Objective.MISSION_TIME) < over.cost
    value, pos = qp_solution(X0, Objective.MISSION_TIME, z_min=30.0 + EPS, from_step=4)
    assert np.all(low.margins(pos) >= EPS - 1e-6)
    assert over.cost <= value * (1 + 1e-6)
    assert over.cost < around.cost
    assert not np.any(over_footprint(around.states, RECT, EPS - 0.1))  # around: outside
    assert np.allclose(around.states[:, 2], 50.0, atol=1e-6)  # at G_o's altitude


def test_a_ceiling_below_the_over_level_forces_the_way_around() -> None:
    """The same 30 m cuboid under a 54 m ceiling: z ≥ 55 m is out of the band, so the plan
    goes around, as with the cuboid taller than the ceiling."""
    spec = dataclasses.replace(SPEC3, band=AltitudeBand(ceiling_m=54.0))
    plan = ExactSystem2(spec, params()).plan(X0, (cuboid(30.0),))
    assert plan.ok and plan.info["optimal"], plan.message
    assert_checked(plan, X0, (cuboid(30.0),), spec)
    assert np.all(plan.states[1:, 2] <= 54.0 + 1e-6)
    assert not np.any(over_footprint(plan.states, RECT, EPS - 0.1))


@pytest.mark.parametrize("objective", list(Objective))
def test_cuboids_taller_than_the_ceiling_give_the_2d_optimum(
        planner: ExactSystem2, planner2: ExactSystem2, objective: Objective) -> None:
    """The top-down evaluation: the 3-D optimum's cost is the 2-D optimum's on the
    rectangles, to the solver's tolerance, and the altitude stays at G_o's."""
    rects = (RECT, Rect(420.0, 180.0, 80.0, 120.0))
    top = SPEC3.above_ceiling_m
    x0 = np.array([100.0, 100.0, 50.0, 4.0, -2.0, 0.0])
    u_prev = np.array([1.0, -0.5, 0.0])
    plan = planner.plan(x0, tuple(cuboid(top, r) for r in rects), objective, u_prev)
    flat = planner2.plan(x0[[0, 1, 3, 4]], tuple(r.polytope() for r in rects), objective,
                         u_prev[:2])
    assert plan.ok and flat.ok and plan.info["optimal"] and flat.info["optimal"]
    assert plan.cost == pytest.approx(flat.cost, rel=1e-5)
    assert np.allclose(plan.states[:, 2], 50.0, atol=1e-6)
    assert np.allclose(plan.states[:, 5], 0.0, atol=1e-6)
    assert_checked(plan, x0, tuple(cuboid(top, r) for r in rects), SPEC3)


def test_six_faces_and_at_most_five_binaries(planner: ExactSystem2) -> None:
    """Each slot holds the six faces of a cuboid (α_l, β_l) and, at every τ, Σ_l b ≤ 5 and a
    face with b = 0 keeps ε (Eq. (P2_3)-(P2_4)); an empty slot constrains nothing
    (α = 0, β = −M)."""
    low = cuboid(30.0)
    plan = planner.plan(X0, (low,))
    assert plan.ok
    model = planner.model
    assert model.slot_faces == 6 and model.B.shape == (12, T)
    alpha, beta = model.values()["alpha"], model.values()["beta"][:, 0]
    assert np.array_equal(alpha[:6], low.A) and np.array_equal(beta[:6], low.b)
    assert low.A.tolist()[4:] == [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]  # top, bottom
    assert model.B.value is not None and model.X.value is not None
    b = np.round(model.B.value)
    assert np.all(b[:6].sum(axis=0) <= 5) and np.any(b[:6].sum(axis=0) == 4)
    assert np.all(alpha[6:] == 0.0) and np.all(beta[6:] == -planner.params.big_m)
    pos = model.X.value[:, :3]
    margins = pos @ low.A.T - low.b  # (T, 6)
    assert np.all(np.max(np.where(b[:6].T == 0, margins, -np.inf), axis=1) >= EPS - 0.1)


def test_a_first_step_out_of_the_band_is_infeasible_before_solving(
        planner: ExactSystem2) -> None:
    plan = planner.plan(np.array([100.0, 100.0, 25.0, 0.0, 0.0, -8.0]), ())
    assert plan.status is PlanStatus.INFEASIBLE and "band" in plan.message
    assert "solver" not in plan.info and plan.states.shape == (0, 6)


def test_invalid_requests_and_the_norm_limit(planner: ExactSystem2) -> None:
    assert planner.plan(np.zeros(4), ()).status is PlanStatus.INVALID_INPUT
    flat = planner.plan(X0, (RECT.polytope(),))
    assert flat.status is PlanStatus.INVALID_INPUT and "Prism" in flat.message
    near = planner.plan(np.array([260.0, 260.0, 40.0, 0, 0, 0]), (cuboid(30.0),))
    assert near.status is PlanStatus.INVALID_INPUT and "d_safe" in near.message
    with pytest.raises(ValueError, match="3-D under speed_limit = 'axis' only"):
        ExactSystem2(MissionSpec(dynamics=DynamicsParams(dim=3, speed_limit="norm")), params())


# -- missions -------------------------------------------------------------------------------------
class _Checked(ExactSystem2):
    """The exact method whose every OK plan is checked again, independently, against what it
    was given: the fast 3-D plans' check (with the band) and the run-time monitor."""

    def __init__(self, spec: MissionSpec, params: System2Params) -> None:
        super().__init__(spec, params)
        self.ok = 0
        self.climbs = 0
        self.timeouts = 0
        self.refused: list[str] = []

    def plan(self, state, hulls, objective=Objective.MISSION_TIME,  # type: ignore[no-untyped-def]
             prev_control=None):
        plan = super().plan(state, hulls, objective, prev_control)
        self.timeouts += plan.status is PlanStatus.TIMEOUT
        if plan.ok:
            self.ok += 1
            self.climbs += float(plan.states[:, 2].max()) > float(state[2]) + 1.0
            spec = self.spec
            v = verify_p2_plan(plan.states, plan.controls, hulls, spec.dynamics, EPS,
                               spec.d_safe_m, spec.area_size_m, tol=0.1, band=spec.band)
            m = check(plan, state, hulls, spec)
            if not (v.ok and m.ok):
                self.refused.append(f"{v.reason}; {m.reason}")
        return plan


def test_the_exact_method_is_a_3d_method_of_s2_and_cc() -> None:
    from dualpilot.mission.config import MissionConfig
    from dualpilot.mission.dimension import refusals
    from dualpilot.planners import planner_method

    assert planner_method("exact").dims == frozenset({2, 3})
    for name in ("s2", "cc"):
        config = MissionConfig.named(name, profile="today-3d", system2_method="exact")
        assert refusals(config) == ()


@pytest.mark.slow
def test_a_3d_exact_mission_over_low_fires_climbs_and_every_plan_passes_the_check() -> None:
    """s2 with the exact method on the paper's process, fronts 5-40 m tall (seed 7: five
    plans climb over one), T = 30 (SCIP solves each plan in under 1.5 s, far within its
    limit, so the mission does not depend on the machine's speed)."""
    from dualpilot.mission.config import MissionConfig
    from dualpilot.mission.local import local_mission
    from dualpilot.mission.params import Timing

    config = MissionConfig.named(
        "s2", seed=7, timing=Timing.PAPER, profile="today-3d", system2_method="exact",
        system2_time_limit_s=20.0,
        settings={"fire_height": "uniform", "fire_height_min_m": 5.0,
                  "fire_height_max_m": 40.0, "max_steps": 30})
    planner = _Checked(config.spec(), dataclasses.replace(config.system2_params(), horizon=30))
    result = local_mission(config, {2: planner}).run()
    assert result.ending is not None and planner.ok > 20 and planner.timeouts == 0
    assert planner.refused == []
    assert planner.climbs >= 3
    assert max(float(r.state[2]) for r in result.records) > 51.0  # and the UAV flies up

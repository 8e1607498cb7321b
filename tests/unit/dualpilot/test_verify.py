"""Every verifier reads d_safe from the MissionSpec: a plan 30 m from a hull passes at d_safe = 20 m
and is refused by each check once the spec's d_safe is 31 m."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.model.dynamics import rollout
from dualpilot.model.geometry import Rect, SegmentChecker
from dualpilot.plan import Objective, PlanStatus
from dualpilot.spec import MissionSpec
from dualpilot.system1.planner import System1
from dualpilot.system2.exact import ExactSystem2
from dualpilot.system2.fast.cfs import Candidate
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import System2Params, p2_cost, verify_p2_plan
from dualpilot.verify import verify_trajectory

SQUARE = Rect(50.0, 50.0, 100.0, 100.0).polytope()  # [0, 100]²
HULLS = (SQUARE,)
PAPER = MissionSpec()  # d_safe = 20 m, ε = clearance = 25 m
STRICT = MissionSpec(d_safe_m=31.0, clearance_m=31.0)
T = 5


def _plan() -> tuple[np.ndarray, np.ndarray]:
    """From (140, 50) at (−8, 0) m/s to a hover at (130, 50), by hand with Eq. (1).

    p1 = 140 − 8 = 132. u0 = m(v1 − (1 − ζ)v0)/ΔT = 1.05·(−2 + 6.4) = 4.62 N gives v1 = −2,
    so p2 = 130; u1 = 1.05·(0 + 1.6) = 1.68 N gives v2 = 0 and the UAV stays at (130, 50).
    Every position lies on y = 50 with x ∈ [130, 140]: the polyline is 30 m from the face
    x = 100 (and max_l α·p − β = 30 m, so the ε-disjunction holds for ε ≤ 30 m).
    """
    x0 = np.array([140.0, 50.0, -8.0, 0.0])
    controls = np.zeros((T, 2))
    controls[0, 0], controls[1, 0] = 4.62, 1.68
    states = rollout(x0, controls, PAPER.dynamics)
    np.testing.assert_allclose(states[2:, :2], np.tile([130.0, 50.0], (T - 1, 1)), atol=1e-9)
    return states, controls


def test_the_plan_is_thirty_metres_from_the_hull() -> None:
    states, _ = _plan()
    assert SegmentChecker(HULLS).path_clearance(states[:, :2]) == pytest.approx(30.0, abs=1e-9)


@pytest.mark.parametrize("spec, ok", [(PAPER, True), (STRICT, False)])
def test_verify_trajectory_follows_d_safe(spec: MissionSpec, ok: bool) -> None:
    states, controls = _plan()
    verdict = verify_trajectory(states, controls, HULLS, spec.dynamics, spec.d_safe_m)
    assert verdict.ok is ok
    if not ok:
        assert "clearance 30.00 m < 31.0 m" in verdict.reason


@pytest.mark.parametrize("spec, ok", [(PAPER, True), (STRICT, False)])
def test_fast_system2_check_follows_d_safe(spec: MissionSpec, ok: bool) -> None:
    states, controls = _plan()
    planner = FastSystem2(spec, System2Params(horizon=T))
    kappa = planner.params.kappa(Objective.MISSION_TIME)
    cand = Candidate("hand", states[1:, :2], controls, 0.0, 0)
    reasons: list[str] = []
    plan = planner._finish(cand, states[0], HULLS, Objective.MISSION_TIME, kappa, np.zeros(2),
                           0.0, {}, reasons)
    assert (plan is not None) is ok
    if not ok:
        assert "clearance 30.00 m < 31.0 m" in reasons[0]
    # the same check as a function, as the seeded SCIP path calls it
    verdict = verify_p2_plan(states, controls, HULLS, spec.dynamics, spec.clearance_m,
                             spec.d_safe_m, spec.area_size_m)
    assert verdict.ok is ok


@pytest.mark.parametrize("spec, ok", [(PAPER, True), (STRICT, False)])
def test_exact_system2_check_follows_d_safe(spec: MissionSpec, ok: bool,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """The solver is replaced by the hand plan: what is left is the exact path's own check."""
    states, controls = _plan()
    planner = ExactSystem2(spec, System2Params(horizon=T, max_hulls=1, max_faces=4))
    monkeypatch.setattr(planner, "_solve", lambda: {"solver_status": "optimal", "U": controls,
                                                    "X": states[1:]})
    plan = planner.plan(states[0], HULLS)
    if ok:
        assert plan.ok, plan.message
        kappa = planner.params.kappa(Objective.MISSION_TIME)
        assert plan.cost == pytest.approx(p2_cost(states, controls, spec.goal.center, kappa))
    else:
        assert plan.status is PlanStatus.UNSAFE
        assert "clearance 30.00 m < 31.0 m" in plan.message


@pytest.mark.parametrize("spec, ok", [(PAPER, True), (STRICT, False)])
def test_system1_check_follows_d_safe(spec: MissionSpec, ok: bool) -> None:
    """System 1's tracking check on the reference (140, 50) → (130, 50) at 30 m from the face."""
    planner = System1(spec)
    x0 = np.array([140.0, 50.0, 0.0, 0.0])
    ref = np.array([[140.0, 50.0], [130.0, 50.0]])
    attempts: list[str] = []
    out = planner._track(x0, ref, HULLS, attempts, "operator", SegmentChecker(HULLS))
    assert (out is not None) is ok
    if ok:
        assert out is not None and 20.0 <= out[3] <= 30.0 + 1e-6
    else:
        assert attempts and all("< 31.0 m" in a for a in attempts)


def test_rolled_out_skips_only_the_dynamics_check() -> None:
    """States made by rollout verify alike either way; ``rolled_out`` only trusts Eq. (1),
    so states that break it pass that one check and nothing else."""
    states, controls = _plan()
    rolled = rollout(states[0], controls, PAPER.dynamics)
    args = (HULLS, PAPER.dynamics, PAPER.clearance_m, PAPER.d_safe_m, PAPER.area_size_m)
    assert verify_p2_plan(rolled, controls, *args) == verify_p2_plan(rolled, controls, *args,
                                                                     rolled_out=True)
    bent = rolled.copy()
    bent[3:, 0] += 2.0  # 2 m off Eq. (1) from the third step on
    assert "Eq. (1)" in verify_p2_plan(bent, controls, *args).reason
    assert verify_p2_plan(bent, controls, *args, rolled_out=True).ok
    fast = rolled.copy()
    fast[1:, 2] = 40.0  # 40 m/s: the limits are still checked
    assert not verify_trajectory(fast, controls, HULLS, PAPER.dynamics, PAPER.d_safe_m,
                                 rolled_out=True).ok

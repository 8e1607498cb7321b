"""System 1 (dualpilot.system1.planner): operator waypoints or RRT, LQR tracking, verification."""

from __future__ import annotations

import numpy as np
import pytest

import dualpilot.system1.planner as s1mod
from dualpilot.model.dynamics import DynamicsParams, hover_state, step
from dualpilot.model.geometry import Polytope, Rect, path_clearance
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.planners import BUILTIN, build_planner, method_names, risk_aware_names
from dualpilot.spec import MissionSpec
from dualpilot.system1.lqr import R_DELTA_U, lqr_gain, reference_states, track
from dualpilot.system1.planner import System1, System1Params
from dualpilot.verify import Verdict, verify_trajectory

SPEC = MissionSpec()
GOAL = SPEC.goal
DYN = DynamicsParams()
BLOCK = Rect(650.0, 650.0, 200.0, 200.0).polytope()  # on the diagonal to G


def planner(seed: int = 0, **kw: object) -> System1:
    return System1(SPEC, System1Params(**kw), np.random.default_rng(seed))  # type: ignore[arg-type]


def iterations(plan: Plan) -> int:
    n = plan.info["rrt_iterations"]
    assert isinstance(n, int)
    return n


def assert_valid(plan: Plan, hulls: tuple[Polytope, ...], horizon: int = 80) -> None:
    assert plan.ok, plan.message
    assert plan.system == 1
    assert plan.states.shape == (horizon + 1, 4) and plan.controls.shape == (horizon, 2)
    assert verify_trajectory(plan.states, plan.controls, hulls, DYN, clearance_m=20.0).ok
    assert plan.path is not None and plan.compute_time_s > 0


def test_open_space_plan_reaches_the_goal_and_stops_there() -> None:
    x = hover_state(np.array([400.0, 400.0]))
    plan = planner().plan(x, ())
    assert_valid(plan, ())
    assert plan.path is not None
    np.testing.assert_array_equal(plan.path, [[400.0, 400.0], GOAL.center])
    np.testing.assert_array_equal(plan.states[0], x)
    assert GOAL.contains(plan.states[-1, :2])
    np.testing.assert_allclose(plan.states[-1], [900.0, 900.0, 0.0, 0.0], atol=1e-3)
    assert plan.info["source"] == "rrt" and plan.info["ref_speed_mps"] == 12.0


def test_rrt_plan_avoids_a_hull() -> None:
    hulls = (BLOCK,)
    plan = planner(seed=5).plan(hover_state(np.array([50.0, 50.0])), hulls)
    assert_valid(plan, hulls)
    assert plan.info["source"] == "rrt" and iterations(plan) > 0
    assert plan.path is not None
    assert path_clearance(plan.path, hulls) >= 25.0 - 1e-9
    assert GOAL.contains(plan.path[-1])


def test_same_seed_gives_the_same_plan() -> None:
    x = hover_state(np.array([50.0, 50.0]))
    a = planner(seed=9).plan(x, (BLOCK,))
    b = planner(seed=9).plan(x, (BLOCK,))
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.path, b.path)


def test_operator_waypoints_are_used_when_safe() -> None:
    s1 = planner()
    wps = np.array([[800.0, 500.0], [880.0, 880.0]])  # around BLOCK's lower right corner
    s1.set_waypoints(wps)
    x = hover_state(np.array([300.0, 300.0]))
    plan = s1.plan(x, (BLOCK,))
    assert_valid(plan, (BLOCK,))
    assert plan.info["source"] == "operator"
    np.testing.assert_array_equal(plan.path, np.vstack([x[:2], wps]))
    # as the UAV flies, passed waypoints drop out of the reference
    for _ in range(55):  # ~540 m to the first waypoint at up to 12 m/s
        x = step(x, plan.controls[0], DYN)
        plan = s1.plan(x, (BLOCK,))
    assert plan.ok and plan.info["source"] == "operator"
    assert plan.path is not None
    np.testing.assert_array_equal(plan.path[-1], wps[-1])
    assert len(plan.path) <= 3 and not np.any(np.all(plan.path == wps[0], axis=1))


def test_unsafe_operator_waypoints_are_replaced_by_the_rrt() -> None:
    s1 = planner(seed=2)
    s1.set_waypoints(np.array([[650.0, 650.0], [900.0, 900.0]]))  # straight through BLOCK
    plan = s1.plan(hover_state(np.array([300.0, 300.0])), (BLOCK,))
    assert_valid(plan, (BLOCK,))
    assert plan.info["source"] == "rrt" and "operator_rejected" in plan.info
    assert plan.path is not None and path_clearance(plan.path, (BLOCK,)) >= 25.0 - 1e-9


def test_a_waypoint_segment_that_clips_a_corner_is_rejected() -> None:
    # Every waypoint and every 10 m sample keeps 25 m from the tip, the segment does not.
    tip = np.array([500.0, 524.0])
    needle = Polytope.from_vertices(np.array([tip, tip + [-40.0, 300.0], tip + [40.0, 300.0]]))
    pts = np.linspace([300.0, 500.0], [700.0, 500.0], 41)
    assert min(needle.distance(p) for p in pts if abs(p[0] - 500.0) > 5) > 25.0
    s1 = planner(seed=1)
    s1.set_waypoints(np.array([[700.0, 500.0], [880.0, 880.0]]))
    plan = s1.plan(hover_state(np.array([300.0, 500.0])), (needle,))
    assert plan.ok and plan.info["source"] == "rrt" and "operator_rejected" in plan.info


def test_the_previous_rrt_path_is_reused_while_free() -> None:
    s1 = planner(seed=3)
    x = hover_state(np.array([50.0, 50.0]))
    first = s1.plan(x, (BLOCK,))
    assert first.ok and iterations(first) > 0
    x = step(x, first.controls[0], DYN)
    again = s1.plan(x, (BLOCK,))
    assert again.ok and again.info["reused"] is True and again.info["rrt_iterations"] == 0
    assert first.path is not None and again.path is not None
    np.testing.assert_array_equal(again.path[-1], first.path[-1])
    fresh = planner(seed=3, reuse_path=False)
    fresh.plan(hover_state(np.array([50.0, 50.0])), (BLOCK,))
    assert fresh.plan(x, (BLOCK,)).info["reused"] is False
    # a new hull across the stored path forces a fresh RRT
    mid = (first.path[1] + first.path[0]) / 2
    blocker = Rect(float(mid[0]), float(mid[1]), 60.0, 60.0).polytope()
    replanned = s1.plan(x, (BLOCK, blocker))
    assert replanned.ok and replanned.info["reused"] is False


def test_no_path_is_a_status_not_an_exception() -> None:
    covering = Rect(900.0, 900.0, 200.0, 200.0).polytope()
    plan = planner(max_iterations=200).plan(hover_state(np.array([50.0, 50.0])), (covering,))
    assert plan.status is PlanStatus.NO_PATH and not plan.ok
    assert plan.states.shape == (0, 4) and plan.controls.shape == (0, 2)
    assert plan.info["rrt_status"] == "unreachable" and plan.info["rrt_iterations"] == 0
    assert plan.compute_time_s > 0
    capped = planner(max_iterations=200, reach_check=False).plan(
        hover_state(np.array([50.0, 50.0])), (covering,))
    assert capped.status is PlanStatus.NO_PATH and capped.info["rrt_iterations"] == 200


def test_an_unverified_trajectory_is_never_ok(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(s1mod, "verify_trajectory",
                        lambda *a, **k: Verdict(False, "forced failure", 0.0))
    plan = planner().plan(hover_state(np.array([400.0, 400.0])), ())
    assert plan.status is PlanStatus.UNSAFE and plan.states.shape == (0, 4)
    attempts = plan.info["attempts"]
    assert isinstance(attempts, list) and len(attempts) == 3  # 12, 6 and 3 m/s
    assert "forced failure" in plan.message


def test_a_failed_verification_is_retried_slower(monkeypatch: pytest.MonkeyPatch) -> None:
    def fussy(states: np.ndarray, controls: np.ndarray, *a: object, **k: object) -> Verdict:
        fast = np.max(np.linalg.norm(states[:, 2:], axis=1)) > 7.0
        return Verdict(not fast, "too fast" if fast else "ok", 99.0)

    monkeypatch.setattr(s1mod, "verify_trajectory", fussy)
    plan = planner().plan(hover_state(np.array([400.0, 400.0])), ())
    assert plan.ok and plan.info["ref_speed_mps"] == 6.0


def test_escape_from_within_the_clearance() -> None:
    hull = Rect(400.0, 500.0, 100.0, 100.0).polytope()  # bottom face at y = 450
    x = hover_state(np.array([400.0, 428.0]))  # 22 m away: inside 25 m, outside d_safe
    plan = planner().plan(x, (hull,))
    assert_valid(plan, (hull,))


def test_bad_input_raises() -> None:
    s1 = planner()
    with pytest.raises(ValueError, match="finite"):
        s1.plan(np.array([np.nan, 50.0, 0.0, 0.0]), ())
    with pytest.raises(ValueError, match="shape"):
        s1.plan(np.array([50.0, 50.0]), ())
    with pytest.raises(ValueError, match="fire hull"):
        s1.plan(hover_state(np.array([650.0, 650.0])), (BLOCK,))
    with pytest.raises(ValueError, match="fire hull"):
        s1.plan(hover_state(np.array([650.0, 535.0])), (BLOCK,))  # 15 m from it
    with pytest.raises(ValueError, match="outside"):
        s1.plan(hover_state(np.array([1200.0, 50.0])), ())
    with pytest.raises(ValueError, match="goal .* outside"):
        System1(MissionSpec(goal=Rect(980.0, 900.0, 100.0, 100.0)))
    with pytest.raises(ValueError, match="shape"):
        s1.set_waypoints(np.empty((0, 2)))
    with pytest.raises(ValueError, match="finite"):
        s1.set_waypoints(np.array([[100.0, np.inf]]))
    with pytest.raises(ValueError, match="inside the"):
        s1.set_waypoints(np.array([[100.0, 100.0], [1500.0, 100.0]]))
    with pytest.raises(ValueError, match="horizon"):
        System1Params(horizon=0)
    s1.set_waypoints(np.array([[100.0, 100.0]]))
    s1.set_waypoints(None)
    assert s1.waypoints is None


def test_short_horizon_and_objective_are_accepted() -> None:
    plan = planner(horizon=1).plan(hover_state(np.array([400.0, 400.0])), (), Objective.ENERGY,
                                   np.zeros(2))
    assert_valid(plan, (), horizon=1)


# -- the tracker option: "lqr" (the paper's, default) and "lqr_du" ------------------------

#: Plans of the default System 1 computed with the code before ``tracker`` existed
#: (commit 75c173e): (seed, state, hulls, prev_control) -> controls[0], controls[7],
#: states[40], states[80] and the path.
BEFORE = {
    "open": (0, [400.0, 400.0, 0.0, 0.0], (), None,
             [2.227386360737643, 2.227386360737643], [1.7819090885901019, 1.7819090885901019],
             [718.1980515339463, 718.1980515339463, 8.485281374238525, 8.485281374238525],
             [900.0, 900.0, -2.332202897839776e-20, -2.332202897839776e-20],
             [[400.0, 400.0], [900.0, 900.0]]),
    "block": (5, [50.0, 50.0, 0.0, 0.0], (BLOCK,), None,
              [1.743963830528065, 2.623183210873742], [1.3951710644224398, 2.098546568698993],
              [299.1376900754383, 424.7404586962487, 6.643671735345038, 9.993078898566637],
              [586.494204699958, 796.1533458519983, 11.39132231834867, 3.773297740636167],
              [[50.0, 50.0], [534.6448890275485, 778.9786140506608], [900.0, 900.0]]),
    "moving": (3, [300.0, 200.0, 10.0, 0.0], (BLOCK,), [3.0, 0.0],
               [-7.5, 7.5], [0.9243297739730033, 2.345328243856448],
               [467.22393664937886, 632.6217765148974, 4.326470996856357, 11.192928513725064],
               [770.5213966324458, 896.2073173635129, 11.994855327526102, 0.3513527569298805],
               [[300.0, 200.0], [566.8026796819227, 890.2399953957623], [900.0, 900.0]]),
}


def plain_track(plan: Plan, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The plan's path re-tracked by the paper's LQR directly (as System1._track does)."""
    assert plan.path is not None
    ref = plan.path
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ref, axis=0), axis=1))])
    s_ahead = min(float(cum[-1]), 15.0)
    ahead = np.array([np.interp(s_ahead, cum, ref[:, d]) for d in range(2)])
    direction = ahead - ref[0]
    v0 = float(x[2:] @ direction / float(np.hypot(*direction)))
    speed = plan.info["ref_speed_mps"]
    assert isinstance(speed, float)
    reference = reference_states(ref, 80, speed, DYN, v0)
    return track(x, reference, lqr_gain(DYN)[0], DYN)


@pytest.mark.parametrize("case", sorted(BEFORE))
def test_the_default_tracker_gives_the_plans_of_before(case: str) -> None:
    seed, x0, hulls, u_prev, c0, c7, s40, s80, path = BEFORE[case]
    x = np.array(x0)
    u = None if u_prev is None else np.array(u_prev)
    assert System1Params().tracker == "lqr"
    plan = planner(seed=seed).plan(x, hulls, prev_control=u)
    assert_valid(plan, hulls)
    np.testing.assert_array_equal(plan.path, path)
    np.testing.assert_allclose(plan.controls[0], c0, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(plan.controls[7], c7, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(plan.states[40], s40, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(plan.states[80], s80, rtol=1e-12, atol=1e-15)
    states, controls = plain_track(plan, x)
    np.testing.assert_array_equal(plan.states, states)
    np.testing.assert_array_equal(plan.controls, controls)
    # the paper's tracker ignores u_{t|t}: any prev_control, the same plan, bit for bit
    other = planner(seed=seed).plan(x, hulls, prev_control=np.array([-7.5, 6.0]))
    np.testing.assert_array_equal(other.states, plan.states)
    np.testing.assert_array_equal(other.controls, plan.controls)


def test_lqr_du_hands_over_from_the_control_last_applied() -> None:
    """East at 10 m/s, u_{t|t} = (+3, 0) N, the operator's path north (see test_lqr).

    Bound (lqr._track_du, e_p,0 = 0, u_{t|t} feasible): ‖u_0 − u_{t|t}‖ ≤
    k_v‖e_v,0‖ + k_u‖u_{t|t} − u_ff,0‖ = 0.2917·10 + 0.5942·‖(3, −3.15)‖ = 5.50 N;
    the paper's tracker jumps by 10.96 N.
    """
    x = np.array([500.0, 300.0, 10.0, 0.0])
    u_prev = np.array([3.0, 0.0])
    wall = Rect(380.0, 500.0, 100.0, 600.0).polytope()  # west of the path, 70 m off
    plans = {}
    for tracker in ("lqr", "lqr_du"):
        s1 = planner(tracker=tracker)
        s1.set_waypoints(np.array([[500.0, 600.0]]))
        plans[tracker] = plan = s1.plan(x, (wall,), prev_control=u_prev)
        assert_valid(plan, (wall,))
        assert plan.info["source"] == "operator" and plan.info["ref_speed_mps"] == 12.0
        verdict = verify_trajectory(plan.states, plan.controls, (wall,), DYN, SPEC.d_safe_m)
        assert verdict.ok and verdict.clearance_m >= SPEC.d_safe_m
    np.testing.assert_array_equal(plans["lqr"].path, plans["lqr_du"].path)
    k_du = planner(tracker="lqr_du").gain
    kv, ku = k_du[0, 2], k_du[0, 4]
    bound = kv * 10.0 + ku * float(np.hypot(3.0, 3.15))
    assert bound == pytest.approx(5.50, abs=0.01)
    jump_du = float(np.linalg.norm(plans["lqr_du"].controls[0] - u_prev))
    jump_plain = float(np.linalg.norm(plans["lqr"].controls[0] - u_prev))
    assert jump_du <= bound
    assert jump_plain == pytest.approx(10.96, abs=0.01)
    assert jump_du < 0.5 * jump_plain
    # the whole plan's Σ‖Δu‖² (from u_{t|t}) is smaller too
    def energy(plan: Plan) -> float:
        return float(np.sum(np.diff(np.vstack([u_prev, plan.controls]), axis=0) ** 2))

    assert energy(plans["lqr_du"]) < 0.5 * energy(plans["lqr"])
    assert not GOAL.contains(plans["lqr_du"].states[-1, :2])  # the operator's end, not G
    np.testing.assert_allclose(plans["lqr_du"].states[-1, :2], [500.0, 600.0], atol=0.5)


def test_lqr_du_rrt_plans_verify_and_use_prev_control() -> None:
    x = np.array([300.0, 200.0, 10.0, 0.0])
    base = planner(seed=3, tracker="lqr_du").plan(x, (BLOCK,), prev_control=np.array([3.0, 0.0]))
    assert_valid(base, (BLOCK,))
    assert verify_trajectory(base.states, base.controls, (BLOCK,), DYN, SPEC.d_safe_m).ok
    # the same RRT path as the paper's tracker (same seed), a different, smoother control
    np.testing.assert_array_equal(base.path, BEFORE["moving"][-1])
    assert not np.allclose(base.controls[0], BEFORE["moving"][4])
    other = planner(seed=3, tracker="lqr_du").plan(x, (BLOCK,), prev_control=np.array([-3.0, 0.0]))
    assert not np.array_equal(other.controls[0], base.controls[0])
    none = planner(seed=3, tracker="lqr_du").plan(x, (BLOCK,))  # no u_{t|t}: zero
    zero = planner(seed=3, tracker="lqr_du").plan(x, (BLOCK,), prev_control=np.zeros(2))
    np.testing.assert_array_equal(none.controls, zero.controls)


def test_the_registry_builds_the_du_tracker() -> None:
    # the built-ins (an installed package may add more after them)
    assert tuple(n for n in method_names(1) if n in BUILTIN) == ("rrt", "rrt+du")
    assert tuple(n for n in risk_aware_names(1) if n in BUILTIN) == ("rrt", "rrt+du")
    paper = build_planner(1, SPEC)
    du = build_planner(1, SPEC, "rrt+du", System1Params(r_delta_u=10.0))
    assert isinstance(paper, System1) and isinstance(du, System1)
    assert (paper.method, paper.params.tracker) == ("rrt", "lqr")
    assert (du.method, du.params.tracker, du.params.r_delta_u) == ("rrt+du", "lqr_du", 10.0)
    assert paper.gain.shape == (2, 4) and du.gain.shape == (2, 6)
    assert System1Params().r_delta_u == R_DELTA_U == 100.0


def test_tracker_bad_input_raises() -> None:
    with pytest.raises(ValueError, match="tracker"):
        System1Params(tracker="pid")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="r_delta_u"):
        System1Params(tracker="lqr_du", r_delta_u=-1.0)
    with pytest.raises(ValueError, match="r_delta_u"):
        System1Params(r_delta_u=float("nan"))
    s1 = planner(tracker="lqr_du")
    with pytest.raises(ValueError, match="prev_control"):
        s1.plan(hover_state(np.array([400.0, 400.0])), (), prev_control=np.zeros(3))
    with pytest.raises(ValueError, match="prev_control"):
        s1.plan(hover_state(np.array([400.0, 400.0])), (), prev_control=np.array([np.inf, 0.0]))

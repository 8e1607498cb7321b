"""The speed-limit reading (Sec. IV-A "a maximum velocity of 15m/s"): per axis or as a norm.

Worked by hand: under full force u = (7.5, 7.5) N, Eq. (1) per axis is
v' = 0.8 v + 7.5/1.05 ≈ 0.8 v + 7.14, which alone would settle at 35.7 m/s; the
clip holds each axis at 15 m/s per axis (|v| = 15√2 ≈ 21.21 m/s), and the
velocity on the disc |v| = 15 m/s (v_x = v_y = 15/√2 ≈ 10.61 m/s) under "norm".
System 2's speed polygon with K = 16 sides has inscribed radius
15·cos(π/16) ≈ 14.712 m/s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dualpilot.mission.monitor import check_plan
from dualpilot.model.dynamics import DynamicsParams, hover_state, speed_polygon, step
from dualpilot.model.geometry import Rect
from dualpilot.plan import Objective
from dualpilot.spec import MissionSpec
from dualpilot.system1.lqr import lqr_du_gain, lqr_gain, reference_states, track
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import System2Params, verify_p2_plan
from dualpilot.verify import verify_trajectory

AXIS = DynamicsParams()
NORM = DynamicsParams(speed_limit="norm")
V_POLY = 15.0 * math.cos(math.pi / 16)  # ≈ 14.712 m/s: the 16-gon's faces from the centre


def polygon_excess(velocities: np.ndarray) -> float:
    """max over v and k of n_k·v − 15 cos(π/16), n_k at angles (2k+1)π/16 (m/s)."""
    ang = (2 * np.arange(16) + 1) * math.pi / 16
    normals = np.column_stack([np.cos(ang), np.sin(ang)])
    return float(np.max(np.asarray(velocities) @ normals.T) - V_POLY)


def test_the_speed_limit_is_a_reading_default_axis() -> None:
    assert AXIS.speed_limit == "axis"
    with pytest.raises(ValueError, match="speed_limit"):
        DynamicsParams(speed_limit="box")  # type: ignore[arg-type]


@pytest.mark.parametrize(("dyn", "speed"), [(AXIS, 15.0 * math.sqrt(2.0)), (NORM, 15.0)])
def test_full_force_diagonal_flight_saturates(dyn: DynamicsParams, speed: float) -> None:
    x = hover_state(np.array([0.0, 0.0]), dyn)
    speeds = []
    for _ in range(20):
        x = step(x, np.array([7.5, 7.5]), dyn)
        speeds.append(float(np.linalg.norm(x[2:])))
    assert speeds[-1] == pytest.approx(speed, abs=1e-9)
    assert max(speeds) <= speed + 1e-9
    assert x[2] == pytest.approx(x[3])  # straight along the diagonal
    # first step below the limit (7.14 per axis), unclipped in both readings
    assert speeds[0] == pytest.approx(7.5 / 1.05 * math.sqrt(2.0))


def test_norm_clip_keeps_the_direction_and_leaves_slow_velocities() -> None:
    x = np.array([0.0, 0.0, 30.0, 40.0])  # 50 m/s at (0.6, 0.8)
    nxt = step(x, np.zeros(2), NORM)  # 0.8 v = (24, 32), |.| = 40 → (9, 12)
    assert nxt[2:] == pytest.approx([9.0, 12.0])
    slow = step(np.array([0.0, 0.0, 6.0, 8.0]), np.zeros(2), NORM)
    assert slow[2:] == pytest.approx([4.8, 6.4])  # 8 m/s: no clip


def test_speed_polygon_lies_inside_the_disc() -> None:
    normals, cos_k = speed_polygon(16)
    assert normals.shape == (16, 2) and cos_k == pytest.approx(math.cos(math.pi / 16))
    # vertices of {n_k·v ≤ 15 cos(π/16)} are at angles 2πk/16 on the circle |v| = 15:
    # on the axes and the diagonals
    ang = 2 * np.arange(16) * math.pi / 16
    verts = 15.0 * np.column_stack([np.cos(ang), np.sin(ang)])
    assert np.max(verts @ normals.T, axis=1) == pytest.approx(np.full(16, 15.0 * cos_k))


def diagonal_plan(speed: float, steps: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """A cruise at ``speed`` m/s along the diagonal that follows Eq. (1) exactly."""
    v = np.full(2, speed / math.sqrt(2.0))  # ≈ 11.31 m/s per axis at 16 m/s
    u = np.tile(AXIS.zeta * AXIS.mass_kg / AXIS.dt_s * v, (steps, 1))  # holds v against ζ
    states = [np.array([100.0, 100.0, *v])]
    for k in range(steps):
        states.append(step(states[-1], u[k], AXIS))
    return np.array(states), u


def test_verify_p2_plan_rejects_16_mps_on_a_diagonal_only_under_norm() -> None:
    states, u = diagonal_plan(16.0)
    assert np.max(np.abs(states[:, 2:])) == pytest.approx(16.0 / math.sqrt(2.0))  # ≈ 11.31
    args = ((), 25.0, 20.0, 1000.0)
    assert verify_p2_plan(states, u, (), AXIS, *args[1:]).ok
    bad = verify_p2_plan(states, u, (), NORM, *args[1:])
    assert not bad.ok and "speed" in bad.reason
    assert verify_trajectory(states, u, [], AXIS, 20.0).ok
    assert not verify_trajectory(states, u, [], NORM, 20.0).ok


def test_the_monitor_rejects_16_mps_on_a_diagonal_only_under_norm() -> None:
    states, u = diagonal_plan(16.0)
    axis = check_plan(states, u, states[0], [], MissionSpec(dynamics=AXIS))
    assert axis.ok, axis.reason
    norm = check_plan(states, u, states[0], [], MissionSpec(dynamics=NORM))
    assert not norm.ok and "16 m/s exceeds 15" in norm.reason


@pytest.mark.parametrize("du", [False, True])
def test_lqr_tracker_keeps_the_disc_on_a_fast_diagonal_reference(du: bool) -> None:
    path = np.array([[0.0, 0.0], [800.0, 800.0]])
    ref = reference_states(path, 40, 25.0, NORM)  # asks for 25 m/s along the diagonal
    x0 = hover_state(np.array([0.0, 0.0]), NORM)
    for dyn in (AXIS, NORM):
        gain = (lqr_du_gain(dyn) if du else lqr_gain(dyn))[0]
        states, controls = track(x0, ref, gain, dyn, prev_control=np.zeros(2) if du else None)
        speeds = np.linalg.norm(states[1:, 2:], axis=1)
        assert np.all(np.abs(controls) <= 7.5 + 1e-12)
        assert np.allclose(states[1:], states[:-1] @ np.array(
            [[1, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0.8, 0], [0, 1, 0, 0.8]])
            + controls @ np.array([[0, 0, 1 / 1.05, 0], [0, 0, 0, 1 / 1.05]]))  # Eq. (1)
        if dyn is NORM:
            assert np.max(speeds) <= 15.0 + 1e-9
            assert np.max(speeds) == pytest.approx(15.0, abs=1e-6)  # saturates on the disc
        else:
            assert np.max(speeds) == pytest.approx(15.0 * math.sqrt(2.0), abs=1e-6)


def far_diagonal(spec_dyn: DynamicsParams) -> tuple[MissionSpec, np.ndarray]:
    return MissionSpec(start=(50.0, 50.0), dynamics=spec_dyn), hover_state(
        np.array([50.0, 50.0]), spec_dyn)


@pytest.mark.parametrize("backend", ["ipm", "clarabel"])
def test_fast_system2_plan_keeps_the_speed_polygon_under_norm(backend: str) -> None:
    spec, x0 = far_diagonal(NORM)
    planner = FastSystem2(spec, System2Params(horizon=30))
    planner.qp.backend = backend
    plan = planner.plan(x0, [], Objective.MISSION_TIME)
    assert plan.ok, plan.message
    speeds = np.linalg.norm(plan.states[1:, 2:], axis=1)
    assert polygon_excess(plan.states[1:, 2:]) <= 1e-6
    assert np.max(speeds) <= 15.0
    assert np.max(speeds) > 15.0 - 0.01  # at the polygon's vertex on the diagonal
    assert verify_p2_plan(plan.states, plan.controls, [], NORM, spec.clearance_m,
                          spec.d_safe_m, spec.area_size_m).ok
    axis_spec, _ = far_diagonal(AXIS)
    axis = FastSystem2(axis_spec, System2Params(horizon=30)).plan(x0, [], Objective.MISSION_TIME)
    assert np.max(np.linalg.norm(axis.states[1:, 2:], axis=1)) > 21.0  # per axis: ≈ 21.2


def test_fast_system2_towards_a_face_normal_progresses_at_15_cos_pi_over_16() -> None:
    # towards a goal at angle π/16 from the start the face n_0 bounds the progress
    # n_0·v (every point of that face progresses alike: |v| anywhere in [14.71, 15])
    a = math.pi / 16
    goal = Rect(50.0 + 850.0 * math.cos(a), 50.0 + 850.0 * math.sin(a), 60.0, 60.0)
    spec = MissionSpec(start=(50.0, 50.0), goal=goal, dynamics=NORM)
    x0 = hover_state(np.array([50.0, 50.0]), NORM)
    plan = FastSystem2(spec, System2Params(horizon=30)).plan(x0, [], Objective.MISSION_TIME)
    assert plan.ok, plan.message
    progress = plan.states[1:, 2:] @ np.array([math.cos(a), math.sin(a)])
    assert np.max(progress) == pytest.approx(V_POLY, abs=2e-3)  # 14.712 m/s, not 15


def test_exact_system2_plan_keeps_the_speed_polygon_under_norm() -> None:
    from dualpilot.system2.exact import ExactSystem2

    spec, x0 = far_diagonal(NORM)
    plan = ExactSystem2(spec, System2Params(horizon=15, max_hulls=1, max_faces=4)).plan(
        x0, [], Objective.MISSION_TIME)
    assert plan.ok, plan.message
    speeds = np.linalg.norm(plan.states[1:, 2:], axis=1)
    assert polygon_excess(plan.states[1:, 2:]) <= 1e-5
    assert np.max(speeds) > 15.0 - 0.01  # the vertex on the diagonal


def test_seeded_scip_keeps_the_speed_polygon_under_norm() -> None:
    pytest.importorskip("pyscipopt")
    from dualpilot.system2.scip import solve_seeded

    _, x0 = far_diagonal(NORM)
    res = solve_seeded(x0, [], np.array([950.0, 950.0]), (1.0, 0.001), np.zeros(2),
                       System2Params(horizon=10), NORM, None, 30.0, 25.0, 1000.0)
    assert res.controls is not None
    from dualpilot.model.dynamics import rollout

    states = rollout(x0, res.controls, NORM)
    speeds = np.linalg.norm(states[1:, 2:], axis=1)
    assert polygon_excess(states[1:, 2:]) <= 1e-5
    assert np.max(speeds) > 15.0 - 0.01  # the vertex on the diagonal

"""The space-time search's pieces: boxes of what is known, plans from a moving state, the
smoothing QP; values worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.model.dynamics import DynamicsParams, rollout
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.geometry import Rect
from dualpilot.plan import Plan, PlanStatus
from dualpilot.spacetime.known import known_future, row_runs
from dualpilot.spacetime.lattice import segment_box_d2
from dualpilot.spacetime.plan import FutureBoxes, Stage, arrival, lattice_plan, plan_clear
from dualpilot.spacetime.smooth import _rollout_matrices, smooth
from dualpilot.spec import MissionSpec

SPEC = MissionSpec(start=(50.0, 500.0), goal=Rect(900.0, 500.0, 100.0, 100.0))
STAGE = Stage(5.0, 50_000, weight=2.0)


def test_segment_box_distance_by_hand() -> None:
    box = (0.0, 0.0, 10.0, 10.0)
    assert segment_box_d2(-5.0, 5.0, 15.0, 5.0, *box) == 0.0  # crosses it
    assert segment_box_d2(13.0, -4.0, 13.0, 20.0, *box) == pytest.approx(9.0)  # 3 m east
    assert segment_box_d2(13.0, 14.0, 20.0, 20.0, *box) == pytest.approx(25.0)  # corner: 3-4-5


def test_row_runs_are_the_runs_of_each_row_grown() -> None:
    mask = np.array([[0, 1, 1, 0, 1], [0, 0, 0, 0, 0], [1, 1, 1, 1, 1]], dtype=bool)
    boxes = row_runs(mask, 10.0, (100.0, 200.0), grow_m=5.0)
    expected = [[105.0, 195.0, 135.0, 215.0], [135.0, 195.0, 155.0, 215.0],
                [95.0, 215.0, 155.0, 235.0]]
    assert boxes.tolist() == expected
    assert row_runs(np.zeros((2, 2), dtype=bool), 10.0, (0.0, 0.0)).shape == (0, 4)


def forecast_with(cells_by_slice: list[list[tuple[int, int]]], horizons: tuple[int, ...]
                  ) -> OccupancyForecast:
    """A 10 m forecast over 1000 m whose given (row, col) cells are certain, slice by slice."""
    levels = []
    for cells in cells_by_slice:
        lv = np.zeros((100, 100), dtype=np.uint8)
        for r, c in cells:
            lv[r, c] = 255
        levels.append(lv)
    return OccupancyForecast(10.0, 0.5, horizons, levels)


def test_the_known_future_holds_the_hulls_and_each_substeps_risky_cells() -> None:
    """Slices at 0 and 2 sub-steps: sub-step 1 stands between them (both count), 2 is slice 1,
    past the horizon the last slice holds; every sub-step has the hull's box."""
    fc = forecast_with([[(10, 10)], [(20, 30)]], (0, 2))
    hull = Rect(500.0, 500.0, 20.0, 40.0).polytope()
    future = known_future((hull,), fc, 4, alpha=0.1)
    def at(s: int) -> list[list[float]]:
        return future.boxes[future.offsets[s]:future.offsets[s + 1]].tolist()
    assert at(0) == [[490.0, 480.0, 510.0, 520.0]]
    assert at(1) == [[490.0, 480.0, 510.0, 520.0], [95.0, 95.0, 115.0, 115.0],
                     [295.0, 195.0, 315.0, 215.0]]
    assert at(2) == at(4) == [[490.0, 480.0, 510.0, 520.0], [295.0, 195.0, 315.0, 215.0]]


def open_field(steps: int = 150) -> FutureBoxes:
    return FutureBoxes.of([np.empty((0, 4))] * (steps + 2))


def test_a_plan_from_a_moving_state_keeps_its_committed_first_flight() -> None:
    """From (50, 500) at 10 m/s east the first flight is fixed: x_1 = (60, 500); the plan lands in
    G, keeps the force and speed limits and follows Eq. (1)."""
    state = np.array([50.0, 500.0, 10.0, 0.0])
    plan, _ = lattice_plan(state, open_field(), SPEC, STAGE, 150, 20.5)
    assert plan is not None
    assert np.allclose(plan.states[1, :2], [60.0, 500.0])
    dyn = SPEC.dynamics
    assert np.allclose(rollout(state, plan.controls, dyn), plan.states)
    assert np.abs(plan.controls).max() <= dyn.u_max_n + 1e-9
    assert np.abs(plan.states[:, 2:]).max() <= dyn.v_max_mps + 1e-9
    assert arrival(plan, SPEC) == len(plan.states) - 1
    # 790 m east to G's edge from (60, 500): at most 15 m a step, so at least 53 steps more
    assert len(plan.controls) >= 1 + 53


def test_no_plan_when_the_committed_flight_meets_a_box() -> None:
    """A box 15 m east of the UAV flying east at 10 m/s: its next flight passes within d."""
    wall = np.array([[75.0, 0.0, 80.0, 1000.0]])
    future = FutureBoxes.of([wall] * 152)
    plan, expansions = lattice_plan(np.array([50.0, 500.0, 10.0, 0.0]), future, SPEC, STAGE,
                                    150, 20.5)
    assert plan is None and expansions == 0


def test_plan_clear_reads_each_flight_against_its_substep() -> None:
    """A box appears at sub-step 3 across the straight line: a plan that is past it by then is
    clear, one that meets it then is not; flights past the future meet its last boxes."""
    box = np.array([[200.0, 0.0, 210.0, 1000.0]])
    parts = [np.empty((0, 4))] * 3 + [box] * 2
    future = FutureBoxes.of(parts)
    dyn = SPEC.dynamics
    fast = rollout(np.array([260.0, 500.0, 15.0, 0.0]), np.zeros((6, 2)), dyn)
    plan = Plan(1, PlanStatus.OK, fast, np.zeros((6, 2)), 0.0)
    assert plan_clear(plan, future, 20.0)
    slow = rollout(np.array([150.0, 500.0, 10.0, 0.0]), np.zeros((6, 2)), dyn)
    meets = Plan(1, PlanStatus.OK, slow, np.zeros((6, 2)), 0.0)
    assert plan_clear(meets, future, 20.0, steps=1)  # flight 0 meets sub-step 1: no box yet
    assert not plan_clear(meets, future, 20.0)


def test_the_rollout_matrices_are_eq_1() -> None:
    dyn = DynamicsParams()
    rng = np.random.default_rng(1)
    x0, u = rng.normal(size=4) * 5, rng.uniform(-7.5, 7.5, (30, 2))
    a, b, c, d = _rollout_matrices(dyn.zeta, dyn.dt_s, dyn.mass_kg, 30)
    states = rollout(x0, u, dyn)
    assert np.allclose(states[1:, 2:], a[:, None] * x0[None, 2:] + b @ u, atol=1e-12)
    assert np.allclose(states[1:, :2], x0[None, :2] + c[:, None] * x0[None, 2:] + d @ u,
                       atol=1e-9)


def test_smoothing_keeps_the_tube_and_lowers_the_energy() -> None:
    """A lattice plan along a direction off the lattice's (north-east, 1 : 2) zig-zags between
    velocities; smoothed in a 3 m tube it lands in G with less Σ‖Δu‖²."""
    spec = MissionSpec(start=(100.0, 100.0), goal=Rect(500.0, 900.0, 100.0, 100.0))
    state = np.array([100.0, 100.0, 0.0, 0.0])
    plan, _ = lattice_plan(state, open_field(), spec, STAGE, 150, 20.5)
    assert plan is not None
    smoothed = smooth(plan, spec, np.zeros(2), 3.0)
    assert smoothed is not None
    def energy(p: Plan) -> float:
        return float(np.sum(np.diff(np.vstack([np.zeros(2), p.controls]), axis=0) ** 2))
    assert energy(smoothed) < 0.5 * energy(plan)
    assert np.abs(smoothed.states[1:, :2] - plan.states[1:, :2]).max() <= 3.0 + 1e-6
    assert spec.goal.contains(smoothed.states[-1, :2])
    assert np.abs(smoothed.controls).max() <= spec.dynamics.u_max_n

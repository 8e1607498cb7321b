"""The reach sets of System 2's certificate: sound on feasible plans, exact to a cell by hand."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dualpilot.evaluation.instances import SPEC, make_instance
from dualpilot.model.geometry import Polytope
from dualpilot.plan import Objective
from dualpilot.system2.certify.planner import relaxation_of
from dualpilot.system2.certify.reach import reach_sets
from dualpilot.system2.fast.planner import FastSystem2
from dualpilot.system2.problem import System2Params

T = 80
STEP_M = 15.0  # ΔT·v_max
CELL_M = 3.0  # STEP_M / CELLS_PER_STEP
P1 = np.array([200.0, 100.0])
GOAL = np.array([600.0, 100.0])
AREA_LO = np.tile([0.0, 0.0], (T, 1))
AREA_HI = np.tile([1000.0, 1000.0], (T, 1))


def _free_distance(n: int) -> float:
    """Free space: after n steps of at most 15 m per axis, G is max(0, 400 − 15 n) m away."""
    return max(0.0, 400.0 - STEP_M * n)


def test_free_space_floors_and_prefix_are_the_hand_values_to_a_cell() -> None:
    """Each floor is the hand distance less at most the start cell's extent (1 m here: p_1
    sits 1 m inside its cell), and the prefix cost lies between the two sums."""
    r = reach_sets(P1, AREA_LO, AREA_HI, [], 25.0, GOAL, STEP_M)
    assert not r.empty and r.cell_m == CELL_M
    for tau in range(1, T + 1):
        exact = _free_distance(tau - 1)
        assert exact - 1.0 - 1e-9 <= r.floor_m[tau - 1] <= exact + 1e-9
    upper = sum(_free_distance(n) ** 2 for n in range(1, T))
    lower = sum(max(0.0, _free_distance(n) - 1.0) ** 2 for n in range(1, T))
    assert lower * (1 - 1e-4) <= r.prefix_m2[-1] <= upper
    assert r.suffix_m2[1] == pytest.approx(r.prefix_m2[-1], rel=1e-5)  # the same path sum


def test_a_wall_keeps_the_uav_on_its_side() -> None:
    """A wall x ∈ [400, 420], y ≤ 800 (ε = 25: 70 m thick inflated, more than a step) stands
    between p_1 and G. Going round it takes 50 steps up and back, so within T = 80 the
    nearest the UAV gets is the wall's face at (375, 100), 225 m from G; free, it is 0."""
    wall = Polytope.from_vertices(np.array([[400.0, 0.0], [420.0, 0.0], [420.0, 800.0],
                                            [400.0, 800.0]]))
    r = reach_sets(P1, AREA_LO, AREA_HI, [wall], 25.0, GOAL, STEP_M)
    assert 225.0 - CELL_M - 1e-9 <= r.floor_m[-1] <= 225.0
    assert reach_sets(P1, AREA_LO, AREA_HI, [], 25.0, GOAL, STEP_M).floor_m[-1] == 0.0
    path = r.corridor()
    assert path is not None
    assert np.all(path[:, 0] <= 375.0 + CELL_M)  # the cheapest cells stay left of the wall
    assert np.all(np.abs(np.diff(path, axis=0)) <= STEP_M + 1e-9)  # a step at most


def test_no_cell_left_proves_infeasible() -> None:
    """A hull covering everything p_2 can reach: R_2 is empty."""
    box = Polytope.from_vertices(np.array([[100.0, 0.0], [300.0, 0.0], [300.0, 200.0],
                                           [100.0, 200.0]]))
    r = reach_sets(P1, AREA_LO, AREA_HI, [box], 25.0, GOAL, STEP_M)
    assert r.empty and r.corridor() is None


@settings(max_examples=12, deadline=None)
@given(index=st.integers(0, 10**4), n_hulls=st.integers(1, 10),
       objective=st.sampled_from(list(Objective)))
def test_every_verified_plan_respects_the_reach_sets(index: int, n_hulls: int,
                                                     objective: Objective) -> None:
    """The fast method's verified plans (feasible for (P2)) lie in every box, keep every
    floor, and their partial sums of ‖p_τ − G_o‖² reach the prefix and suffix bounds."""
    inst = make_instance(index, 3, n_hulls)
    params = System2Params()
    plan = FastSystem2(SPEC, params).plan(inst.state, inst.hulls, objective, inst.prev_control)
    if not plan.ok:
        return
    rel = relaxation_of(SPEC, params, inst.state, inst.hulls, objective, inst.prev_control)
    reach = rel.reach
    assert reach is not None and not reach.empty
    horizon = params.horizon
    pos = plan.states[1:horizon + 1, :2]  # p_1..p_T
    assert np.all(pos >= reach.lo - 1e-6) and np.all(pos <= reach.hi + 1e-6)
    dist = np.linalg.norm(pos - SPEC.goal.center[:2], axis=1)
    assert np.all(dist >= reach.floor_m - 1e-6)
    d2 = dist[1:] ** 2  # p_2..p_T
    assert np.all(np.cumsum(d2) >= reach.prefix_m2[1:] * (1 - 1e-9))
    assert np.all(np.cumsum(d2[::-1])[::-1] >= reach.suffix_m2[1:] * (1 - 1e-9))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10**6), k=st.integers(1, 6))
def test_window_minimum_is_the_brute_force_one(seed: int, k: int) -> None:
    """The separable van Herk–Gil-Werman minimum equals the minimum over each window,
    taken only over the source box, on random boxes and values (inf included)."""
    from dualpilot.system2.certify.reach import _window_min

    rng = np.random.default_rng(seed)
    nx, ny = rng.integers(5, 40, size=2)
    src = rng.uniform(0, 10, (nx, ny)).astype(np.float32)
    src[rng.uniform(size=(nx, ny)) < 0.3] = np.inf
    i0, i1 = np.sort(rng.integers(0, nx, 2))
    j0, j1 = np.sort(rng.integers(0, ny, 2))
    o = np.array([max(i0 - k, 0), max(j0 - k, 0), min(i1 + k, nx - 1), min(j1 + k, ny - 1)])
    out = np.full((nx, ny), -1.0, dtype=np.float32)
    work = [np.empty((nx + 2 * k + 1, ny + 2 * k + 1), dtype=np.float32) for _ in range(2)]
    _window_min(src, np.array([i0, j0, i1, j1]), out, o, k,
                np.empty((nx, ny), dtype=np.float32), *work)
    masked = np.full((nx, ny), np.inf, dtype=np.float32)
    masked[i0:i1 + 1, j0:j1 + 1] = src[i0:i1 + 1, j0:j1 + 1]
    for i in range(o[0], o[2] + 1):
        for j in range(o[1], o[3] + 1):
            want = masked[max(i - k, 0):i + k + 1, max(j - k, 0):j + k + 1].min()
            assert out[i, j] == want

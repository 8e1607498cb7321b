"""The grid proof of "no path" (dualpilot.system1.reach): sound, and decisive on clear-cut cases."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.model.geometry import Polytope, Rect
from dualpilot.system1.reach import certainly_unreachable, corridor, possibly_free, start_component
from dualpilot.system1.rrt import RrtParams, plan_path

GOAL = Rect(900.0, 900.0, 100.0, 100.0)
AREA = 1000.0
START = np.array([50.0, 50.0])


def wall_with_gap(gap_m: float) -> tuple[Polytope, ...]:
    """A 20 m thick wall across the area at y ∈ [500, 520] with a gap centred on x = 500."""
    half = gap_m / 2
    left = Rect((500 - half) / 2, 510.0, 500 - half, 20.0)
    right = Rect((1500 + half) / 2, 510.0, 500 - half, 20.0)
    return (left.polytope(), right.polytope())


def test_a_closed_wall_is_proved_unreachable() -> None:
    assert certainly_unreachable(START, GOAL, wall_with_gap(0.0), 25.0, AREA)


@pytest.mark.parametrize(("gap_m", "proved"), [
    # Cell centres in the gap lie at x = 495 and 505; the threshold is 25 − 5√2 ≈ 17.93 m.
    (30.0, True),    # sides at 485/515: the centres are 10 m from a side
    (44.0, True),    # sides at 478/522: 17 m < 17.93, every gap cell blocked
    (46.0, False),   # sides at 477/523: 18 m ≥ 17.93; no path (needs 50 m), the grid cannot tell
    (60.0, False),   # a path exists through the middle (30 m from each side)
])
def test_gap_widths_worked_by_hand(gap_m: float, proved: bool) -> None:
    assert certainly_unreachable(START, GOAL, wall_with_gap(gap_m), 25.0, AREA) is proved


def test_a_wide_gap_is_really_passable() -> None:
    result = plan_path(START, GOAL, wall_with_gap(60.0), np.random.default_rng(1), 25.0, AREA,
                       RrtParams(max_iterations=20_000, max_cpu_s=30.0))
    assert result.found


def test_cells_marked_by_hand() -> None:
    # one 100 m square at [400, 500]²; cells of 10 m; threshold 25 − 7.07 = 17.93 m
    free = possibly_free((Rect(450.0, 450.0, 100.0, 100.0).polytope(),), 25.0, 1000.0, 10.0)
    assert free.shape == (100, 100)
    assert not free[45, 45]               # inside
    assert not free[45, 51]               # centre (515, 455): 15 m from the right side
    assert free[45, 52]                   # centre (525, 455): 25 m away
    assert not free[50, 50]               # centre (505, 505): 5√2 ≈ 7.1 m from the corner
    assert free[51, 51]                   # centre (515, 515): 15√2 ≈ 21.2 m ≥ 17.9 (over-approx.)


def test_an_escape_start_is_not_blocked_by_its_own_cell() -> None:
    hull = Rect(100.0, 100.0, 100.0, 100.0).polytope()  # start 22 m from its right side
    start = np.array([172.0, 100.0])
    assert not certainly_unreachable(start, GOAL, (hull,), 25.0, AREA, start_clearance_m=22.0)


def test_never_hides_a_path_the_rrt_finds() -> None:
    rng = np.random.default_rng(7)
    found = 0
    for _ in range(25):
        rects = [Rect(*rng.uniform(150, 850, 2), *rng.uniform(100, 250, 2)) for _ in range(6)]
        hulls = tuple(r.polytope() for r in rects)
        if any(h.distance(START) < 25.0 for h in hulls):
            continue
        result = plan_path(START, GOAL, hulls, np.random.default_rng(0), 25.0, AREA,
                           RrtParams(reach_check=False, max_iterations=5000))
        if result.found:
            found += 1
            assert not certainly_unreachable(START, GOAL, hulls, 25.0, AREA)
    assert found >= 5


def test_finer_cells_prove_a_gap_the_coarse_grid_cannot() -> None:
    # Gap 46 m (sides at 477/523). Cells of 5 m: threshold 25 − 2.5√2 ≈ 21.46 m; the gap cells'
    # centres (492.5 … 507.5) lie at most 20.5 m from a side, so all are blocked. Cells of
    # 10 m cannot tell (test_gap_widths_worked_by_hand).
    hulls = wall_with_gap(46.0)
    assert not certainly_unreachable(START, GOAL, hulls, 25.0, AREA, cell_m=10.0)
    assert certainly_unreachable(START, GOAL, hulls, 25.0, AREA, cell_m=5.0)
    result = plan_path(START, GOAL, hulls, np.random.default_rng(1), 25.0, AREA, RrtParams())
    # the paper's 500 samples fail, the 5 m grid then proves that no path exists
    assert (result.status, result.iterations) == ("unreachable", 500)


@pytest.mark.parametrize("seed", [3, 11, 29])
def test_the_coarse_component_only_saves_work(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rects = [Rect(*rng.uniform(150, 850, 2), *rng.uniform(100, 250, 2)) for _ in range(8)]
    hulls = tuple(r.polytope() for r in rects) + wall_with_gap(70.0)
    coarse, _ = start_component(START, GOAL, hulls, 25.0, AREA, cell_m=10.0)
    fine, meets = start_component(START, GOAL, hulls, 25.0, AREA, cell_m=5.0)
    restricted, meets_restricted = start_component(START, GOAL, hulls, 25.0, AREA, cell_m=5.0,
                                                   coarse=coarse)
    assert np.array_equal(fine, restricted) and meets == meets_restricted
    assert not np.any(fine & ~np.repeat(np.repeat(coarse, 2, axis=0), 2, axis=1))


def test_corridor_threads_the_gap() -> None:
    # Gap 60 m centred on x = 150 (sides at 120/180) in a wall at y ∈ [500, 520].
    left = Rect(60.0, 510.0, 120.0, 20.0).polytope()
    right = Rect(590.0, 510.0, 820.0, 20.0).polytope()
    component, meets = start_component(START, GOAL, (left, right), 25.0, AREA)
    assert meets
    chain = corridor(component, START, GOAL, 10.0)
    assert tuple(chain[0]) == (5, 5)                                  # the start's cell
    assert 85 <= chain[-1][0] <= 94 and 85 <= chain[-1][1] <= 94     # a cell meeting G
    assert np.all(np.abs(np.diff(chain, axis=0)).max(axis=1) == 1)   # 8-connected steps
    assert np.all(component[chain[:, 1], chain[:, 0]])
    # Rows 49–52 (centres 495–525 m) lie within 17.93 m of the wall y ∈ [500, 520]; there only
    # columns 14 and 15 are possibly free (centres 145/155 m keep ≥ 17.93 m from the sides at
    # 120/180; 135 and 165 m do not).
    in_wall = chain[(chain[:, 1] >= 49) & (chain[:, 1] <= 52)]
    assert len(in_wall) == 4 and set(in_wall[:, 0]) <= {14, 15}
    # Fewest cells, by Chebyshev distance through the gap: (5, 5) → (15, 49) is 44 steps,
    # (15, 49) → (15, 52) three, (15, 52) → the nearest G cell (85, 85) 70: 117 steps, 118 cells.
    assert len(chain) == 118

"""Alg. 1 (dualpilot.system1.rrt): exact edge checks, free paths, determinism, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.geometry import Polytope, Rect, path_clearance
from dualpilot.spec import MissionSpec
from dualpilot.system1.rrt import RrtParams, SegmentChecker, plan_path, shortcut

SPEC = MissionSpec()
GOAL = SPEC.goal
START = np.array(SPEC.start)
CLEAR = SPEC.clearance_m
AREA = SPEC.area_size_m
# A needle pointing at the diagonal y = x: its tip lies 24 m from the line, above (500, 500).
_TIP = np.array([500.0, 500.0]) + 24.0 * np.array([-1.0, 1.0]) / np.sqrt(2.0)
NEEDLE = Polytope.from_vertices(
    np.array([_TIP, _TIP + [-150.0, 250.0], _TIP + [-250.0, 150.0]])
)


def fire_hulls(seed: int, n_fronts: int, substeps: int) -> tuple[Polytope, ...]:
    """Hulls of ``n_fronts`` fronts born uniformly and advanced ``substeps`` sub-steps."""
    rng = np.random.default_rng(seed)
    field = FireField(FireParams())
    for _ in range(n_fronts):
        field.spawn(rng, 0)
    for _ in range(substeps):
        field.fronts = [f.advance(rng, field.params) for f in field.fronts]
    return field.snapshot().hulls


def sampled_min_distance(path: np.ndarray, hulls: tuple[Polytope, ...], step: float = 0.25
                         ) -> float:
    """Independent check: point-sample every edge densely, distance by Polytope.distance.

    Points farther than 2·CLEAR from a hull's bounding box are skipped (they are clear).
    """
    best = np.inf
    for p0, p1 in zip(path[:-1], path[1:], strict=True):
        n = max(2, int(np.ceil(np.linalg.norm(p1 - p0) / step)) + 1)
        pts = np.linspace(p0, p1, n)
        for h in hulls:
            lo, hi = h.vertices.min(axis=0) - 2 * CLEAR, h.vertices.max(axis=0) + 2 * CLEAR
            near = pts[np.all((pts >= lo) & (pts <= hi), axis=1)]
            for p in near:
                assert not h.contains(p), "a path point lies inside a hull"
                best = min(best, h.distance(p))
    return best


def test_segment_checker_matches_polytope_segment_distance() -> None:
    rng = np.random.default_rng(3)
    hulls = [Polytope.from_vertices(rng.uniform(0, 250, (7, 2)) + rng.uniform(0, 750, 2))
             for _ in range(4)]
    checker = SegmentChecker(hulls)
    p0 = rng.uniform(0, 1000, (400, 2))
    p1 = p0 + rng.normal(0.0, 80.0, (400, 2))
    expected = np.array([min(h.segment_distance(a, b) for h in hulls)
                         for a, b in zip(p0, p1, strict=True)])
    assert np.any(expected == 0.0) and np.any(expected > 0.0)
    np.testing.assert_allclose(checker.distances(p0, p1), expected, atol=1e-9)
    np.testing.assert_array_equal(checker.clear(p0, p1, CLEAR), expected >= CLEAR)
    singles = [checker.segment_clear(a[0], a[1], b[0], b[1], CLEAR) for a, b in zip(p0, p1,
                                                                                     strict=True)]
    np.testing.assert_array_equal(singles, expected >= CLEAR)
    assert checker.path_clearance(p0[:5]) == pytest.approx(path_clearance(p0[:5], hulls))


def test_empty_hulls_are_clear() -> None:
    checker = SegmentChecker(())
    assert checker.point_distance(START) == np.inf
    assert checker.clear(START[None], GOAL.center[None], CLEAR).all()
    assert checker.segment_clear(0.0, 0.0, 10.0, 10.0, CLEAR)


def test_exact_check_catches_a_corner_that_sampling_misses() -> None:
    # One 15 m RRT step passing 24 m from the needle's tip: both end states keep > 25 m,
    # so a check that samples states (every <= 15 m) accepts the edge; the exact one does not.
    foot = np.array([500.0, 500.0])
    a, b = foot - 7.5 / np.sqrt(2) * np.ones(2), foot + 7.5 / np.sqrt(2) * np.ones(2)
    assert NEEDLE.distance(a) > CLEAR and NEEDLE.distance(b) > CLEAR
    assert NEEDLE.segment_distance(a, b) == pytest.approx(24.0)
    assert not SegmentChecker([NEEDLE]).segment_clear(a[0], a[1], b[0], b[1], CLEAR)


def test_rrt_avoids_the_needle_tip_on_the_direct_line() -> None:
    hulls = (NEEDLE,)
    result = plan_path(START, GOAL, hulls, np.random.default_rng(0), CLEAR, AREA)
    assert result.status == "exact" and result.path is not None
    assert result.iterations > 0
    assert sampled_min_distance(result.path, hulls) >= CLEAR - 1e-6
    assert path_clearance(result.path, hulls) >= CLEAR - 1e-9


@pytest.mark.parametrize("seed", [1, 2, 3, 4])  # fire fields where G stays reachable
def test_paths_are_free_of_every_hull_and_end_in_goal(seed: int) -> None:
    hulls = fire_hulls(seed, n_fronts=3 + seed % 3, substeps=20)
    start = START
    rng = np.random.default_rng(100 + seed)
    checker = SegmentChecker(hulls)
    while checker.point_distance(start) < CLEAR:  # a start that is itself valid
        start = rng.uniform(0, 1000, 2)
    result = plan_path(start, GOAL, hulls, np.random.default_rng(seed), CLEAR, AREA)
    assert result.status == "exact" and result.path is not None
    path = result.path
    np.testing.assert_array_equal(path[0], start)
    assert GOAL.contains(path[-1])
    assert sampled_min_distance(path, hulls) >= CLEAR - 1e-6
    if result.tree_path is not None:  # the raw RRT edges were checked exactly as well
        assert np.all(np.linalg.norm(np.diff(result.tree_path, axis=0), axis=1) <= 15.0 + 1e-9)
        assert path_clearance(result.tree_path, hulls) >= CLEAR - 1e-9


def test_same_seed_gives_the_same_path() -> None:
    hulls = (NEEDLE, Rect(300.0, 650.0, 200.0, 150.0).polytope())
    a = plan_path(START, GOAL, hulls, np.random.default_rng(42), CLEAR, AREA)
    b = plan_path(START, GOAL, hulls, np.random.default_rng(42), CLEAR, AREA)
    c = plan_path(START, GOAL, hulls, np.random.default_rng(43), CLEAR, AREA)
    assert a.path is not None and b.path is not None and c.path is not None
    assert a.tree_path is not None and b.tree_path is not None and c.tree_path is not None
    assert a.iterations == b.iterations
    np.testing.assert_array_equal(a.tree_path, b.tree_path)
    np.testing.assert_array_equal(a.path, b.path)
    assert not np.array_equal(a.tree_path, c.tree_path)


def narrow_gap(gap_m: float, x_m: float) -> tuple[Polytope, ...]:
    """A 20 m thick wall across the area at y ∈ [500, 520] with a gap of ``gap_m`` centred on x."""
    half = gap_m / 2
    return (Rect((x_m - half) / 2, 510.0, x_m - half, 20.0).polytope(),
            Rect((1000.0 + x_m + half) / 2, 510.0, 1000.0 - x_m - half, 20.0).polytope())


def test_guided_samples_thread_a_narrow_passage() -> None:
    # 56 m gap at x = 150: a path needs 50 m, so the passage leaves 6 m of play. After the
    # paper's 500 samples the tree is drawn along the grid corridor through the gap.
    hulls = narrow_gap(56.0, 150.0)
    plain = RrtParams(guide_after=10**6)
    guided = [plan_path(START, GOAL, hulls, np.random.default_rng(k), CLEAR, AREA)
              for k in range(8)]
    unguided = [plan_path(START, GOAL, hulls, np.random.default_rng(k), CLEAR, AREA, plain)
                for k in range(8)]
    assert sum(r.found for r in unguided) < 8          # the premise: plain Alg. 1 misses it
    for result in guided:
        assert result.status == "exact" and result.path is not None
        assert result.iterations <= 2000
        assert GOAL.contains(result.path[-1])
        assert sampled_min_distance(result.path, hulls) >= CLEAR - 1e-6
        assert result.tree_path is not None
        assert path_clearance(result.tree_path, hulls) >= CLEAR - 1e-9
    again = plan_path(START, GOAL, hulls, np.random.default_rng(3), CLEAR, AREA)
    assert guided[3].tree_path is not None and again.tree_path is not None
    np.testing.assert_array_equal(again.tree_path, guided[3].tree_path)  # still deterministic


def test_direct_line_when_free_and_start_in_goal() -> None:
    direct = plan_path(START, GOAL, (), np.random.default_rng(0), CLEAR, AREA)
    assert direct.status == "direct" and direct.iterations == 0
    np.testing.assert_array_equal(direct.path, [START, GOAL.center])
    inside = plan_path(np.array([880.0, 870.0]), GOAL, (), np.random.default_rng(0), CLEAR,
                       AREA)
    np.testing.assert_array_equal(inside.path, [[880.0, 870.0], GOAL.center])


def test_goal_covered_by_fire_is_a_result_not_an_error() -> None:
    hulls = (Rect(900.0, 900.0, 200.0, 200.0).polytope(),)
    proved = plan_path(START, GOAL, hulls, np.random.default_rng(0), CLEAR, AREA)
    assert proved.path is None and proved.status == "unreachable" and proved.iterations == 0
    params = RrtParams(max_iterations=300, reach_check=False)
    result = plan_path(START, GOAL, hulls, np.random.default_rng(0), CLEAR, AREA, params)
    assert result.path is None and not result.found
    assert result.status == "iteration_cap" and result.iterations == 300
    timed = plan_path(START, GOAL, hulls, np.random.default_rng(0), CLEAR, AREA,
                      RrtParams(max_iterations=10_000, max_cpu_s=1e-9, reach_check=False))
    assert timed.status == "time_cap" and timed.path is None


def test_escape_from_a_start_nearer_than_the_clearance() -> None:
    hull = Rect(100.0, 300.0, 100.0, 100.0).polytope()  # bottom face at y = 250
    start = np.array([100.0, 228.0])  # 22 m below it
    with pytest.raises(ValueError, match="from a fire hull"):
        plan_path(start, GOAL, (hull,), np.random.default_rng(0), CLEAR, AREA)
    result = plan_path(start, GOAL, (hull,), np.random.default_rng(0), CLEAR, AREA,
                       start_clearance_m=20.0)
    assert result.path is not None
    first = SegmentChecker([hull]).distances(result.path[:1], result.path[1:2])[0]
    assert first >= 22.0 - 1e-9  # the first edge never moves closer to the hull
    assert path_clearance(result.path[1:], (hull,)) >= CLEAR - 1e-9


def test_shortcut_straightens_a_zigzag() -> None:
    zigzag = np.array([[0.0, 0.0], [10.0, 5.0], [20.0, -5.0], [30.0, 5.0], [40.0, 0.0]])
    np.testing.assert_array_equal(shortcut(zigzag, SegmentChecker(()), CLEAR),
                                  [[0.0, 0.0], [40.0, 0.0]])
    wall = (Rect(20.0, 100.0, 4.0, 160.0).polytope(),)  # 20 m from the straight line
    bent = np.array([[0.0, 0.0], [20.0, -60.0], [40.0, 0.0]])
    assert path_clearance(bent, wall) > CLEAR
    np.testing.assert_array_equal(shortcut(bent, SegmentChecker(wall), CLEAR), bent)


def test_bad_input_raises() -> None:
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="finite"):
        plan_path(np.array([np.nan, 50.0]), GOAL, (), rng, CLEAR, AREA)
    with pytest.raises(ValueError, match="outside"):
        plan_path(np.array([-5.0, 50.0]), GOAL, (), rng, CLEAR, AREA)
    with pytest.raises(ValueError, match="goal .* outside"):
        plan_path(START, Rect(990.0, 500.0, 100.0, 100.0), (), rng, CLEAR, AREA)
    with pytest.raises(ValueError, match="from a fire hull"):
        plan_path(START, GOAL, (Rect(60.0, 60.0, 50.0, 50.0).polytope(),), rng, CLEAR, AREA)
    with pytest.raises(ValueError, match="from a fire hull"):  # outside, but within 25 m
        plan_path(START, GOAL, (Rect(95.0, 50.0, 50.0, 50.0).polytope(),), rng, CLEAR, AREA)
    with pytest.raises(ValueError, match="max_iterations"):
        RrtParams(max_iterations=0)

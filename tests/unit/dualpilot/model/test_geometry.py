"""Exact distances and corner-clipping checks on hand-drawn polygons."""

import numpy as np
import pytest

from dualpilot.model.geometry import Polytope, Rect, path_clearance


@pytest.fixture
def square():
    return Rect(0.0, 0.0, 2.0, 2.0).polytope()


def test_h_form_of_a_rectangle(square):
    assert square.n_faces == 4
    assert np.linalg.norm(square.A, axis=1) == pytest.approx(np.ones(4))
    assert square.b == pytest.approx(np.ones(4))
    assert square.contains([0.5, -0.9]) and not square.contains([1.1, 0.0])


def test_point_distances_by_hand(square):
    assert square.distance([3.0, 0.0]) == pytest.approx(2.0)
    assert square.distance([2.0, 2.0]) == pytest.approx(np.sqrt(2.0))
    assert square.distance([0.2, 0.3]) == 0.0


def test_segment_that_clips_a_corner_is_caught(square):
    # Both ends are outside and far from the square; the chord x + y = 1.9 cuts the
    # corner (1, 1): a check at the two endpoints alone would miss it.
    p0, p1 = np.array([-1.0, 2.9]), np.array([2.9, -1.0])
    assert square.distance(p0) > 0.9 and square.distance(p1) > 0.9
    assert square.segment_intersects(p0, p1)
    assert square.segment_distance(p0, p1) == 0.0


def test_segment_distance_by_hand(square):
    # Line x + y = 4.5 is |2 - 4.5| / sqrt(2) from the corner (1, 1).
    assert square.segment_distance([1.5, 3.0], [3.0, 1.5]) == pytest.approx(2.5 / np.sqrt(2))
    assert square.segment_distance([-3, 1.5], [3, 1.5]) == pytest.approx(0.5)


def test_hull_of_two_rectangles_has_six_faces_and_contains_both():
    a, b = Rect(0, 0, 2, 2), Rect(3, 3, 2, 2)
    hull = Polytope.from_vertices(np.vstack([a.corners(), b.corners()]))
    assert hull.n_faces == 6
    for p in np.vstack([a.corners(), b.corners()]):
        assert hull.contains(p, margin=1e-9)
    assert hull.contains([1.5, 1.5])  # between the two, inside the hull only


def test_path_clearance(square):
    path = np.array([[-5.0, 3.0], [5.0, 3.0], [5.0, -5.0]])
    assert path_clearance(path, [square]) == pytest.approx(2.0)
    assert path_clearance(path, []) == float("inf")


def test_bad_rectangles_and_hulls():
    with pytest.raises(ValueError, match="positive"):
        Rect(0, 0, -1, 2)
    with pytest.raises(ValueError, match="finite"):
        Rect(np.nan, 0, 1, 1)
    with pytest.raises(ValueError, match="collinear|3 distinct"):
        Polytope.from_vertices(np.array([[0, 0], [1, 1], [2, 2]]))


def test_rectangle_polytope_is_the_hull_of_its_corners_bit_for_bit():
    """Rect.polytope skips the hull (its corners already are one, counter-clockwise from the
    lowest corner): the same vertices, normals and offsets as Polytope.from_vertices."""
    rng = np.random.default_rng(7)
    for i in range(2000):
        r = Rect(*rng.uniform(-100.0, 1100.0, 2), *rng.uniform(0.01 if i % 2 else 50.0, 300.0, 2))
        got, want = r.polytope(), Polytope.from_vertices(r.corners())
        assert np.array_equal(got.vertices, want.vertices)
        assert np.array_equal(got.A, want.A) and np.array_equal(got.b, want.b)
        assert r.polytope() is got  # made once, then kept


def test_rectangle_distance_and_contains_equal_the_array_formulas():
    """The float forms give the numpy formulas' values exactly (distance by hand: 3-4-5)."""
    r = Rect(0.0, 0.0, 2.0, 2.0)
    assert r.distance([4.0, 5.0]) == 5.0 and r.distance([0.5, -0.5]) == 0.0
    assert r.contains([1.0, -1.0]) and not r.contains([1.0 + 1e-9, 0.0])
    assert r.contains([1.5, 0.0], margin=0.5) and not r.contains([0.0, -1.2], margin=0.1)
    rng = np.random.default_rng(8)
    for i in range(5000):
        r = Rect(*rng.uniform(0.0, 1000.0, 2), *rng.uniform(1.0, 300.0, 2))
        p = rng.uniform(-200.0, 1200.0, 2)
        if i % 4 == 0:  # on an edge
            p[0] = r.center_x + r.width / 2
        margin = (0.0, 1e-3, -2.0, 5.0)[i % 4]
        gap = np.maximum(0.0, np.maximum(r.lo - p, p - r.hi))
        assert r.distance(p) == float(np.hypot(gap[0], gap[1]))
        inside = bool(np.all(p >= r.lo - margin) and np.all(p <= r.hi + margin))
        assert r.contains(p, margin) == inside

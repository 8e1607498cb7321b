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

"""The exact 3-D hull of a front's cuboids: faces, the slanted roof, exact distances."""

import math

import numpy as np
import pytest

from dualpilot.model.geometry import Rect
from dualpilot.model.hull3d import Polytope3, point_triangle_d2
from dualpilot.model.prism import Prism


@pytest.fixture
def two():
    """A low and a tall cuboid 10 m apart: [-1, 1]² × [0, 2] and [9, 11] × [-1, 1] × [0, 6]."""
    return (Prism.cuboid(Rect(0.0, 0.0, 2.0, 2.0), 0.0, 2.0),
            Prism.cuboid(Rect(10.0, 0.0, 2.0, 2.0), 0.0, 6.0))


def _rows(a, b):
    return sorted(tuple(np.round(np.append(r, c), 9)) for r, c in zip(a, b, strict=True))


def test_a_cuboids_hull_is_the_cuboid():
    box = Prism.cuboid(Rect(0.0, 0.0, 2.0, 2.0), 0.0, 3.0)
    hull = Polytope3.hull_of([box])
    assert hull.n_faces == 6  # Qhull's twelve triangles merged into the paper's six faces
    assert _rows(hull.A, hull.b) == _rows(box.A, box.b)
    rng = np.random.default_rng(2)
    for _ in range(100):
        p, q = rng.uniform(-4.0, 6.0, size=(2, 3))
        assert hull.distance(p) == pytest.approx(box.distance(p), abs=1e-9)
        assert hull.segment_distance(p, q) == pytest.approx(box.segment_distance(p, q),
                                                            abs=1e-9)


def test_the_slanted_roof_by_hand(two):
    low, tall = two
    hull = Polytope3.hull_of([low, tall])
    # bottom, the two long sides, the two ends, the slanted roof z = 2 + 0.4 (x + 1) from
    # x = −1 to 9 (through the low box's far top edge and the tall one's near top edge),
    # and the tall box's flat top from x = 9 to 11
    assert hull.n_faces == 7
    assert hull.contains([4.0, 0.0, 3.9]) and not hull.contains([4.0, 0.0, 4.1])
    # 0.5 m above the roof at x = 4: 0.5 / √(1 + 0.4²) from the plane, whose foot
    # (4.17, 0, 4.07) lies on the roof
    assert hull.distance([4.0, 0.0, 4.5]) == pytest.approx(0.5 / math.sqrt(1.16), rel=1e-9)
    # the swept prism is a superset: that point is inside it
    assert Prism.swept([low, tall]).distance([4.0, 0.0, 4.5]) == 0.0
    # a segment along the roof 0.5 m above it, parallel to it: the same distance
    p0, p1 = [0.0, 0.0, 2.4 + 0.5 * math.sqrt(1.16)], [8.0, 0.0, 5.6 + 0.5 * math.sqrt(1.16)]
    assert hull.segment_distance(p0, p1) == pytest.approx(0.5, rel=1e-9)
    assert hull.segment_intersects([4.0, 0.0, 9.0], [4.0, 0.0, 3.0])


def test_point_triangle_distances_by_hand():
    a, b, c = (np.array(v, dtype=float) for v in ([0, 0, 0], [2, 0, 0], [0, 2, 0]))
    assert point_triangle_d2(np.array([0.5, 0.5, 3.0]), a, b, c) == pytest.approx(9.0)  # face
    assert point_triangle_d2(np.array([-3.0, -4.0, 0.0]), a, b, c) == pytest.approx(25.0)
    assert point_triangle_d2(np.array([1.0, -1.0, 1.0]), a, b, c) == pytest.approx(2.0)  # edge
    assert point_triangle_d2(np.array([2.0, 2.0, 0.0]), a, b, c) == pytest.approx(2.0)  # hyp.


def test_distances_against_dense_samples(two):
    hull = Polytope3.hull_of(list(two))
    rng = np.random.default_rng(4)
    ts = np.linspace(0.0, 1.0, 801)
    for _ in range(60):
        p0 = rng.uniform([-4, -4, -2], [14, 4, 10])
        p1 = p0 + rng.uniform(-8.0, 8.0, 3)
        exact = hull.segment_distance(p0, p1)
        sampled = min(hull.distance(p0 + t * (p1 - p0)) for t in ts)
        spacing = float(np.linalg.norm(p1 - p0)) / 800
        assert exact <= sampled + 1e-9
        assert sampled <= exact + spacing / 2 + 1e-9


def test_a_flat_set_has_no_hull():
    with pytest.raises(ValueError, match="no volume"):
        Polytope3.from_points([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    with pytest.raises(ValueError, match="finite"):
        Polytope3.from_points(np.array([[0, 0, math.nan], [1, 0, 0], [0, 1, 0], [0, 0, 1]]))


def test_with_one_height_the_exact_hull_is_the_swept_prism():
    rng = np.random.default_rng(8)
    cuboids = [Prism.cuboid(Rect(*rng.uniform(0.0, 50.0, 2), *rng.uniform(5.0, 20.0, 2)),
                            0.0, 30.0) for _ in range(4)]
    hull, swept = Polytope3.hull_of(cuboids), Prism.swept(cuboids)
    assert hull.n_faces == swept.n_faces
    assert _rows(hull.A, hull.b) == _rows(swept.A, swept.b)
    for p in rng.uniform([-20, -20, -10], [80, 80, 50], size=(100, 3)):
        assert hull.distance(p) == pytest.approx(swept.distance(p), abs=1e-9)

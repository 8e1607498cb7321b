"""Prisms in ℝ³ (the paper's six-face cuboids): H-form, exact distances, the 2-D case."""

import math

import numpy as np
import pytest

from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.geometry import Polytope, Rect, point_segment_d2
from dualpilot.model.prism import Prism, prism_clearance
from dualpilot.model.segment_kernels import segment_segment_d2


@pytest.fixture
def box():
    """[-1, 1]² × [0, 3]."""
    return Prism.cuboid(Rect(0.0, 0.0, 2.0, 2.0), 0.0, 3.0)


def _seg_d(p, q, a, b):
    p, q, a, b = (np.asarray(v, dtype=float) for v in (p, q, a, b))
    return math.sqrt(segment_segment_d2(p, q - p, a, b - a))


def _distances(prism, pts):
    """Each point's distance to the prism, from the planar edges and the altitude gap (m)."""
    v = prism.base.vertices
    e = np.roll(v, -1, axis=0) - v
    d2 = point_segment_d2(pts[:, :1], pts[:, 1:2], v[None, :, 0], v[None, :, 1],
                          e[None, :, 0], e[None, :, 1]).min(axis=1)
    inside = np.all(pts[:, :2] @ prism.base.A.T <= prism.base.b, axis=1)
    dz = np.maximum(0.0, np.maximum(prism.z_lo - pts[:, 2], pts[:, 2] - prism.z_hi))
    return np.sqrt(np.where(inside, 0.0, d2) + dz**2)


def _sampled(prism, p0, p1, n=4001):
    """The least distance of n points along p0–p1, and the spacing of the points (m)."""
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    ts = np.linspace(0.0, 1.0, n)[:, None]
    return (float(_distances(prism, p0 + ts * (p1 - p0)).min()),
            np.linalg.norm(p1 - p0) / (n - 1))


def test_the_cuboid_has_the_papers_six_faces(box):
    assert box.n_faces == 6
    # the rectangle's faces counter-clockwise from the lower left, then top and bottom
    assert box.A.tolist() == [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0],
                              [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]
    assert box.b.tolist() == [1.0, 1.0, 1.0, 1.0, 3.0, -0.0]
    assert box.contains([0.5, -0.9, 2.9]) and not box.contains([0.5, -0.9, 3.1])
    assert box.margins([[0.0, 0.0, 5.0], [0.0, 0.0, 1.0]]).tolist() == [2.0, -1.0]
    lo, hi = box.box
    assert lo.tolist() == [-1.0, -1.0, 0.0] and hi.tolist() == [1.0, 1.0, 3.0]
    assert len(box.vertices) == 8 and len(box.edges[0]) == 12
    with pytest.raises(ValueError, match="z_lo < z_hi"):
        Prism.cuboid(Rect(0.0, 0.0, 2.0, 2.0), 3.0, 3.0)


def test_point_distances_by_hand(box):
    assert box.distance([0.0, 0.0, 5.0]) == 2.0  # above the top
    assert box.distance([3.0, 0.0, 1.0]) == 2.0  # beside a side face
    assert box.distance([2.0, 2.0, 4.0]) == pytest.approx(math.sqrt(3.0))  # off a corner
    assert box.distance([0.2, 0.3, 1.0]) == 0.0


def test_segment_distances_by_hand(box):
    # over the top, 1 m above it
    assert box.segment_distance([-5.0, 0.0, 4.0], [5.0, 0.0, 4.0]) == pytest.approx(1.0)
    # passing a top edge (y = 1, z = 3) at √2: the line y + z = 6 in the yz-plane, nearest
    # at (0, 2, 4), inside the segment; both ends are 2 m away
    p0, p1 = [0.0, 3.0, 3.0], [0.0, 1.0, 5.0]
    assert box.distance(p0) == 2.0 and box.distance(p1) == 2.0
    assert box.segment_distance(p0, p1) == pytest.approx(math.sqrt(2.0))
    # diving through the top
    assert box.segment_intersects([0.0, 0.0, 5.0], [0.5, 0.5, 2.0])
    assert box.segment_distance([0.0, 0.0, 5.0], [0.5, 0.5, 2.0]) == 0.0
    # passing the corner (1, 1, 3) at √2 mid-way, (2, 2, 3), its ends √40 and √13 away
    p0, p1 = [3.0, 1.0, 9.0], [1.0, 3.0, -3.0]
    assert box.distance(p0) == pytest.approx(math.sqrt(40.0))
    assert box.distance(p1) == pytest.approx(math.sqrt(13.0))
    assert box.segment_distance(p0, p1) == pytest.approx(math.sqrt(2.0))


def test_segment_distance_against_dense_samples():
    rng = np.random.default_rng(5)
    hull = Polytope.from_vertices(rng.uniform(-3.0, 3.0, size=(9, 2)))
    prism = Prism(hull, 10.0, 40.0)
    for _ in range(300):
        p0 = rng.uniform([-8, -8, -5], [8, 8, 55])
        p1 = p0 + rng.uniform(-15.0, 15.0, 3)
        exact = prism.segment_distance(p0, p1)
        assert _distances(prism, p0[None])[0] == pytest.approx(prism.distance(p0), abs=1e-9)
        sampled, spacing = _sampled(prism, p0, p1)
        assert exact <= sampled + 1e-9
        assert sampled <= exact + spacing / 2 + 1e-9


def test_inside_its_altitudes_a_prism_is_its_base_bit_for_bit():
    """Where the UAV's altitude lies within a prism's, every distance is the planar one: a
    cuboid taller than the band gives the top-down evaluation's numbers exactly."""
    rng = np.random.default_rng(7)
    rect = Rect(500.0, 400.0, 180.0, 120.0)
    prism = Prism.cuboid(rect, 0.0, 145.0)
    poly = rect.polytope()
    for _ in range(300):
        a, c = rng.uniform(0.0, 1000.0, 2), rng.uniform(0.0, 1000.0, 2)
        za, zc = rng.uniform(20.0, 120.0, 2)
        assert prism.distance([*a, za]) == poly.distance(a)
        assert prism.segment_distance([*a, za], [*c, zc]) == poly.segment_distance(a, c)


def test_segment_segment_distances_by_hand():
    assert _seg_d([-1, 0, 0], [1, 0, 0], [0, -1, 1], [0, 1, 1]) == pytest.approx(1.0)  # skew
    assert _seg_d([0, 0, 0], [2, 0, 0], [1, 1, 0], [3, 1, 0]) == pytest.approx(1.0)  # parallel
    assert _seg_d([0, 0, 0], [1, 0, 0], [3, 1, 0], [4, 1, 0]) == pytest.approx(math.sqrt(5))
    assert _seg_d([0, 0, 0], [0, 0, 0], [3, 4, 0], [3, 4, 0]) == pytest.approx(5.0)  # points
    assert _seg_d([0, 0, 0], [0, 0, 0], [3, -4, 0], [3, 4, 0]) == pytest.approx(3.0)
    assert _seg_d([0, 0, 0], [2, 2, 2], [0, 2, 0], [2, 0, 2]) == pytest.approx(0.0)  # crossing


def test_segment_segment_distance_against_dense_samples():
    rng = np.random.default_rng(9)
    ts = np.linspace(0.0, 1.0, 201)
    for _ in range(100):
        p, q, a, b = rng.uniform(-5.0, 5.0, size=(4, 3))
        if rng.random() < 0.2:  # near-parallel pairs too
            b = a + (q - p) * rng.uniform(0.5, 2.0) + rng.normal(0.0, 1e-9, 3)
        exact = _seg_d(p, q, a, b)
        s1 = p + ts[:, None] * (q - p)
        s2 = a + ts[:, None] * (b - a)
        sampled = float(np.min(np.linalg.norm(s1[:, None] - s2[None], axis=2)))
        spacing = (np.linalg.norm(q - p) + np.linalg.norm(b - a)) / 200
        assert exact <= sampled + 1e-9
        assert sampled <= exact + spacing + 1e-9


def test_the_swept_prism_holds_every_cuboid():
    a = Prism.cuboid(Rect(0.0, 0.0, 2.0, 2.0), 0.0, 2.0)
    b = Prism.cuboid(Rect(10.0, 0.0, 2.0, 2.0), 0.0, 6.0)
    s = a.extended(b)
    assert (s.z_lo, s.z_hi) == (0.0, 6.0) and s.base.n_faces == 4
    for corner in np.vstack([a.vertices, b.vertices]):
        assert s.contains(corner, margin=1e-9)
    assert s.contains([5.0, 0.0, 5.0])  # between the two, above the lower one
    assert Prism.swept([a]) is a
    with pytest.raises(ValueError, match="at least one"):
        Prism.swept([])


def test_spans_and_the_faces_that_can_be_escaped_through(box):
    band = AltitudeBand()
    tall = Prism.cuboid(Rect(0.0, 0.0, 2.0, 2.0), 0.0, band.above_ceiling_m(25.0))
    assert tall.spans(band) and not box.spans(band)
    # only the four sides: the top lies above the band (145 + 25 > 120), the bottom below
    assert tall.escape_faces(band, 25.0).tolist() == [0, 1, 2, 3]
    low = Prism.cuboid(Rect(0.0, 0.0, 2.0, 2.0), 0.0, 11.0)
    assert low.escape_faces(band, 25.0).tolist() == [0, 1, 2, 3, 4]  # over it at 36 m
    assert low.escape_faces(band, 110.0).tolist() == [0, 1, 2, 3]


def test_polyline_clearance(box):
    pts = [[-5.0, 0.0, 4.0], [0.0, 0.0, 4.0], [0.0, 5.0, 4.0]]
    assert prism_clearance(pts, [box]) == pytest.approx(1.0)
    assert prism_clearance(pts[:1], [box]) == pytest.approx(math.hypot(4.0, 1.0))
    assert prism_clearance(pts, []) == math.inf

"""SegmentChecker3 (dualpilot/model/segment3.py): exact 3-D distances, the planar ones bit for bit
within a prism's altitudes."""

from __future__ import annotations

import numpy as np
import pytest

from dualpilot.model.geometry import Polytope, Rect, SegmentChecker
from dualpilot.model.prism import Cuboid, Prism
from dualpilot.model.segment3 import SegmentChecker3, prism_path_clearance


def _clear(check: SegmentChecker3, a: np.ndarray, b: np.ndarray, need: float) -> bool:
    return check.segment_clear(float(a[0]), float(a[1]), float(a[2]), float(b[0]),
                               float(b[1]), float(b[2]), need)


def _prisms(rng: np.random.Generator, n: int, top: tuple[float, float]) -> list[Prism]:
    out = []
    for _ in range(n):
        base = Polytope.from_vertices(rng.uniform(0.0, 300.0, (8, 2)))
        out.append(Prism(base, 0.0, float(rng.uniform(*top))))
    return out


def test_by_hand_over_a_low_fire() -> None:
    """A 10 m fire 100 m wide: a UAV crossing at 40 m keeps 30 m, at 25 m keeps 15 m."""
    fire = Cuboid(Rect(500.0, 500.0, 100.0, 100.0), 10.0).prism
    check = SegmentChecker3([fire])
    a, b = np.array([400.0, 500.0, 40.0]), np.array([600.0, 500.0, 40.0])
    assert check.distances(a[None], b[None])[0] == pytest.approx(30.0, abs=1e-12)
    assert _clear(check, a, b, 20.0) and not _clear(check, a, b, 30.5)
    low = np.array([0.0, 0.0, -15.0])
    assert check.distances((a + low)[None], (b + low)[None])[0] == pytest.approx(15.0)
    assert not _clear(check, a + low, b + low, 20.0)
    # through it: 0; a point beside its top edge at (3, 4) m: 5 m
    assert check.distances(np.array([[500.0, 500.0, 5.0]]),
                           np.array([[500.0, 500.0, 50.0]]))[0] == 0.0
    assert check.point_distance(np.array([553.0, 500.0, 14.0])) == pytest.approx(5.0)
    assert check.path_clearance(np.array([[400.0, 500.0, 40.0]])) == pytest.approx(
        fire.distance([400.0, 500.0, 40.0]))


def test_against_the_prisms_exact_distances() -> None:
    rng = np.random.default_rng(3)
    prisms = _prisms(rng, 6, (5.0, 150.0))
    check = SegmentChecker3(prisms)
    a = np.column_stack([rng.uniform(-50.0, 350.0, (3000, 2)), rng.uniform(0.0, 200.0, 3000)])
    b = a + rng.normal(0.0, 30.0, (3000, 3))
    got = check.distances(a, b)
    want = np.array([min(p.segment_distance(x, y) for p in prisms)
                     for x, y in zip(a, b, strict=True)])
    np.testing.assert_allclose(got, want, rtol=0.0, atol=1e-9)
    for need in (5.0, 20.0):
        clear = check.clear(a, b, need)
        one = np.array([_clear(check, x, y, need) for x, y in zip(a, b, strict=True)])
        sure = np.abs(want - need) > 1e-9  # away from the boundary, every test agrees
        assert np.array_equal(clear[sure], (want >= need)[sure])
        assert np.array_equal(one[sure], (want >= need)[sure])
    points = [check.point_distance(x) for x in a[:300]]
    np.testing.assert_allclose(points, [min(p.distance(x) for p in prisms) for x in a[:300]],
                               rtol=0.0, atol=1e-9)


def test_within_the_prisms_altitudes_the_planar_numbers_bit_for_bit() -> None:
    rng = np.random.default_rng(4)
    bases = [p.base for p in _prisms(rng, 7, (1.0, 2.0))]
    flat = SegmentChecker(bases)
    tall = SegmentChecker3([Prism(b, 0.0, 145.0) for b in bases])
    a = np.column_stack([rng.uniform(-50.0, 350.0, (3000, 2)), rng.uniform(20.0, 120.0, 3000)])
    b = np.column_stack([a[:, :2] + rng.normal(0.0, 30.0, (3000, 2)), a[:, 2]])
    assert np.array_equal(tall.distances(a, b), flat.distances(a[:, :2], b[:, :2]))
    assert np.array_equal(tall.clear(a, b, 20.0), flat.clear(a[:, :2], b[:, :2], 20.0))
    assert all(_clear(tall, x, y, 20.0) == flat.segment_clear(x[0], x[1], y[0], y[1], 20.0)
               for x, y in zip(a[:500], b[:500], strict=True))
    assert all(tall.point_distance(x) == flat.point_distance(x[:2]) for x in a[:500])
    pts = a[:12]
    assert tall.path_clearance(pts) == flat.path_clearance(pts[:, :2])


def test_no_prisms() -> None:
    check = SegmentChecker3([])
    a = np.zeros((2, 3))
    assert np.all(np.isinf(check.distances(a, a + 1.0)))
    assert check.clear(a, a + 1.0, 5.0).all() and check.segment_clear(0, 0, 0, 1, 1, 1, 5.0)
    assert prism_path_clearance(a, []) == float("inf")

"""Planar convex geometry: rectangles, convex polygons as H-polytopes, exact distances.

A convex polygon is kept in both forms: H-form {p : α_l · p ≤ β_l} with unit
outward normals α_l (the form of Eq. (P2_3)), and its vertices in
counter-clockwise order. All lengths are metres.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Rect:
    """Axis-aligned rectangle given by its centre and full side lengths (m)."""

    center_x: float
    center_y: float
    width: float
    height: float

    def __post_init__(self) -> None:
        vals = (self.center_x, self.center_y, self.width, self.height)
        if not all(np.isfinite(vals)):
            raise ValueError(f"rectangle must be finite: {self}")
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"rectangle sides must be positive: {self}")

    @property
    def center(self) -> Array:
        return np.array([self.center_x, self.center_y])

    @property
    def lo(self) -> Array:
        return np.array([self.center_x - self.width / 2, self.center_y - self.height / 2])

    @property
    def hi(self) -> Array:
        return np.array([self.center_x + self.width / 2, self.center_y + self.height / 2])

    def corners(self) -> Array:
        """The four corners, counter-clockwise from the lower left, shape (4, 2)."""
        (x0, y0), (x1, y1) = self.lo, self.hi
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])

    def contains(self, p: ArrayLike, margin: float = 0.0) -> bool:
        p = np.asarray(p, dtype=float)[:2]
        return bool(np.all(p >= self.lo - margin) and np.all(p <= self.hi + margin))

    def inside(self, outer: Rect) -> bool:
        """True if this rectangle lies within ``outer``."""
        return bool(np.all(self.lo >= outer.lo) and np.all(self.hi <= outer.hi))

    def polytope(self) -> Polytope:
        return Polytope.from_vertices(self.corners())


def _cross(o: Array, a: Array, b: Array) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def convex_hull_vertices(points: Array) -> Array:
    """Counter-clockwise hull vertices of 2-D points (Andrew's monotone chain), shape (k, 2)."""
    pts = np.unique(np.asarray(points, dtype=float).reshape(-1, 2), axis=0)
    if len(pts) < 3:
        raise ValueError("a convex hull needs at least 3 distinct points")
    lower: list[Array] = []
    for p in pts:
        while len(lower) >= 2 and _cross(lower[-2], lower[-1], p) <= 1e-9:
            lower.pop()
        lower.append(p)
    upper: list[Array] = []
    for p in pts[::-1]:
        while len(upper) >= 2 and _cross(upper[-2], upper[-1], p) <= 1e-9:
            upper.pop()
        upper.append(p)
    hull = np.array(lower[:-1] + upper[:-1])
    if len(hull) < 3:
        raise ValueError("points are collinear: the hull has no interior")
    return hull


@dataclass(frozen=True)
class Polytope:
    """Convex polygon {p : A p ≤ b}; rows of A are unit outward normals α_l, b holds β_l."""

    vertices: Array
    A: Array = field(repr=False)
    b: Array = field(repr=False)

    @staticmethod
    def from_vertices(points: Array) -> Polytope:
        """The convex hull of ``points`` (any order, duplicates allowed)."""
        v = convex_hull_vertices(points)
        edges = np.roll(v, -1, axis=0) - v
        normals = np.column_stack([edges[:, 1], -edges[:, 0]])  # outward for CCW order
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        b = np.einsum("ij,ij->i", normals, v)
        return Polytope(vertices=v, A=normals, b=b)

    @property
    def n_faces(self) -> int:
        return len(self.b)

    def contains(self, p: ArrayLike, margin: float = 0.0) -> bool:
        """True if p satisfies every face inflated by ``margin`` (α·p ≤ β + margin)."""
        return bool(np.all(self.A @ np.asarray(p, dtype=float)[:2] <= self.b + margin))

    def distance(self, p: ArrayLike) -> float:
        """Euclidean distance from p to the polygon (0 inside)."""
        p = np.asarray(p, dtype=float)[:2]
        if np.all(self.A @ p <= self.b):
            return 0.0
        a = self.vertices
        c = np.roll(a, -1, axis=0)
        return float(np.min(_point_segment_distances(p, a, c)))

    def distances(self, points: Array) -> Array:
        """Distance from each row of ``points`` (shape (n, 2)) to the polygon."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        return np.array([self.distance(p) for p in pts])

    def segment_distance(self, p0: ArrayLike, p1: ArrayLike) -> float:
        """Exact distance from segment p0–p1 to the polygon (0 if they intersect)."""
        p0 = np.asarray(p0, dtype=float)[:2]
        p1 = np.asarray(p1, dtype=float)[:2]
        if self.segment_intersects(p0, p1):
            return 0.0
        a = self.vertices
        c = np.roll(a, -1, axis=0)
        d_ends = min(
            float(np.min(_point_segment_distances(p0, a, c))),
            float(np.min(_point_segment_distances(p1, a, c))),
        )
        d_verts = float(np.min(_point_segment_distances_many(a, p0, p1)))
        return min(d_ends, d_verts)

    def segment_intersects(self, p0: ArrayLike, p1: ArrayLike) -> bool:
        """Cyrus–Beck clipping: does segment p0–p1 meet the closed polygon?"""
        p0 = np.asarray(p0, dtype=float)[:2]
        d = np.asarray(p1, dtype=float)[:2] - p0
        t_lo, t_hi = 0.0, 1.0
        num = self.b - self.A @ p0
        den = self.A @ d
        for n_l, d_l in zip(num, den, strict=True):
            if abs(d_l) < 1e-12:
                if n_l < 0:
                    return False
                continue
            t = n_l / d_l
            if d_l > 0:
                t_hi = min(t_hi, t)
            else:
                t_lo = max(t_lo, t)
            if t_lo > t_hi:
                return False
        return True


def _point_segment_distances(p: Array, a: Array, c: Array) -> Array:
    """Distances from point p to each segment a[i]–c[i]."""
    ac = c - a
    len2 = np.einsum("ij,ij->i", ac, ac)
    t = np.clip(np.einsum("ij,ij->i", p - a, ac) / np.where(len2 > 0, len2, 1.0), 0.0, 1.0)
    proj = a + t[:, None] * ac
    return np.asarray(np.linalg.norm(p - proj, axis=1))


def _point_segment_distances_many(points: Array, a: Array, c: Array) -> Array:
    """Distances from each point to the single segment a–c."""
    ac = c - a
    len2 = float(ac @ ac)
    t = np.clip(((points - a) @ ac) / (len2 if len2 > 0 else 1.0), 0.0, 1.0)
    proj = a + t[:, None] * ac
    return np.asarray(np.linalg.norm(points - proj, axis=1))


def min_distance(p: ArrayLike, polytopes: Iterable[Polytope]) -> float:
    """Distance from p to the nearest polytope (inf when there are none)."""
    return min((poly.distance(p) for poly in polytopes), default=float("inf"))


def path_clearance(points: Array, polytopes: Sequence[Polytope]) -> float:
    """Smallest distance from the polyline through ``points`` to any polytope (inf if none).

    Every segment is checked exactly, so a path cannot clip a corner unseen.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if not polytopes:
        return float("inf")
    if len(pts) == 1:
        return min_distance(pts[0], polytopes)
    best = float("inf")
    for poly in polytopes:
        lo, hi = poly.vertices.min(axis=0), poly.vertices.max(axis=0)
        for p0, p1 in zip(pts[:-1], pts[1:], strict=True):
            # bounding-box lower bound: skip segments that are clearly farther than `best`
            seg_lo, seg_hi = np.minimum(p0, p1), np.maximum(p0, p1)
            gap = np.maximum(0.0, np.maximum(lo - seg_hi, seg_lo - hi))
            if float(np.hypot(*gap)) >= best:
                continue
            best = min(best, poly.segment_distance(p0, p1))
            if best == 0.0:
                return 0.0
    return best

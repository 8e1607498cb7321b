"""Planar convex geometry: rectangles, convex polygons as H-polytopes, exact distances.

A convex polygon is kept in both forms: H-form {p : α_l · p ≤ β_l} with unit
outward normals α_l (the form of Eq. (P2_3)), and its vertices in
counter-clockwise order. All lengths are metres.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from dualpilot.arrays import AnyArray, Array
from dualpilot.lazy import lazy_module

#: the polygons' Numba kernels (dualpilot.model.hull_kernels), loaded at their first use
_hull_kernels = lazy_module("dualpilot.model.hull_kernels")


@dataclass(frozen=True)
class Rect:
    """Axis-aligned rectangle given by its centre and full side lengths (m)."""

    center_x: float
    center_y: float
    width: float
    height: float

    def __post_init__(self) -> None:
        vals = (self.center_x, self.center_y, self.width, self.height)
        if not all(math.isfinite(v) for v in vals):
            raise ValueError(f"rectangle must be finite: {self}")
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"rectangle sides must be positive: {self}")

    @property
    def center(self) -> Array:
        return np.array([self.center_x, self.center_y])

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x_lo, y_lo, x_hi, y_hi) (m)."""
        hw, hh = self.width / 2, self.height / 2
        return (self.center_x - hw, self.center_y - hh, self.center_x + hw, self.center_y + hh)

    @property
    def lo(self) -> Array:
        return np.array(self.bounds[:2])

    @property
    def hi(self) -> Array:
        return np.array(self.bounds[2:])

    def corners(self) -> Array:
        """The four corners, counter-clockwise from the lower left, shape (4, 2)."""
        x0, y0, x1, y1 = self.bounds
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])

    def contains(self, p: ArrayLike, margin: float = 0.0) -> bool:
        x, y = _xy(p)
        x0, y0, x1, y1 = self.bounds
        return x0 - margin <= x <= x1 + margin and y0 - margin <= y <= y1 + margin

    def distance(self, p: ArrayLike) -> float:
        """Euclidean distance from p to the rectangle (0 inside)."""
        x, y = _xy(p)
        x0, y0, x1, y1 = self.bounds
        gx = max(0.0, max(x0 - x, x - x1))
        gy = max(0.0, max(y0 - y, y - y1))
        return float(np.hypot(gx, gy))

    def inside(self, outer: Rect) -> bool:
        """True if this rectangle lies within ``outer``."""
        return bool(np.all(self.lo >= outer.lo) and np.all(self.hi <= outer.hi))

    def polytope(self) -> Polytope:
        """The rectangle as a :class:`Polytope` (made on the first call, then kept)."""
        return self._polytope

    @cached_property
    def _polytope(self) -> Polytope:
        # the corners are already the hull, counter-clockwise from the lowest (x, y)
        corners = self.corners()
        normals, b = _hull_kernels().faces(corners)
        return Polytope(vertices=corners, A=normals, b=b)


def _xy(p: ArrayLike) -> tuple[float, float]:
    """The first two coordinates of a point as floats (m)."""
    q = np.asarray(p, dtype=float)
    return float(q[0]), float(q[1])


def convex_hull_vertices(points: Array) -> Array:
    """Counter-clockwise hull vertices of 2-D points (Andrew's monotone chain), shape (k, 2)."""
    pts = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 2))
    hull, distinct = _hull_kernels().monotone_chain(pts)
    if distinct < 3:
        raise ValueError("a convex hull needs at least 3 distinct points")
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
        normals, b = _hull_kernels().faces(v)
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
        return float(np.sqrt(np.min(self._edge_d2(p))))

    def _edge_d2(self, p: Array) -> Array:
        """Squared distances (m²) from point p to each edge."""
        a, e = self.vertices, self._edges
        return point_segment_d2(p[0], p[1], a[:, 0], a[:, 1], e[:, 0], e[:, 1])

    @cached_property
    def _edges(self) -> Array:
        """The edge vectors a_{l+1} − a_l (m), made on first use and kept."""
        a = self.vertices
        e = np.empty_like(a)
        e[:-1] = a[1:] - a[:-1]
        e[-1] = a[0] - a[-1]
        return e

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
        s = p1 - p0
        d2_verts = point_segment_d2(a[:, 0], a[:, 1], p0[0], p0[1], s[0], s[1])
        d2 = min(float(np.min(self._edge_d2(p0))), float(np.min(self._edge_d2(p1))),
                 float(np.min(d2_verts)))
        return float(np.sqrt(d2))

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


def point_segment_d2(px: Array | float, py: Array | float, ax: Array | float,
                     ay: Array | float, dx: Array | float, dy: Array | float,
                     inv_len2: Array | float | None = None) -> Array:
    """Squared distance (m²) from points (px, py) to segments a → a + d, broadcast.

    The one point-to-segment distance of the package; ``inv_len2`` may carry
    1 / ‖d‖² (1 for a zero-length segment) when it is reused.
    """
    if inv_len2 is None:
        len2 = np.multiply(dx, dx) + np.multiply(dy, dy)
        inv_len2 = 1.0 / np.where(len2 > 0, len2, 1.0)
    t = np.minimum(np.maximum(((px - ax) * dx + (py - ay) * dy) * inv_len2, 0.0), 1.0)
    ex = px - ax - t * dx
    ey = py - ay - t * dy
    return np.asarray(ex * ex + ey * ey)


def hull_boxes(hulls: Sequence[Polytope]) -> tuple[Array, Array]:
    """Lower and upper corners (H, 2) of each hull's bounding box (m)."""
    if not hulls:
        return np.zeros((0, 2)), np.zeros((0, 2))
    v = np.vstack([h.vertices for h in hulls])
    starts = _starts(hulls)
    return np.minimum.reduceat(v, starts, axis=0), np.maximum.reduceat(v, starts, axis=0)


def _starts(hulls: Sequence[Polytope]) -> AnyArray:
    """The first row of each hull's vertices (or faces) when they are stacked."""
    return np.concatenate([[0], np.cumsum([len(h.b) for h in hulls[:-1]])]).astype(np.int64)


def path_clearance(points: Array, polytopes: Sequence[Polytope]) -> float:
    """Smallest distance from the polyline through ``points`` to any polytope (inf if none).

    Every segment is checked exactly, so a path cannot clip a corner unseen.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if not polytopes:
        return float("inf")
    return SegmentChecker(polytopes).path_clearance(pts)


class SegmentChecker:
    """Exact segment-to-hulls distances, vectorised over segments and hull edges.

    For a segment that neither crosses an edge nor starts inside a hull, the
    distance to a convex polygon is the smallest of its endpoints' distances
    to the polygon's edges and the polygon's vertices' distances to the
    segment; otherwise it is 0. This equals ``Polytope.segment_distance``
    (the unit tests check that) at a fraction of the cost.
    """

    def __init__(self, hulls: Sequence[Polytope]):
        self.n_hulls = len(hulls)
        self._hulls = tuple(hulls)
        self._all = _HullEdges(hulls) if hulls else None
        self._box_lo, self._box_hi = hull_boxes(hulls)

    # plain-float boxes, faces (nx, ny, β) and vertices for the scalar tests, made on first use
    @cached_property
    def _boxes(self) -> list[tuple[float, float, float, float]]:
        return [(float(a[0]), float(a[1]), float(b[0]), float(b[1]))
                for a, b in zip(self._box_lo, self._box_hi, strict=True)]

    @cached_property
    def _faces(self) -> list[list[tuple[float, float, float]]]:
        return [list(zip(h.A[:, 0].tolist(), h.A[:, 1].tolist(), h.b.tolist(), strict=True))
                for h in self._hulls]

    @cached_property
    def _verts(self) -> list[list[tuple[float, float]]]:
        return [[(float(x), float(y)) for x, y in h.vertices.tolist()] for h in self._hulls]

    def segment_clear(self, x0: float, y0: float, x1: float, y1: float, need_m: float) -> bool:
        """Whether the single segment (x0, y0)–(x1, y1) keeps ``need_m`` from every hull.

        Plain Python (one segment is too small for numpy): bounding boxes
        settle most hulls, a face line with both endpoints ``need_m`` beyond it
        most of the rest, and only segments near a hull get the exact test
        (:func:`_segment_near_polygon`).
        """
        lox, hix = (x0, x1) if x0 <= x1 else (x1, x0)
        loy, hiy = (y0, y1) if y0 <= y1 else (y1, y0)
        need2 = need_m * need_m
        for i, (bx0, by0, bx1, by1) in enumerate(self._boxes):
            gx = max(0.0, bx0 - hix, lox - bx1)
            gy = max(0.0, by0 - hiy, loy - by1)
            if gx * gx + gy * gy >= need2:
                continue
            faces = self._faces[i]
            if any(nx * x0 + ny * y0 - b >= need_m and nx * x1 + ny * y1 - b >= need_m
                   for nx, ny, b in faces):
                continue
            if _segment_near_polygon(x0, y0, x1, y1, faces, self._verts[i], need_m):
                return False
        return True

    def clear(self, p0: Array, p1: Array, need_m: float) -> Array:
        """Whether each segment p0[i]–p1[i] keeps ``need_m`` from every hull (bool (n,))."""
        p0 = np.atleast_2d(np.asarray(p0, dtype=float))
        p1 = np.atleast_2d(np.asarray(p1, dtype=float))
        if self.n_hulls == 0:
            return np.ones(len(p0), dtype=bool)
        seg_lo = np.minimum(p0, p1)[:, None]
        seg_hi = np.maximum(p0, p1)[:, None]
        gap = np.maximum(0.0, np.maximum(self._box_lo[None] - seg_hi, seg_lo - self._box_hi[None]))
        lower = np.sqrt(np.min(np.sum(gap * gap, axis=-1), axis=1))
        ok = lower >= need_m
        todo = np.nonzero(~ok)[0]
        if len(todo):
            ok[todo] = self.distances(p0[todo], p1[todo]) >= need_m
        return ok

    def distances(self, p0: Array, p1: Array) -> Array:
        """Distance from each segment p0[i]–p1[i] (arrays (n, 2)) to the nearest hull (or inf)."""
        p0 = np.atleast_2d(np.asarray(p0, dtype=float))
        p1 = np.atleast_2d(np.asarray(p1, dtype=float))
        if self._all is None:
            return np.full(len(p0), np.inf)
        return self._all.distances(p0, p1)

    def point_distance(self, p: Array) -> float:
        """Distance from point p to the nearest hull (inf if none), in plain floats.

        Hulls are visited nearest bounding box first; one whose box is already
        farther than the best distance so far cannot be nearer.
        """
        x, y = float(p[0]), float(p[1])
        boxes = []
        for i, (bx0, by0, bx1, by1) in enumerate(self._boxes):
            gx = max(0.0, bx0 - x, x - bx1)
            gy = max(0.0, by0 - y, y - by1)
            boxes.append((gx * gx + gy * gy, i))
        best2 = float("inf")
        for box2, i in sorted(boxes):
            if box2 >= best2:
                break
            best2 = min(best2, _point_polygon_distance2(x, y, self._faces[i], self._verts[i]))
        return best2 ** 0.5

    def path_clearance(self, points: Array) -> float:
        """Smallest distance from the polyline through ``points`` (k, 2) to any hull."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        if len(pts) == 1:
            return self.point_distance(pts[0])
        return float(np.min(self.distances(pts[:-1], pts[1:])))


def _point_edge_d2(px: float, py: float, ax: float, ay: float, ex: float, ey: float) -> float:
    """:func:`point_segment_d2` for one point and one segment, in plain floats.

    Kept apart for the per-motion checks of the RRT, where numpy's per-call
    overhead would cost more than the arithmetic.
    """
    e2 = ex * ex + ey * ey
    t = ((px - ax) * ex + (py - ay) * ey) / e2 if e2 > 0.0 else 0.0
    t = 0.0 if t < 0.0 else 1.0 if t > 1.0 else t
    dx, dy = px - ax - t * ex, py - ay - t * ey
    return dx * dx + dy * dy


def _edges(verts: list[tuple[float, float]]) -> Iterator[tuple[float, float, float, float]]:
    """(a_x, a_y, e_x, e_y) of every edge a → a + e of a closed polygon."""
    k = len(verts)
    for j in range(k):
        ax, ay = verts[j]
        bx, by = verts[j + 1 if j + 1 < k else 0]
        yield ax, ay, bx - ax, by - ay


def _point_polygon_distance2(x: float, y: float, faces: list[tuple[float, float, float]],
                             verts: list[tuple[float, float]]) -> float:
    """Squared distance (m²) from (x, y) to a convex polygon: 0 inside, else to the nearest edge."""
    if all(nx * x + ny * y - b <= 0.0 for nx, ny, b in faces):
        return 0.0
    return min(_point_edge_d2(x, y, ax, ay, ex, ey) for ax, ay, ex, ey in _edges(verts))


def _segment_near_polygon(x0: float, y0: float, x1: float, y1: float,
                          faces: list[tuple[float, float, float]],
                          verts: list[tuple[float, float]], need_m: float) -> bool:
    """Whether segment p0–p1 comes nearer than ``need_m`` to a convex polygon (plain floats).

    True when the segment meets the polygon (Cyrus–Beck clipping against the
    faces) or when an endpoint-to-edge or vertex-to-segment distance, the
    candidates of :class:`_HullEdges`, is below ``need_m``; it stops at the
    first such pair.
    """
    t_in, t_out = 0.0, 1.0
    sx, sy = x1 - x0, y1 - y0
    for nx, ny, b in faces:
        s0 = nx * x0 + ny * y0 - b
        ds = nx * sx + ny * sy
        if ds == 0.0:
            if s0 > 0.0:
                t_in = 2.0  # parallel and outside this face: no intersection
        elif ds < 0.0:
            if -s0 / ds > t_in:
                t_in = -s0 / ds
        elif -s0 / ds < t_out:
            t_out = -s0 / ds
        if t_in > t_out:
            break
    else:
        return True  # the clipped interval is not empty: the segment meets the polygon
    need2 = need_m * need_m
    for ax, ay, ex, ey in _edges(verts):
        if (_point_edge_d2(x0, y0, ax, ay, ex, ey) < need2
                or _point_edge_d2(x1, y1, ax, ay, ex, ey) < need2
                or _point_edge_d2(ax, ay, x0, y0, sx, sy) < need2):
            return True
    return False


class _HullEdges:
    """Edges and faces of one or more hulls as flat arrays (components split for speed)."""

    def __init__(self, hulls: Sequence[Polytope]):
        self._kernel = _hull_kernels().hull_distances
        a = np.vstack([h.vertices for h in hulls])
        starts = _starts(hulls)
        following = np.arange(1, len(a) + 1)  # each vertex's successor, around its own hull
        following[np.append(starts[1:], len(a)) - 1] = starts
        c = a[following]
        self.ax, self.ay = a[:, 0].copy(), a[:, 1].copy()
        self.dx, self.dy = c[:, 0] - a[:, 0], c[:, 1] - a[:, 1]
        len2 = self.dx**2 + self.dy**2
        self.inv_len2 = 1.0 / np.where(len2 > 0, len2, 1.0)
        normals = np.vstack([h.A for h in hulls])
        self.nx, self.ny = normals[:, 0].copy(), normals[:, 1].copy()
        self.offsets = np.concatenate([h.b for h in hulls])
        self.starts = starts

    def distances(self, p0: Array, p1: Array) -> Array:
        return self._kernel(np.ascontiguousarray(p0, dtype=float),
                            np.ascontiguousarray(p1, dtype=float), self.ax, self.ay,
                            self.dx, self.dy, self.inv_len2, self.nx, self.ny,
                            self.offsets, np.asarray(self.starts, dtype=np.int64))

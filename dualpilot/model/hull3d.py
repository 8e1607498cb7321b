"""Convex polytopes of ℝ³ from points: the exact swept hull △(C^i_{1:t}) of a front's cuboids.

Eq. (P1_4) keeps the UAV out of "the convex hull outlined by the firefront's path
C^i_{1:t}". When a front's cuboids differ in height the hull has slanted roofs and is no
prism; :class:`Polytope3` is that hull, from Qhull (scipy.spatial.ConvexHull):

* H-form {p : α_l·p ≤ β_l}, one row per face (Qhull's coplanar triangles merged), unit
  outward normals α_l: the (α_l, β_l) of Eq. (P2_3), with Σ_l b ≤ (faces − 1) in (P2_4);
* its boundary triangles, for exact distances: a point's is 0 inside, else the least
  over the triangles (Ericson, *Real-Time Collision Detection*, 2005, §5.1.5); a
  segment's is 0 when it meets the hull (Cyrus–Beck on the faces), else the least of its
  endpoints' distances and its distances to the triangles' edges (the argument of
  dualpilot/model/prism.py: a diagonal of a face lies on the boundary, so it adds a
  candidate that is never nearer than the true distance).

:meth:`dualpilot.model.prism.Prism.swept` is the cheaper superset planners may use
instead (a reading: the prism's faces are the planar hull's plus a top and a bottom).
Lengths m.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import ArrayLike
from scipy.spatial import ConvexHull, QhullError

from dualpilot.arrays import Array
from dualpilot.model.prism import Prism, segment_meets
from dualpilot.model.segment_kernels import segment_segment_d2

#: Two of Qhull's facet planes are one face when their (α, β) agree to this (unit α; m).
_SAME_PLANE = 1e-9


@dataclass(frozen=True, eq=False)
class Polytope3:
    """A convex polytope {p : A p ≤ b} of ℝ³ with its vertices and boundary triangles."""

    vertices: Array  # (V, 3)
    A: Array = field(repr=False)  # (F, 3) unit outward normals α_l
    b: Array = field(repr=False)  # (F,) offsets β_l
    triangles: Array = field(repr=False)  # (T, 3) rows of ``vertices``

    @staticmethod
    def from_points(points: ArrayLike) -> Polytope3:
        """The convex hull of ``points`` (n, 3); ValueError when it has no volume."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        if not np.all(np.isfinite(pts)):
            raise ValueError("hull points must be finite")
        try:
            hull = ConvexHull(pts)
        except (QhullError, ValueError) as err:
            raise ValueError(f"the points span no volume: {err}") from None
        used = np.unique(hull.simplices)
        index = np.full(len(pts), -1, dtype=np.int64)
        index[used] = np.arange(len(used))
        a, b = _faces(hull.equations)
        return Polytope3(pts[used], a, b, index[hull.simplices])

    @staticmethod
    def hull_of(prisms: Sequence[Prism]) -> Polytope3:
        """The convex hull of the prisms (a front's cuboids C^i_{1:t}): △ exactly."""
        if not prisms:
            raise ValueError("a hull needs at least one prism")
        return Polytope3.from_points(np.vstack([p.vertices for p in prisms]))

    @property
    def n_faces(self) -> int:
        return len(self.b)

    @property
    def box(self) -> tuple[Array, Array]:
        """The bounding box (lo, hi) (m)."""
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    def margins(self, points: ArrayLike) -> Array:
        """max_l (α_l·p − β_l) per point (n, 3) (m), as :meth:`Prism.margins`."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        return np.asarray(np.max(pts @ self.A.T - self.b, axis=1))

    def contains(self, p: ArrayLike, margin: float = 0.0) -> bool:
        """True if p satisfies every face inflated by ``margin`` (α·p ≤ β + margin)."""
        return bool(np.all(self.A @ np.asarray(p, dtype=float)[:3] <= self.b + margin))

    def distance(self, p: ArrayLike) -> float:
        """Euclidean distance (m) from the point p (0 inside)."""
        q = np.ascontiguousarray(np.asarray(p, dtype=float)[:3])
        if self.contains(q):
            return 0.0
        return math.sqrt(_triangles_d2(q, self.vertices, self.triangles))

    def segment_intersects(self, p0: ArrayLike, p1: ArrayLike) -> bool:
        """Cyrus–Beck clipping: does the segment p0–p1 meet the closed polytope?"""
        a = np.asarray(p0, dtype=float)[:3]
        return segment_meets(self.A, self.b, a, np.asarray(p1, dtype=float)[:3] - a)

    def segment_distance(self, p0: ArrayLike, p1: ArrayLike) -> float:
        """Exact distance (m) from the segment p0–p1 to the polytope (0 if they meet)."""
        a = np.ascontiguousarray(np.asarray(p0, dtype=float)[:3])
        c = np.ascontiguousarray(np.asarray(p1, dtype=float)[:3])
        if segment_meets(self.A, self.b, a, c - a):
            return 0.0
        d2 = _tri_edges_d2(a, c - a, self.vertices, self.triangles)
        return math.sqrt(min(d2, self.distance(a) ** 2, self.distance(c) ** 2))


def _faces(equations: Array) -> tuple[Array, Array]:
    """(α, β) of Qhull's facet equations n·x + c ≤ 0, coplanar facets merged into one face."""
    a = equations[:, :3] / np.linalg.norm(equations[:, :3], axis=1)[:, None]
    b = -equations[:, 3] / np.linalg.norm(equations[:, :3], axis=1)
    keep: list[int] = []
    for i in range(len(b)):
        if not any(np.all(np.abs(a[i] - a[j]) <= _SAME_PLANE)
                   and abs(b[i] - b[j]) <= _SAME_PLANE * max(1.0, abs(b[j])) for j in keep):
            keep.append(i)
    return np.ascontiguousarray(a[keep]), np.ascontiguousarray(b[keep])


@njit(cache=True)
def _dot3(u: Array, v: Array) -> float:
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@njit(cache=True)
def point_triangle_d2(p: Array, a: Array, b: Array, c: Array) -> float:
    """Squared distance (m²) from p to the triangle abc: its closest point by the Voronoi
    regions of the vertices, edges and face (Ericson 2005, §5.1.5)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = _dot3(ab, ap), _dot3(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        q = a
    else:
        bp = p - b
        d3, d4 = _dot3(ab, bp), _dot3(ac, bp)
        cp = p - c
        d5, d6 = _dot3(ab, cp), _dot3(ac, cp)
        vc = d1 * d4 - d3 * d2
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:
            q = b
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            q = a + (d1 / (d1 - d3)) * ab
        elif d6 >= 0.0 and d5 <= d6:
            q = c
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            q = a + (d2 / (d2 - d6)) * ac
        elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
            q = b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b)
        else:
            denom = 1.0 / (va + vb + vc)
            q = a + ab * (vb * denom) + ac * (vc * denom)
    r = p - q
    return _dot3(r, r)


@njit(cache=True)
def _triangles_d2(p: Array, verts: Array, tris: Array) -> float:
    best = np.inf
    for k in range(len(tris)):
        best = min(best, point_triangle_d2(p, verts[tris[k, 0]], verts[tris[k, 1]],
                                           verts[tris[k, 2]]))
    return best


@njit(cache=True)
def _tri_edges_d2(p: Array, d: Array, verts: Array, tris: Array) -> float:
    best = np.inf
    for k in range(len(tris)):
        for j in range(3):
            a = verts[tris[k, j]]
            e = verts[tris[k, (j + 1) % 3]] - a
            best = min(best, segment_segment_d2(p, d, a, e))
    return best

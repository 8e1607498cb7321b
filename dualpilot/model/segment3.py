"""Exact segment-to-prisms distances in ℝ³, compiled: the 3-D :class:`SegmentChecker`.

:class:`SegmentChecker3` answers for prisms (:class:`~dualpilot.model.prism.Prism`: a
planar hull over [z_lo, z_hi], the fires' cuboids and hulls in 3-D) what
:class:`~dualpilot.model.geometry.SegmentChecker` answers for planar hulls, in this order:

1. the bounding boxes' gap in 3-D, a lower bound that settles most prisms;
2. a segment whose two altitudes lie within a prism's [z_lo, z_hi] is at its planar
   distance from the base (the prism is a product): the planar kernel, with the very
   operations of :class:`SegmentChecker`, so such distances are the 2-D numbers **bit for
   bit** (a cuboid taller than the band seen from a UAV in the band: the top-down case);
3. any other segment: 0 when it meets the prism (Cyrus–Beck on its k + 2 faces), else the
   least of its endpoints' distances and its distances to the prism's 3k edges
   (:func:`~dualpilot.model.segment_kernels.segment_segment_d2`), as
   :meth:`~dualpilot.model.prism.Prism.segment_distance` does.

Lengths m; points (n, 3).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property

import numpy as np

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.geometry import (
    _HullEdges,
    _point_polygon_distance2,
    _segment_near_polygon,
)
from dualpilot.model.prism import Prism


class SegmentChecker3:
    """Exact distances from 3-D segments and points to a set of prisms (module docstring)."""

    def __init__(self, prisms: Sequence[Prism]):
        from dualpilot.model.segment_kernels import one_prism_d2, prism_distances

        self._one_prism_d2, self._prism_distances = one_prism_d2, prism_distances
        self.prisms = tuple(prisms)
        self.n_prisms = len(self.prisms)
        lo = [p.box[0] for p in self.prisms]
        hi = [p.box[1] for p in self.prisms]
        self._box_lo = np.array(lo).reshape(-1, 3)
        self._box_hi = np.array(hi).reshape(-1, 3)
        self._zlo = np.array([p.z_lo for p in self.prisms], dtype=float)
        self._zhi = np.array([p.z_hi for p in self.prisms], dtype=float)
        if self.prisms:
            self._plane = _HullEdges([p.base for p in self.prisms])
            starts = [p.edges[0] for p in self.prisms]
            vecs = [p.edges[1] for p in self.prisms]
            self._e_start = np.ascontiguousarray(np.vstack(starts))
            self._e_vec = np.ascontiguousarray(np.vstack(vecs))
            self._e_first = np.concatenate(
                [[0], np.cumsum([len(s) for s in starts])]).astype(np.int64)

    # plain floats for the one-segment test, made on first use
    @cached_property
    def _boxes(self) -> list[tuple[float, ...]]:
        return [tuple(float(v) for v in (*a, *b))
                for a, b in zip(self._box_lo, self._box_hi, strict=True)]

    @cached_property
    def _faces(self) -> list[list[tuple[float, float, float]]]:
        return [list(zip(p.base.A[:, 0].tolist(), p.base.A[:, 1].tolist(), p.base.b.tolist(),
                         strict=True)) for p in self.prisms]

    @cached_property
    def _verts(self) -> list[list[tuple[float, float]]]:
        return [[(float(x), float(y)) for x, y in p.base.vertices.tolist()]
                for p in self.prisms]

    def _kernel_args(self) -> tuple[AnyArray, ...]:
        h = self._plane
        return (h.ax, h.ay, h.dx, h.dy, h.inv_len2, h.nx, h.ny, h.offsets,
                np.asarray(h.starts, dtype=np.int64), self._zlo, self._zhi, self._e_start,
                self._e_vec, self._e_first)

    def distances(self, p0: Array, p1: Array) -> Array:
        """Distance (m) from each segment p0[i]–p1[i] (arrays (n, 3)) to the nearest prism
        (0 on contact, inf without prisms)."""
        a = np.ascontiguousarray(np.atleast_2d(np.asarray(p0, dtype=float)))
        b = np.ascontiguousarray(np.atleast_2d(np.asarray(p1, dtype=float)))
        if not self.prisms:
            return np.full(len(a), np.inf)
        return self._prism_distances(a, b, *self._kernel_args())

    def clear(self, p0: Array, p1: Array, need_m: float) -> Array:
        """Whether each segment p0[i]–p1[i] keeps ``need_m`` from every prism (bool (n,))."""
        a = np.atleast_2d(np.asarray(p0, dtype=float))
        b = np.atleast_2d(np.asarray(p1, dtype=float))
        if not self.prisms:
            return np.ones(len(a), dtype=bool)
        seg_lo, seg_hi = np.minimum(a, b)[:, None], np.maximum(a, b)[:, None]
        gap = np.maximum(0.0, np.maximum(self._box_lo[None] - seg_hi,
                                         seg_lo - self._box_hi[None]))
        ok = np.sqrt(np.min(np.sum(gap * gap, axis=-1), axis=1)) >= need_m
        todo = np.nonzero(~ok)[0]
        if len(todo):
            ok[todo] = self.distances(a[todo], b[todo]) >= need_m
        return ok

    def segment_clear(self, x0: float, y0: float, z0: float, x1: float, y1: float, z1: float,
                      need_m: float) -> bool:
        """Whether the single segment (x0, y0, z0)–(x1, y1, z1) keeps ``need_m`` from every
        prism: boxes, then a face (a base face, the top or the bottom) with both endpoints
        ``need_m`` beyond it, then the exact test (plain floats where they suffice)."""
        lo = (min(x0, x1), min(y0, y1), min(z0, z1))
        hi = (max(x0, x1), max(y0, y1), max(z0, z1))
        need2 = need_m * need_m
        for k, box in enumerate(self._boxes):
            g2 = 0.0
            for a in range(3):
                g = max(0.0, box[a] - hi[a], lo[a] - box[3 + a])
                g2 += g * g
            if g2 >= need2:
                continue
            zlo, zhi = float(self._zlo[k]), float(self._zhi[k])
            if min(z0, z1) - zhi >= need_m or zlo - max(z0, z1) >= need_m:
                continue
            faces = self._faces[k]
            if any(nx * x0 + ny * y0 - b >= need_m and nx * x1 + ny * y1 - b >= need_m
                   for nx, ny, b in faces):
                continue
            if zlo <= lo[2] and hi[2] <= zhi:  # within its altitudes: the planar test
                if _segment_near_polygon(x0, y0, x1, y1, faces, self._verts[k], need_m):
                    return False
            elif self._one_prism_d2(np.array([x0, y0, z0]), np.array([x1, y1, z1]), k,
                                    *self._kernel_args()) < need2:
                return False
        return True

    def point_distance(self, p: Array) -> float:
        """Distance (m) from the 3-D point p to the nearest prism (inf if none): nearest box
        first; the planar distance to the base bit for bit within a prism's altitudes."""
        x, y, z = float(p[0]), float(p[1]), float(p[2])
        order = []
        for k, box in enumerate(self._boxes):
            g2 = 0.0
            for a, v in enumerate((x, y, z)):
                g = max(0.0, box[a] - v, v - box[3 + a])
                g2 += g * g
            order.append((g2, k))
        best2 = float("inf")
        for box2, k in sorted(order):
            if box2 >= best2:
                break
            dz = max(0.0, float(self._zlo[k]) - z, z - float(self._zhi[k]))
            d2 = _point_polygon_distance2(x, y, self._faces[k], self._verts[k])
            best2 = min(best2, d2 if dz == 0.0 else d2 + dz * dz)
        return best2 ** 0.5

    def path_clearance(self, points: Array) -> float:
        """Smallest distance (m) from the polyline through ``points`` (k, 3) to any prism."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        if len(pts) == 1:
            return self.point_distance(pts[0])
        return float(np.min(self.distances(pts[:-1], pts[1:])))


def prism_path_clearance(points: Array, prisms: Sequence[Prism]) -> float:
    """Smallest distance (m) from the polyline through ``points`` (k, 3) to any prism (inf if
    none), every segment exactly."""
    if not prisms:
        return float("inf")
    return SegmentChecker3(prisms).path_clearance(points)

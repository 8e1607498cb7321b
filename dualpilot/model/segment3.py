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
   (:func:`~dualpilot.model.prism.segment_segment_d2`), as
   :meth:`~dualpilot.model.prism.Prism.segment_distance` does.

Lengths m; points (n, 3).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property

import numpy as np
from numba import njit

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.geometry import (
    _HullEdges,
    _point_polygon_distance2,
    _pseg_d2,  # the planar operations, so the planar numbers are the same
    _segment_near_polygon,
)
from dualpilot.model.prism import Prism, segment_segment_d2

#: Below this |α·d| a face is parallel to the segment (as in prism.segment_meets).
_PARALLEL = 1e-12


class SegmentChecker3:
    """Exact distances from 3-D segments and points to a set of prisms (module docstring)."""

    def __init__(self, prisms: Sequence[Prism]):
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
        return _prism_distances(a, b, *self._kernel_args())

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
            elif _one_prism_d2(np.array([x0, y0, z0]), np.array([x1, y1, z1]), k,
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


@njit(cache=True)
def _planar(p0: Array, p1: Array, fs: int, fe: int, ax: Array, ay: Array, dx: Array,
            dy: Array, inv_len2: Array, nx: Array, ny: Array, offsets: Array) -> tuple[float, bool]:
    """(least squared distance, contact) of the planar segment to one hull's edges fs..fe−1:
    geometry._hull_distances for one hull."""
    x0, y0, x1, y1 = p0[0], p0[1], p1[0], p1[1]
    sx, sy = x1 - x0, y1 - y0
    slen2 = sx * sx + sy * sy
    inv = 1.0 / (slen2 if slen2 > 0 else 1.0)
    best = np.inf
    hit = False
    for j in range(fs, fe):
        d2 = min(_pseg_d2(x0, y0, ax[j], ay[j], dx[j], dy[j], inv_len2[j]),
                 _pseg_d2(x1, y1, ax[j], ay[j], dx[j], dy[j], inv_len2[j]))
        d2 = min(d2, _pseg_d2(ax[j], ay[j], x0, y0, sx, sy, inv))
        if d2 < best:
            best = d2
        o1 = sx * (ay[j] - y0) - sy * (ax[j] - x0)
        o2 = sx * (ay[j] + dy[j] - y0) - sy * (ax[j] + dx[j] - x0)
        o3 = dx[j] * (y0 - ay[j]) - dy[j] * (x0 - ax[j])
        o4 = dx[j] * (y1 - ay[j]) - dy[j] * (x1 - ax[j])
        if (o1 * o2) < 0 and (o3 * o4) < 0:
            hit = True
    worst = -np.inf
    for j in range(fs, fe):
        slack = x0 * nx[j] + y0 * ny[j] - offsets[j]
        if slack > worst:
            worst = slack
    if worst <= 0.0:
        hit = True
    return best, hit


@njit(cache=True)
def _meets(p0: Array, p1: Array, fs: int, fe: int, nx: Array, ny: Array, offsets: Array,
           zlo: float, zhi: float) -> bool:
    """Cyrus–Beck: does the segment meet the prism (base faces fs..fe−1, top, bottom)?"""
    d0, d1, d2 = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
    t_lo, t_hi = 0.0, 1.0
    for j in range(fs, fe + 2):
        if j < fe:
            num = offsets[j] - (nx[j] * p0[0] + ny[j] * p0[1])
            den = nx[j] * d0 + ny[j] * d1
        elif j == fe:
            num, den = zhi - p0[2], d2
        else:
            num, den = p0[2] - zlo, -d2
        if abs(den) < _PARALLEL:
            if num < 0:
                return False
            continue
        t = num / den
        if den > 0:
            t_hi = min(t_hi, t)
        else:
            t_lo = max(t_lo, t)
        if t_lo > t_hi:
            return False
    return True


@njit(cache=True)
def _point_d2(p: Array, fs: int, fe: int, ax: Array, ay: Array, dx: Array, dy: Array,
              inv_len2: Array, nx: Array, ny: Array, offsets: Array, zlo: float,
              zhi: float) -> float:
    """Squared distance (m²) from the 3-D point p to one prism."""
    inside = True
    for j in range(fs, fe):
        if p[0] * nx[j] + p[1] * ny[j] - offsets[j] > 0.0:
            inside = False
            break
    d2 = 0.0
    if not inside:
        d2 = np.inf
        for j in range(fs, fe):
            d2 = min(d2, _pseg_d2(p[0], p[1], ax[j], ay[j], dx[j], dy[j], inv_len2[j]))
    dz = max(0.0, zlo - p[2], p[2] - zhi)
    return d2 + dz * dz


@njit(cache=True)
def _one_prism_d2(p0: Array, p1: Array, k: int, ax: Array, ay: Array, dx: Array, dy: Array,
                  inv_len2: Array, nx: Array, ny: Array, offsets: Array, starts: AnyArray,
                  zlo: Array, zhi: Array, e_start: Array, e_vec: Array,
                  e_first: AnyArray) -> float:
    """Squared distance (m²) from the segment p0–p1 to prism k (0 on contact)."""
    h = len(starts)
    fs = starts[k]
    fe = starts[k + 1] if k + 1 < h else len(ax)
    if zlo[k] <= p0[2] <= zhi[k] and zlo[k] <= p1[2] <= zhi[k]:
        best, hit = _planar(p0, p1, fs, fe, ax, ay, dx, dy, inv_len2, nx, ny, offsets)
        return 0.0 if hit else best
    if _meets(p0, p1, fs, fe, nx, ny, offsets, zlo[k], zhi[k]):
        return 0.0
    d = p1 - p0
    best = min(_point_d2(p0, fs, fe, ax, ay, dx, dy, inv_len2, nx, ny, offsets, zlo[k],
                         zhi[k]),
               _point_d2(p1, fs, fe, ax, ay, dx, dy, inv_len2, nx, ny, offsets, zlo[k],
                         zhi[k]))
    for j in range(e_first[k], e_first[k + 1]):
        best = min(best, segment_segment_d2(p0, d, e_start[j], e_vec[j]))
    return best


@njit(cache=True)
def _prism_distances(p0: Array, p1: Array, ax: Array, ay: Array, dx: Array, dy: Array,
                     inv_len2: Array, nx: Array, ny: Array, offsets: Array, starts: AnyArray,
                     zlo: Array, zhi: Array, e_start: Array, e_vec: Array,
                     e_first: AnyArray) -> Array:
    """Distance (m) from each segment p0[i]–p1[i] to the nearest prism (0 on contact)."""
    n = len(p0)
    out = np.empty(n)
    for i in range(n):
        best = np.inf
        for k in range(len(starts)):
            d2 = _one_prism_d2(p0[i], p1[i], k, ax, ay, dx, dy, inv_len2, nx, ny, offsets,
                               starts, zlo, zhi, e_start, e_vec, e_first)
            if d2 < best:
                best = d2
            if best == 0.0:
                break
        out[i] = np.sqrt(best)
    return out

"""Convex prisms in ℝ³: a planar hull extruded over an altitude interval, as H-polytopes.

Sec. II-B's cuboid C_t is "characterised by the parameter set {α_l, β_l}_{l=1}^6": the
points p ∈ ℝ³ with α_l·p ≤ β_l. A :class:`Prism` is the convex polygon ``base``
(:class:`dualpilot.model.geometry.Polytope`, k faces) over [z_lo, z_hi]; its faces are

* l = 1..k: the base's faces, α_l = (α_l^x, α_l^y, 0), β_l the base's β_l, in the base's
  order (counter-clockwise from the lowest corner);
* l = k + 1: the top, α = (0, 0, 1), β = z_hi;
* l = k + 2: the bottom, α = (0, 0, −1), β = −z_lo,

so a rectangle's prism (:meth:`Prism.cuboid`) has the paper's six faces, and the
swept region of a front, △(C^i_{1:t}) (Eq. P1_4), is a prism over the planar hull of its
rectangles (:meth:`Prism.swept`: the planar hull of the bases over the lowest bottom and
the highest top, which contains the 3-D convex hull of the cuboids; that hull itself,
with slanted roofs, is :mod:`dualpilot.model.hull3d`).

Distances are exact. A prism is the product of its base and an interval, so a point's
distance is √(d_xy² + d_z²); a segment whose altitude stays within [z_lo, z_hi] is at
its planar distance from the base (the 2-D numbers, bit for bit); any other segment is
0 when it meets the prism (Cyrus–Beck) and else at the least of its endpoints'
distances and its distances to the prism's 3k edges: two convex sets apart are
nearest at a vertex, an edge or an endpoint (a segment interior nearest to a face
interior runs parallel to it and is as near at the face's edge). Lengths m.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from dualpilot.arrays import Array
from dualpilot.lazy import lazy_module
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.geometry import Polytope, Rect

#: the 3-D segments' Numba kernels, loaded at their first use
_segment_kernels = lazy_module("dualpilot.model.segment_kernels")


@dataclass(frozen=True, eq=False)
class Prism:
    """The convex polygon ``base`` over the altitudes [z_lo, z_hi] (m); faces as above."""

    base: Polytope
    z_lo: float
    z_hi: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.z_lo) and math.isfinite(self.z_hi)):
            raise ValueError(f"prism altitudes must be finite, got {self.z_lo}, {self.z_hi}")
        if not self.z_lo < self.z_hi:
            raise ValueError(f"need z_lo < z_hi, got {self.z_lo}, {self.z_hi}")

    @staticmethod
    def cuboid(rect: Rect, z_lo: float, z_hi: float) -> Prism:
        """The rectangle ``rect`` over [z_lo, z_hi]: Sec. II-B's cuboid, six faces."""
        return Prism(rect.polytope(), float(z_lo), float(z_hi))

    @staticmethod
    def swept(prisms: Sequence[Prism]) -> Prism:
        """The prism over the planar hull of the bases, from the lowest bottom to the highest
        top: convex, it contains every prism and so their convex hull."""
        if not prisms:
            raise ValueError("a swept prism needs at least one prism")
        if len(prisms) == 1:
            return prisms[0]
        base = Polytope.from_vertices(np.vstack([p.base.vertices for p in prisms]))
        return Prism(base, min(p.z_lo for p in prisms), max(p.z_hi for p in prisms))

    def extended(self, region: Prism) -> Prism:
        """:meth:`swept` of this prism and ``region``: a front's △ after one more cuboid."""
        return Prism.swept([self, region])

    # -- the H-form of Eq. (P2_3) ---------------------------------------------------------------
    @property
    def n_faces(self) -> int:
        return self.base.n_faces + 2

    @cached_property
    def A(self) -> Array:  # the α_l stacked, as in geometry.Polytope
        """Unit outward normals α_l (rows, shape (k + 2, 3)): the base's, top, bottom."""
        k = self.base.n_faces
        a = np.zeros((k + 2, 3))
        a[:k, :2] = self.base.A
        a[k, 2], a[k + 1, 2] = 1.0, -1.0
        a.setflags(write=False)
        return a

    @cached_property
    def b(self) -> Array:
        """Offsets β_l (shape (k + 2,)): the base's, z_hi, −z_lo."""
        out = np.concatenate([self.base.b, [self.z_hi, -self.z_lo]])
        out.setflags(write=False)
        return out

    @cached_property
    def vertices(self) -> Array:
        """The 2k corners (m): the base's at z_lo, then at z_hi, shape (2k, 3)."""
        v = self.base.vertices
        k = len(v)
        return np.vstack([np.column_stack([v, np.full(k, self.z_lo)]),
                          np.column_stack([v, np.full(k, self.z_hi)])])

    @cached_property
    def edges(self) -> tuple[Array, Array]:
        """(starts, vectors) of the 3k edges: bottom ring, top ring, the k verticals."""
        v = self.vertices
        k = self.base.n_faces
        ring = np.arange(k)
        nxt = (ring + 1) % k
        starts = np.vstack([v[ring], v[k + ring], v[ring]])
        ends = np.vstack([v[nxt], v[k + nxt], v[k + ring]])
        return np.ascontiguousarray(starts), np.ascontiguousarray(ends - starts)

    @property
    def box(self) -> tuple[Array, Array]:
        """The bounding box (lo, hi) (m)."""
        v = self.base.vertices
        return (np.array([*v.min(axis=0), self.z_lo]), np.array([*v.max(axis=0), self.z_hi]))

    def margins(self, points: ArrayLike) -> Array:
        """max_l (α_l·p − β_l) per point (n, 3) (m): ≥ ε iff Eq. (P2_3)-(P2_4) hold at p
        with tolerance ε, > 0 iff p lies outside (Eq. collision)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        return np.asarray(np.max(pts @ self.A.T - self.b, axis=1))

    def contains(self, p: ArrayLike, margin: float = 0.0) -> bool:
        """True if p satisfies every face inflated by ``margin`` (α·p ≤ β + margin)."""
        return bool(np.all(self.A @ np.asarray(p, dtype=float)[:3] <= self.b + margin))

    # -- the band -------------------------------------------------------------------------------
    def spans(self, band: AltitudeBand) -> bool:
        """Whether the prism covers every altitude of the band: over its base no position of
        the band is outside it, as in the top-down evaluation."""
        return self.z_lo <= band.floor_m and self.z_hi >= band.ceiling_m

    def escape_faces(self, band: AltitudeBand, eps: float) -> Array:
        """Indices l of the faces whose side α_l·p ≥ β_l + ε meets the band's altitudes: the
        faces Eq. (P2_3) can use there (the others' binaries are forced to 1)."""
        k = self.base.n_faces
        keep = list(range(k))
        if self.z_hi + eps <= band.ceiling_m:
            keep.append(k)
        if self.z_lo - eps >= band.floor_m:
            keep.append(k + 1)
        return np.array(keep, dtype=np.int64)

    # -- distances ------------------------------------------------------------------------------
    def _z_gap(self, z: float) -> float:
        return max(0.0, self.z_lo - z, z - self.z_hi)

    def distance(self, p: ArrayLike) -> float:
        """Euclidean distance (m) from the 3-D point p (0 inside); the base's planar distance
        exactly when p's altitude lies within [z_lo, z_hi]."""
        q = np.asarray(p, dtype=float)
        d_xy = self.base.distance(q[:2])
        d_z = self._z_gap(float(q[2]))
        if d_z == 0.0:
            return d_xy
        return d_z if d_xy == 0.0 else math.hypot(d_xy, d_z)

    def segment_intersects(self, p0: ArrayLike, p1: ArrayLike) -> bool:
        """Cyrus–Beck clipping: does the segment p0–p1 meet the closed prism?"""
        a = np.asarray(p0, dtype=float)[:3]
        return segment_meets(self.A, self.b, a, np.asarray(p1, dtype=float)[:3] - a)

    def segment_distance(self, p0: ArrayLike, p1: ArrayLike) -> float:
        """Exact distance (m) from the segment p0–p1 to the prism (0 if they meet)."""
        a = np.asarray(p0, dtype=float)[:3]
        c = np.asarray(p1, dtype=float)[:3]
        z_in = self.z_lo <= a[2] <= self.z_hi and self.z_lo <= c[2] <= self.z_hi
        if z_in:  # every point of the segment is at its planar distance from the base
            return self.base.segment_distance(a[:2], c[:2])
        if segment_meets(self.A, self.b, a, c - a):
            return 0.0
        starts, vecs = self.edges
        d2 = _segment_kernels().edges_d2(a, c - a, starts, vecs)
        return math.sqrt(min(d2, self.distance(a) ** 2, self.distance(c) ** 2))


@dataclass(frozen=True)
class Cuboid:
    """A front's region C_t in 3-D: the rectangle ``rect`` over [``bottom_m``, ``top_m``] (m;
    fires stand on the ground, bottom 0), Sec. II-B's cuboid.

    What the mission step measures d_t and d_safe to (dualpilot/mission/step.py). Its
    distances are the planar ones of :class:`~dualpilot.model.geometry.Rect` bit for bit
    when the altitudes lie within [bottom, top] (so a cuboid taller than the band gives a
    UAV in the band the top-down evaluation's numbers); :attr:`prism` is its H-form.
    """

    rect: Rect
    top_m: float
    bottom_m: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.top_m) and math.isfinite(self.bottom_m)
                and self.bottom_m < self.top_m):
            raise ValueError(f"a cuboid needs finite bottom_m < top_m, got {self.bottom_m}, "
                             f"{self.top_m}")

    @property
    def prism(self) -> Prism:
        """The six faces of Sec. II-B (made on each call; :meth:`Rect.polytope` is kept)."""
        return Prism(self.rect.polytope(), self.bottom_m, self.top_m)

    @property
    def bounds3(self) -> tuple[float, float, float, float, float, float]:
        """(x_lo, y_lo, z_lo, x_hi, y_hi, z_hi) (m)."""
        x0, y0, x1, y1 = self.rect.bounds
        return (x0, y0, self.bottom_m, x1, y1, self.top_m)

    def z_gap(self, z: float) -> float:
        """How far (m) altitude ``z`` lies below the bottom or above the top (0 within)."""
        return max(0.0, self.bottom_m - z, z - self.top_m)

    def distance(self, p: ArrayLike) -> float:
        """Euclidean distance (m) from the 3-D point p (0 inside): the rectangle's planar
        distance exactly when p's altitude lies within the cuboid's."""
        q = np.asarray(p, dtype=float)
        d_xy = self.rect.distance(q[:2])
        d_z = self.z_gap(float(q[2]))
        if d_z == 0.0:
            return d_xy
        return d_z if d_xy == 0.0 else math.hypot(d_xy, d_z)

    def segment_distance(self, p0: ArrayLike, p1: ArrayLike) -> float:
        """Exact distance (m) from the 3-D segment p0–p1 (0 if they meet): the rectangle's
        planar segment distance exactly when both altitudes lie within the cuboid's."""
        return self.prism.segment_distance(p0, p1)


def segment_meets(a_mat: Array, b: Array, p0: Array, d: Array) -> bool:
    """Whether p0 + t·d, t ∈ [0, 1], meets the closed H-polytope {p : A p ≤ b} (Cyrus–Beck
    clipping, any dimension)."""
    t_lo, t_hi = 0.0, 1.0
    num = b - a_mat @ p0
    den = a_mat @ d
    for n_l, d_l in zip(num.tolist(), den.tolist(), strict=True):
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


def prism_clearance(points: ArrayLike, prisms: Sequence[Prism]) -> float:
    """Smallest distance (m) from the polyline through ``points`` (n, 3) to any prism (inf
    if none); every segment is checked exactly."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    if not prisms or not len(pts):
        return float("inf")
    if len(pts) == 1:
        return min(p.distance(pts[0]) for p in prisms)
    return min(p.segment_distance(pts[k], pts[k + 1])
               for p in prisms for k in range(len(pts) - 1))

"""Convex pieces that cover the free space of one planned position (plane geometry).

For one p_τ, its reach box B, the faces already fixed at τ, and a cluster of hulls, the
positions allowed by Eq. (P2_3)-(P2_4) are B ∩ (fixed half-planes) ∩ ⋂_i ⋃_l R_{i,l},
R_{i,l} = {p : α_{i,l}·p ≥ β_{i,l} + ε}. :func:`cover` writes that union of
intersections as a list of convex pieces, each a list of half-planes a·p ≥ c: a piece
that already avoids the next hull is kept whole, the others are split by its faces.
Lengths in m.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.geometry import Polytope

#: Half-planes a·p ≥ c as rows (a_x, a_y, c).
HalfPlanes = Array

#: Tolerance (m) of the clipping tests: a piece thinner than this counts as empty only
#: when it is empty by this much (pieces are kept when unsure, which only loosens a bound).
_SLACK = 1e-7


def clip(lo: Array, hi: Array, halfplanes: HalfPlanes) -> Array:
    """The vertices of the box [lo, hi] cut by every half-plane a·p ≥ c (empty (0, 2) if none
    is left; Sutherland–Hodgman)."""
    poly = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    if np.any(lo > hi):
        return np.zeros((0, 2))
    for ax, ay, c in np.asarray(halfplanes, dtype=float).reshape(-1, 3):
        f = poly @ np.array([ax, ay]) - c
        inside = f >= -_SLACK
        if np.all(inside):
            continue
        if not np.any(inside):
            return np.zeros((0, 2))
        out: list[Array] = []
        n = len(poly)
        for k in range(n):
            j = (k + 1) % n
            if inside[k]:
                out.append(poly[k])
            if inside[k] != inside[j]:
                out.append(poly[k] + (poly[j] - poly[k]) * (f[k] / (f[k] - f[j])))
        poly = np.array(out)
    return poly


def faces_of(hull: Polytope, eps: float) -> HalfPlanes:
    """The half-planes R_l = {α_l·p ≥ β_l + ε} of one hull, one row per face."""
    return np.column_stack([hull.A, hull.b + eps])


def inside_of(hull: Polytope, eps: float) -> HalfPlanes:
    """The ε-inflated hull Q = {α_l·p ≤ β_l + ε ∀l} as half-planes (−α)·p ≥ −(β + ε)."""
    return np.column_stack([-hull.A, -(hull.b + eps)])


def cover(lo: Array, hi: Array, fixed: HalfPlanes, hulls: Sequence[Polytope], eps: float,
          max_pieces: int) -> list[HalfPlanes] | None:
    """Convex pieces whose union holds every p in [lo, hi] that satisfies ``fixed`` and
    stays outside the ε-inflation of each of ``hulls``; None past ``max_pieces``.

    An empty list: no such point (the cluster, with the fixed faces, blocks the box).
    """
    base = np.asarray(fixed, dtype=float).reshape(-1, 3)
    if not len(clip(lo, hi, base)):
        return []
    pieces = [base]
    for hull in hulls:
        inner = inside_of(hull, eps)
        split: list[HalfPlanes] = []
        for piece in pieces:
            if not len(clip(lo, hi, np.vstack([piece, inner]))):
                split.append(piece)  # the piece already avoids this hull
                continue
            for row in faces_of(hull, eps):
                cut = np.vstack([piece, row[None, :]])
                if len(clip(lo, hi, cut)):
                    split.append(cut)
        pieces = _undominated(lo, hi, split)
        if len(pieces) > max_pieces:
            return None
    return pieces


def _undominated(lo: Array, hi: Array, pieces: list[HalfPlanes]) -> list[HalfPlanes]:
    """``pieces`` without those inside another one (their union is the same)."""
    verts = [clip(lo, hi, p) for p in pieces]
    keep: list[int] = []
    for k, vk in enumerate(verts):
        inside = False
        for j, pj in enumerate(pieces):
            if j == k or (j < k and j not in keep):
                continue
            # piece k inside piece j (of two equal pieces the later one goes)
            tie = j > k and _holds(verts[j], pieces[k])
            if _holds(vk, pj) and not tie:
                inside = True
                break
        if not inside:
            keep.append(k)
    return [pieces[k] for k in keep]


def _holds(vertices: Array, piece: HalfPlanes) -> bool:
    """True if every vertex satisfies every half-plane of ``piece`` (within the slack)."""
    return bool(np.all(vertices @ piece[:, :2].T - piece[:, 2] >= -_SLACK))

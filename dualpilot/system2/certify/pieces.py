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
from numba import njit

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
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    if np.any(lo > hi):
        return np.zeros((0, 2))
    return _clip(lo, hi, np.ascontiguousarray(halfplanes, dtype=float).reshape(-1, 3), _SLACK)


@njit(cache=True)
def _clip(lo: Array, hi: Array, halfplanes: Array, slack: float) -> Array:
    """:func:`clip`, compiled (a cut adds at most one vertex)."""
    m = len(halfplanes)
    poly = np.empty((4 + m, 2))
    poly[0, 0], poly[0, 1] = lo[0], lo[1]
    poly[1, 0], poly[1, 1] = hi[0], lo[1]
    poly[2, 0], poly[2, 1] = hi[0], hi[1]
    poly[3, 0], poly[3, 1] = lo[0], hi[1]
    n = 4
    out = np.empty((4 + m, 2))
    f = np.empty(4 + m)
    for r in range(m):
        ax, ay, c = halfplanes[r, 0], halfplanes[r, 1], halfplanes[r, 2]
        n_in = 0
        for k in range(n):
            f[k] = poly[k, 0] * ax + poly[k, 1] * ay - c
            if f[k] >= -slack:
                n_in += 1
        if n_in == n:
            continue
        if n_in == 0:
            return np.zeros((0, 2))
        cnt = 0
        for k in range(n):
            j = (k + 1) % n
            in_k, in_j = f[k] >= -slack, f[j] >= -slack
            if in_k:
                out[cnt, 0], out[cnt, 1] = poly[k, 0], poly[k, 1]
                cnt += 1
            if in_k != in_j:
                t = f[k] / (f[k] - f[j])
                out[cnt, 0] = poly[k, 0] + (poly[j, 0] - poly[k, 0]) * t
                out[cnt, 1] = poly[k, 1] + (poly[j, 1] - poly[k, 1]) * t
                cnt += 1
        poly, out = out, poly
        n = cnt
    return poly[:n].copy()


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
    n = len(pieces)
    if n < 2:
        return pieces
    owner = np.concatenate([np.full(len(v), k) for k, v in enumerate(verts)]).astype(np.int64)
    allv = np.vstack([v.reshape(-1, 2) for v in verts])
    # within[k, j]: every vertex of piece k satisfies every half-plane of piece j
    within = np.zeros((n, n), dtype=bool)
    for j, pj in enumerate(pieces):
        ok = np.all(allv @ pj[:, :2].T - pj[:, 2] >= -_SLACK, axis=1)
        bad = np.bincount(owner, weights=~ok, minlength=n)
        within[:, j] = bad == 0
    keep: list[int] = []
    for k in range(n):
        inside = False
        for j in range(n):
            if j == k or (j < k and j not in keep):
                continue
            tie = j > k and within[j, k]  # of two equal pieces the later one goes
            if within[k, j] and not tie:
                inside = True
                break
        if not inside:
            keep.append(k)
    return [pieces[k] for k in keep]

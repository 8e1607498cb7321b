"""Geometry for the fast System 2: ε-inflated hulls, supporting half-planes, homotopies.

The avoidance disjunction of Eq. (P2_3)-(P2_4) says that p_τ lies outside
Q_i = {p : α_{i,l}·p ≤ β_{i,l} + ε ∀l}, the hull with every face pushed out by
ε (sharp corners). For a point r outside Q_i, the half-plane through the
point c of Q_i nearest to r with normal (r − c)/‖r − c‖ supports Q_i, so every
position in it satisfies the disjunction: fixing one such half-plane per
(τ, i) gives a convex restriction of (P2). Re-choosing the half-planes at the
restriction's optimum never loses the current point, so the cost can only go
down (the convex-feasible-set iteration).

Which side of each hull the trajectory passes (its homotopy class) is chosen
here with a visibility graph on the vertices of the inflated hulls: one
Dijkstra over the graph lifted by the ray-crossing parity of the nearby hulls
(an h-signature) gives the shortest path in every class at once.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numba import njit
from scipy.sparse.csgraph import dijkstra

from dualpilot.arrays import AnyArray
from dualpilot.model.geometry import Polytope, point_segment_d2


@dataclass(frozen=True)
class Inflated:
    """One hull and its ε-inflation Q in both forms (normals A, offsets b + ε, vertices W)."""

    hull: Polytope
    A: AnyArray
    b: AnyArray  # β + ε
    W: AnyArray  # vertices of Q, CCW
    lo: AnyArray  # bounding box of Q
    hi: AnyArray
    E: AnyArray  # edge vectors W[l+1] − W[l] (edge l lies on face l)
    len2: AnyArray  # their squared lengths
    nsum: AnyArray  # α_{l−1} + α_l at vertex l: a vertex moves by δ·nsum/den when faces move by δ
    den: AnyArray  # 1 + α_{l−1}·α_l

    @staticmethod
    def make(hull: Polytope, eps: float) -> Inflated:
        return Inflated.make_many([hull], eps)[0]

    @staticmethod
    def make_many(hulls: Sequence[Polytope], eps: float) -> list[Inflated]:
        """Q of every hull (vertex k joins faces k−1 and k) and its edges, all at once."""
        if not hulls:
            return []
        sizes = np.array([len(h.b) for h in hulls])
        start = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        prv, nxt = _ring_neighbours(sizes)
        v = np.vstack([h.vertices for h in hulls])
        n = np.vstack([h.A for h in hulls])
        n_prev = n[prv]
        c = np.einsum("ij,ij->i", n_prev, n)
        nsum, den = n_prev + n, 1.0 + c
        w = v + eps * nsum / den[:, None]
        e = w[nxt] - w
        len2 = np.maximum(np.einsum("ij,ij->i", e, e), 1e-12)
        lo = np.minimum.reduceat(w, start, axis=0)
        hi = np.maximum.reduceat(w, start, axis=0)
        out = []
        for i, h in enumerate(hulls):
            sl = slice(int(start[i]), int(start[i] + sizes[i]))
            out.append(Inflated(h, h.A, h.b + eps, w[sl], lo[i], hi[i], e[sl], len2[sl],
                                nsum[sl], den[sl]))
        return out

    def margin(self, points: AnyArray) -> AnyArray:
        """max_l (α_l·p − β_l − ε) per point: ≥ 0 means the disjunction holds (m)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        return np.asarray(np.max(pts @ self.A.T - self.b, axis=1))

    def nearest(self, points: AnyArray) -> tuple[AnyArray, AnyArray]:
        """Nearest boundary point of Q and the distance to it, per point."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        a, e = self.W, self.E
        rel = pts[:, None, :] - a[None, :, :]
        t = np.clip(np.einsum("kfi,fi->kf", rel, e) / self.len2, 0.0, 1.0)
        c = a[None, :, :] + t[:, :, None] * e[None, :, :]
        d2 = np.sum((pts[:, None, :] - c) ** 2, axis=2)
        j = np.argmin(d2, axis=1)
        k = np.arange(len(pts))
        return c[k, j], np.sqrt(d2[k, j])

    def support(self, points: AnyArray) -> tuple[AnyArray, AnyArray, AnyArray]:
        """Supporting half-planes n·p ≥ c of Q at the projections of ``points``.

        Returns (normals (k,2), offsets (k,), outside mask). For a point inside
        Q (or on its boundary) the face with the largest α·p − β is used.
        """
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        margins = pts @ self.A.T - self.b
        face = np.argmax(margins, axis=1)
        normals = self.A[face].copy()
        offsets = self.b[face].copy()
        outside = margins[np.arange(len(pts)), face] > 1e-9
        # a point whose foot on its max-margin face lies on that edge projects onto it
        # (the face itself supports there); only the others need the vertex search
        foot = np.einsum("ki,ki->k", pts - self.W[face], self.E[face]) / self.len2[face]
        vertex_region = outside & ((foot < 0.0) | (foot > 1.0))
        if np.any(vertex_region):
            outside_v = vertex_region
            c, d = self.nearest(pts[outside_v])
            good = d > 1e-6
            nrm = np.where(good[:, None], (pts[outside_v] - c) / np.where(good, d, 1.0)[:, None],
                           normals[outside_v])
            normals[outside_v] = nrm
            offsets[outside_v] = np.where(good, np.einsum("ij,ij->i", nrm, c),
                                          offsets[outside_v])
        return normals, offsets, outside


@dataclass(frozen=True)
class FaceStack:
    """The faces of several inflated hulls stacked, for margins of all of them at once."""

    A: AnyArray
    b: AnyArray
    starts: AnyArray  # first face of each hull
    n: int

    @staticmethod
    def of(polys: Sequence[Inflated] | Sequence[Polytope]) -> FaceStack:
        """Faces (α, β) of each hull: Q's (β + ε) for Inflated, the hull's own for Polytope."""
        if not polys:
            return FaceStack(np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=np.int64), 0)
        return FaceStack(np.vstack([q.A for q in polys]), np.concatenate([q.b for q in polys]),
                         np.cumsum([0] + [len(q.b) for q in polys[:-1]]), len(polys))

    def margins(self, points: AnyArray) -> AnyArray:
        """Inflated.margin of every hull: array (n points, n hulls) (m), compiled
        (:func:`_stack_margins`)."""
        pts = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
        if not self.n:
            return np.zeros((len(pts), 0))
        return _stack_margins(pts, self.A, self.b, self._bounds())

    def below(self, points: AnyArray, threshold: float, mask: AnyArray | None = None
              ) -> AnyArray:
        """(n hulls, n points): hull i's margin at point k is below ``threshold`` (m), where
        ``mask[i, k]`` (all pairs without a mask); a hull's faces are read only until one
        reaches the threshold (:func:`_stack_below`)."""
        pts = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
        if mask is None:
            mask = np.ones((self.n, len(pts)), dtype=np.bool_)
        return _stack_below(pts, self.A, self.b, self._bounds(), float(threshold),
                            np.ascontiguousarray(mask, dtype=np.bool_))

    def _bounds(self) -> AnyArray:
        """The faces of hull i are rows bounds[i]..bounds[i + 1] − 1 of A and b."""
        return np.append(np.asarray(self.starts, dtype=np.int64), len(self.b))


@njit(cache=True)
def _stack_margins(pts: AnyArray, a: AnyArray, b: AnyArray, bounds: AnyArray) -> AnyArray:
    """max over each hull's faces l of α_l·p − b_l, for every point (rows) and hull (columns)."""
    n_pts, n_hulls = pts.shape[0], len(bounds) - 1
    out = np.empty((n_pts, n_hulls))
    for k in range(n_pts):
        x, y = pts[k, 0], pts[k, 1]
        for i in range(n_hulls):
            best = -np.inf
            for f in range(bounds[i], bounds[i + 1]):
                m = (x * a[f, 0] + y * a[f, 1]) - b[f]
                if m > best:
                    best = m
            out[k, i] = best
    return out


@njit(cache=True)
def _stack_below(pts: AnyArray, a: AnyArray, b: AnyArray, bounds: AnyArray, threshold: float,
                 mask: AnyArray) -> AnyArray:
    """mask[i, k] and max_l (α_l·p_k − b_l) < threshold over hull i's faces (early exit)."""
    n_pts, n_hulls = pts.shape[0], len(bounds) - 1
    out = np.zeros((n_hulls, n_pts), dtype=np.bool_)
    for i in range(n_hulls):
        for k in range(n_pts):
            if not mask[i, k]:
                continue
            x, y = pts[k, 0], pts[k, 1]
            inside = True
            for f in range(bounds[i], bounds[i + 1]):
                if (x * a[f, 0] + y * a[f, 1]) - b[f] >= threshold:
                    inside = False
                    break
            out[i, k] = inside
    return out


@dataclass(frozen=True)
class HullStack:
    """Several inflated hulls padded to one face count F, for per-point work on any of them.

    Row h holds Q_h: normals A (H, F, 2), offsets b (H, F) (padding: A = 0,
    b = +inf, so a padded face never has the largest margin), vertices W and
    edges E (padding: zero) and ``valid`` (H, F). Built once per plan; every
    method takes ``hid``, the hull of each point, and matches the
    :class:`Inflated` method of that hull point by point.
    """

    A: AnyArray
    b: AnyArray
    W: AnyArray
    E: AnyArray
    len2: AnyArray
    valid: AnyArray

    @staticmethod
    def of(polys: Sequence[Inflated]) -> HullStack:
        h = len(polys)
        f = max((len(q.b) for q in polys), default=1)
        a = np.zeros((h, f, 2))
        b = np.full((h, f), np.inf)
        w = np.zeros((h, f, 2))
        e = np.zeros((h, f, 2))
        len2 = np.ones((h, f))
        valid = np.zeros((h, f), dtype=bool)
        for i, q in enumerate(polys):
            k = len(q.b)
            a[i, :k], b[i, :k], w[i, :k], e[i, :k], len2[i, :k] = q.A, q.b, q.W, q.E, q.len2
            valid[i, :k] = True
        return HullStack(a, b, w, e, len2, valid)

    def _face_margins(self, hid: AnyArray, pts: AnyArray) -> AnyArray:
        """α_l·p − β_l − ε for every face of each point's hull, (k, F) (m)."""
        a = self.A[hid]
        return np.asarray(pts[:, None, 0] * a[..., 0] + pts[:, None, 1] * a[..., 1]
                          - self.b[hid])

    def margin(self, hid: AnyArray, points: AnyArray) -> AnyArray:
        """Inflated.margin of hull ``hid[k]`` at ``points[k]`` (m)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        return np.asarray(np.max(self._face_margins(hid, pts), axis=1))

    def nearest(self, hid: AnyArray, points: AnyArray) -> tuple[AnyArray, AnyArray]:
        """Inflated.nearest of hull ``hid[k]`` at ``points[k]``."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        a, e = self.W[hid], self.E[hid]
        rel = pts[:, None, :] - a
        t = np.clip(np.einsum("kfi,kfi->kf", rel, e) / self.len2[hid], 0.0, 1.0)
        c = a + t[:, :, None] * e
        d2 = np.where(self.valid[hid], np.sum((pts[:, None, :] - c) ** 2, axis=2), np.inf)
        j = np.argmin(d2, axis=1)
        k = np.arange(len(pts))
        return c[k, j], np.sqrt(d2[k, j])

    def support(self, hid: AnyArray, points: AnyArray) -> tuple[AnyArray, AnyArray, AnyArray]:
        """Inflated.support of hull ``hid[k]`` at ``points[k]``: (normals, offsets, outside)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        margins = self._face_margins(hid, pts)
        face = np.argmax(margins, axis=1)
        k = np.arange(len(pts))
        normals = self.A[hid, face]
        offsets = self.b[hid, face]
        outside = margins[k, face] > 1e-9
        e = self.E[hid, face]
        foot = np.einsum("ki,ki->k", pts - self.W[hid, face], e) / self.len2[hid, face]
        vertex_region = outside & ((foot < 0.0) | (foot > 1.0))
        if np.any(vertex_region):
            sub = vertex_region
            c, d = self.nearest(hid[sub], pts[sub])
            good = d > 1e-6
            nrm = np.where(good[:, None], (pts[sub] - c) / np.where(good, d, 1.0)[:, None],
                           normals[sub])
            normals[sub] = nrm
            offsets[sub] = np.where(good, np.einsum("ij,ij->i", nrm, c), offsets[sub])
        return normals, offsets, outside

    def support_toward(self, hid: AnyArray, points: AnyArray, desired: AnyArray,
                       lambdas: tuple[float, ...] = (1.0, 0.5, 0.25), slack: float = 0.0
                       ) -> tuple[AnyArray, AnyArray, AnyArray]:
        """:func:`support_toward` of hull ``hid[k]`` at ``points[k]``."""
        return _lean(lambda idx, x: self.support(hid[idx], x), points, desired, lambdas, slack)


def support_toward(poly: Inflated, points: AnyArray, desired: AnyArray,
                   lambdas: tuple[float, ...] = (1.0, 0.5, 0.25), slack: float = 0.0
                   ) -> tuple[AnyArray, AnyArray, AnyArray]:
    """Supporting half-planes that contain ``points`` and lean towards ``desired``.

    For each point p (outside Q) the support is taken at the projection of
    p + λ(d − p) for the largest λ whose half-plane still contains p with
    ``slack``; λ = 0 is the plain support at p. Returns (normals, offsets,
    outside mask of the points).
    """
    return _lean(lambda _idx, x: poly.support(x), points, desired, lambdas, slack)


def _lean(support: Callable[[AnyArray, AnyArray], tuple[AnyArray, AnyArray, AnyArray]],
          points: AnyArray, desired: AnyArray, lambdas: tuple[float, ...], slack: float
          ) -> tuple[AnyArray, AnyArray, AnyArray]:
    """:func:`support_toward` given ``support(indices, x)``: the supports for points[indices]."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    nrm, off, outside = support(np.arange(len(pts)), pts)
    done = np.logical_not(outside)
    for lam in lambdas:
        if np.all(done):
            break
        todo = np.flatnonzero(~done)
        x = pts[todo] + lam * (desired[todo] - pts[todo])
        n2, o2, out2 = support(todo, x)
        ok = out2 & (np.einsum("ij,ij->i", n2, pts[todo]) >= o2 + slack)
        sel = todo[ok]
        nrm[sel] = n2[ok]
        off[sel] = o2[ok]
        done[sel] = True
    return nrm, off, outside


# --------------------------------------------------------------- homotopies
def _segments_blocked(p: AnyArray, q: AnyArray, polys: Sequence[Inflated]) -> AnyArray:
    """True where segment p[k]–q[k] meets the interior of some Q (Cyrus–Beck, vectorised)."""
    blocked = np.zeros(len(p), dtype=bool)
    if not len(p):
        return blocked
    d = q - p
    seg_lo, seg_hi = np.minimum(p, q), np.maximum(p, q)
    for poly in polys:
        cand = ~blocked & np.all(seg_hi > poly.lo, axis=1) & np.all(seg_lo < poly.hi, axis=1)
        if not np.any(cand):
            continue
        pc, dc = p[cand], d[cand]
        num = poly.b[None, :] - pc @ poly.A.T  # (k, F) ; inside where A(p+td) < b
        den = dc @ poly.A.T
        with np.errstate(divide="ignore", invalid="ignore"):
            t = num / den
        t_lo = np.max(np.where(den < -1e-12, t, -np.inf), axis=1)
        t_hi = np.min(np.where(den > 1e-12, t, np.inf), axis=1)
        parallel_out = np.any((np.abs(den) <= 1e-12) & (num <= 1e-9), axis=1)
        lo = np.maximum(t_lo, 0.0)
        hi = np.minimum(t_hi, 1.0)
        # an open interior crossing of positive length (touching the boundary is fine)
        hit = (hi - lo > 1e-7) & ~parallel_out
        blocked[np.flatnonzero(cand)[hit]] = True
    return blocked


def _ray_crossings(p: AnyArray, q: AnyArray, origins: AnyArray, direction: AnyArray) -> AnyArray:
    """(k, r) 1 where segment p[k]–q[k] crosses the ray origins[j] + s·direction, s ≥ 0.

    Each endpoint is put on one side of the ray's line by a fixed predicate
    (cross ≥ 0), so a path vertex lying exactly on a ray is counted once.
    """
    side_p = ((p[:, None, 0] - origins[None, :, 0]) * direction[1]
              - (p[:, None, 1] - origins[None, :, 1]) * direction[0]) >= 0.0
    side_q = ((q[:, None, 0] - origins[None, :, 0]) * direction[1]
              - (q[:, None, 1] - origins[None, :, 1]) * direction[0]) >= 0.0
    d = q - p
    w = origins[None, :, :] - p[:, None, :]
    cross_dd = d[:, 0] * direction[1] - d[:, 1] * direction[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / cross_dd[:, None]
    return ((side_p != side_q) & (s >= 0.0)).astype(np.int64)


def homotopy_paths(
    start: AnyArray,
    target: AnyArray,
    polys: Sequence[Inflated],
    *,
    node_margin: float = 1.0,
    area: float | None = None,
    max_paths: int = 4,
    max_signature_hulls: int = 5,
    length_slack: float = 0.5,
    stack: HullStack | None = None,
) -> list[AnyArray]:
    """Shortest start→target polylines outside every Q, one per homotopy class.

    Nodes are the vertices of each Q pushed out by ``node_margin``; edges join
    mutually visible nodes (bitangent at polygon vertices). The graph is lifted
    by the crossing parity of a ray from each of the ``max_signature_hulls``
    hulls nearest the start–target segment, and one Dijkstra gives the shortest
    path of every parity class. Classes longer than (1 + length_slack) times
    the shortest are dropped; at most ``max_paths`` are returned, shortest first.
    ``stack`` may carry ``HullStack.of(polys)``.
    """
    start = np.asarray(start, dtype=float)
    target = np.asarray(target, dtype=float)
    nodes, prv, nxt, keep = _graph_nodes(start, target, polys, node_margin, area, stack)
    iu, ju = _visible_pairs(nodes, keep, prv, nxt, polys)
    if not len(iu):
        return []
    n = len(nodes)
    lengths = np.linalg.norm(nodes[ju] - nodes[iu], axis=1)
    # plain shortest path first: bounds the relevant hulls
    g0 = sp.coo_matrix((lengths, (iu, ju)), shape=(n, n)).tocsr()
    dist0 = dijkstra(g0, directed=False, indices=0)
    if not np.isfinite(dist0[1]):
        # the target is enclosed: aim for the reachable node nearest to it
        swapped = _swap_target(nodes, target, dist0, iu, ju)
        if swapped is None:
            return []
        iu, ju = swapped
        target = nodes[1].copy()
        g0 = sp.coo_matrix((lengths, (iu, ju)), shape=(n, n)).tocsr()
        dist0 = dijkstra(g0, directed=False, indices=0)
    l_star = float(dist0[1])
    # hulls near enough to matter: inside the ellipse |x−start| + |x−target| ≤ (1+slack) L*
    bound = (1.0 + length_slack) * l_star
    sig = _signature_hulls(start, target, polys, bound, max_signature_hulls)
    if not sig:
        return [_reconstruct(g0, nodes, 0, 1)]
    return _class_paths(nodes, iu, ju, lengths, [polys[k] for k in sig], start, target, bound,
                        max_paths)


def _graph_nodes(start: AnyArray, target: AnyArray, polys: Sequence[Inflated],
                 node_margin: float, area: float | None, stack: HullStack | None
                 ) -> tuple[AnyArray, AnyArray, AnyArray, AnyArray]:
    """The visibility graph's nodes: start (0), target (1), then each Q's vertices pushed
    out by ``node_margin`` (m), hull by hull.

    Returns (nodes, prv, nxt, keep): each vertex's ring neighbours (−1 for the
    start and the target) and False in ``keep`` for a vertex inside some Q or
    outside [0, area]².
    """
    nodes = np.vstack([start[None, :], target[None, :]]
                      + [_offset(poly, node_margin) for poly in polys])
    sizes = np.array([len(poly.b) for poly in polys], dtype=np.int64)
    ring_prv, ring_nxt = _ring_neighbours(sizes)
    prv = np.concatenate([[-1, -1], 2 + ring_prv])  # nodes 0 and 1 are the start and target
    nxt = np.concatenate([[-1, -1], 2 + ring_nxt])
    keep = np.ones(len(nodes), dtype=bool)
    if len(polys):
        # a node inside Q_h lies in Q_h's bounding box: exact margins only for those pairs
        stack = HullStack.of(polys) if stack is None else stack
        lo = np.array([poly.lo for poly in polys]) - 1e-6
        hi = np.array([poly.hi for poly in polys]) + 1e-6
        inner = nodes[2:]
        kk, hh = np.nonzero((inner[:, None, 0] >= lo[None, :, 0])
                            & (inner[:, None, 0] <= hi[None, :, 0])
                            & (inner[:, None, 1] >= lo[None, :, 1])
                            & (inner[:, None, 1] <= hi[None, :, 1]))
        if len(kk):
            inside = stack.margin(hh, inner[kk]) <= 0.0
            keep[2 + kk[inside]] = False
    if area is not None:
        keep[2:] &= np.all((nodes[2:] >= 0.0) & (nodes[2:] <= area), axis=1)
    return nodes, prv, nxt, keep


def _visible_pairs(nodes: AnyArray, keep: AnyArray, prv: AnyArray, nxt: AnyArray,
                   polys: Sequence[Inflated]) -> tuple[AnyArray, AnyArray]:
    """The graph's edges (iu[k] < ju[k]): pairs of kept nodes that are bitangent at polygon
    vertices and whose segment meets no Q's interior."""
    # pairs of kept nodes, in the row-major order of np.triu_indices(n, 1)
    kept = np.flatnonzero(keep)
    ku, kv = np.triu_indices(len(kept), k=1)
    iu, ju = kept[ku], kept[kv]
    # bitangency at polygon vertices: both neighbours on one side of the edge line
    sel = np.ones(len(iu), dtype=bool)
    for a_idx, b_idx in ((iu, ju), (ju, iu)):
        has = prv[a_idx] >= 0
        a = nodes[a_idx[has]]
        dvec = nodes[b_idx[has]] - a
        cp = _cross2(dvec, nodes[prv[a_idx[has]]] - a)
        cn = _cross2(dvec, nodes[nxt[a_idx[has]]] - a)
        sel[np.flatnonzero(has)[cp * cn < -1e-9]] = False
    iu, ju = iu[sel], ju[sel]
    vis = ~_segments_blocked(nodes[iu], nodes[ju], polys)
    return iu[vis], ju[vis]


def _swap_target(nodes: AnyArray, target: AnyArray, dist0: AnyArray, iu: AnyArray,
                 ju: AnyArray) -> tuple[AnyArray, AnyArray] | None:
    """Make the node reachable from the start (distances ``dist0``) nearest to ``target``
    node 1: swaps the two rows of ``nodes`` in place and returns the edges renumbered;
    None if no node is reachable."""
    reach = np.flatnonzero(np.isfinite(dist0))
    reach = reach[reach != 0]
    if not len(reach):
        return None
    j = int(reach[np.argmin(np.linalg.norm(nodes[reach] - target, axis=1))])
    nodes[[1, j]] = nodes[[j, 1]]
    perm = np.arange(len(nodes))
    perm[1], perm[j] = j, 1
    return perm[iu], perm[ju]


def _signature_hulls(start: AnyArray, target: AnyArray, polys: Sequence[Inflated],
                     bound: float, max_signature_hulls: int) -> list[int]:
    """Indices of the hulls whose rays tell the homotopy classes apart: those with a vertex
    in the ellipse |x−start| + |x−target| ≤ ``bound`` (m), nearest to the start–target
    segment first, at most ``max_signature_hulls``."""
    scores = []
    if len(polys):
        sizes = np.array([len(poly.b) for poly in polys], dtype=np.int64)
        w_all = np.vstack([poly.W for poly in polys])
        w_first = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        d_s = np.minimum.reduceat(np.linalg.norm(w_all - start, axis=1), w_first)
        d_t = np.minimum.reduceat(np.linalg.norm(w_all - target, axis=1), w_first)
        for k in np.flatnonzero(d_s + d_t <= bound + 1e-9).tolist():
            c = polys[k].W.mean(axis=0)
            scores.append((float(point_segment_d2(c[0], c[1], *start, *(target - start))), k))
    scores.sort()
    return [k for _, k in scores[:max_signature_hulls]]


def _class_paths(nodes: AnyArray, iu: AnyArray, ju: AnyArray, lengths: AnyArray,
                 sig_polys: Sequence[Inflated], start: AnyArray, target: AnyArray,
                 bound: float, max_paths: int) -> list[AnyArray]:
    """The shortest path of each class, shortest first (at most ``max_paths``, none longer
    than ``bound`` m), by one Dijkstra over the graph lifted by the crossing parities of
    the rays from ``sig_polys`` (normal to the start–target line)."""
    n, r = len(nodes), len(sig_polys)
    axis = target - start
    nrm = float(np.linalg.norm(axis))
    direction = np.array([-axis[1], axis[0]]) / nrm if nrm > 1e-9 else np.array([0.0, 1.0])
    origins = np.array([poly.hull.vertices.mean(axis=0) for poly in sig_polys])
    cross = _ray_crossings(nodes[iu], nodes[ju], origins, direction)
    masks = cross @ (1 << np.arange(r))
    layers = 1 << r
    lay = np.arange(layers)
    src = (lay[:, None] * n + iu[None, :]).ravel()
    dst = ((lay[:, None] ^ masks[None, :]) * n + ju[None, :]).ravel()
    w = np.tile(lengths, layers)
    big = sp.coo_matrix((w, (src, dst)), shape=(layers * n, layers * n)).tocsr()
    dist, pred = dijkstra(big, directed=False, indices=0, return_predecessors=True)
    ends = lay * n + 1
    order = np.argsort(dist[ends])
    out: list[AnyArray] = []
    for li in order:
        d_end = dist[ends[li]]
        if not np.isfinite(d_end) or d_end > bound or len(out) >= max_paths:
            break
        path = [int(ends[li])]
        while path[-1] != 0:
            path.append(int(pred[path[-1]]))
            if path[-1] < 0:
                break
        if path[-1] != 0:
            continue
        out.append(nodes[np.array(path[::-1]) % n])
    return out


def _ring_neighbours(sizes: AnyArray) -> tuple[AnyArray, AnyArray]:
    """Previous and next index of each vertex when polygons of ``sizes`` vertices are stacked."""
    sizes = np.asarray(sizes, dtype=np.int64)
    first = np.repeat(np.cumsum(sizes) - sizes, sizes)
    size = np.repeat(sizes, sizes)
    k = np.arange(int(sizes.sum()))
    return first + (k - first - 1) % size, first + (k - first + 1) % size


def _offset(poly: Inflated, margin: float) -> AnyArray:
    """Vertices of Q pushed out face-wise by ``margin`` more (m)."""
    return np.asarray(poly.W + margin * poly.nsum / poly.den[:, None])


def _cross2(a: AnyArray, b: AnyArray) -> AnyArray:
    return np.asarray(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])


def _reconstruct(graph: sp.csr_matrix, nodes: AnyArray, i: int, j: int) -> AnyArray:
    _, pred = dijkstra(graph, directed=False, indices=i, return_predecessors=True)
    path = [j]
    while path[-1] != i:
        path.append(int(pred[path[-1]]))
    return nodes[np.array(path[::-1])]


def resample(path: AnyArray, arc: AnyArray) -> AnyArray:
    """Points at arc lengths ``arc`` (m) along a polyline (clamped to its ends)."""
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.clip(arc, 0.0, cum[-1])
    x = np.interp(s, cum, path[:, 0])
    y = np.interp(s, cum, path[:, 1])
    return np.column_stack([x, y])

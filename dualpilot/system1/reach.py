"""A quick proof that no path to G exists: 8-connected cells of an over-approximated free space.

Alg. 1 spends its whole iteration budget before it can say "no path" (on
the random fire fields of Sec. IV-A a third of the instances have none).
:func:`certainly_unreachable` settles most of those in about a millisecond
and is conservative: it answers True only when no path keeping the
clearance exists, so it never hides a path from the RRT.

Why it is sound: the area is cut into square cells of side c. A cell is
*possibly free* when the distance from its centre to the nearest hull is at
least ``clearance − c/√2`` (if any point of the cell keeps the clearance, its
centre is at most the half-diagonal c/√2 closer). A continuous path moves
between cells across a shared edge or corner, so every cell it visits is
possibly free and the visited cells form an 8-connected chain from the
start's cell to a cell meeting G. No such chain means no such path.

Near the start, edges may keep only the start's own (smaller) clearance
(see :func:`dualpilot.system1.rrt.plan_path`); cells within ``start_radius_m`` of
the start use that clearance instead. Lengths are metres.

In 3-D (:func:`band_blockers`) the grid stays planar: it takes only the prisms that span
the altitude band. Above such a prism's base every altitude of the band is inside it, so
the distance of a point of the band from it is the planar distance from its base and a
path of the band keeps the clearance from it only if its ground track does. A lower prism
is left out (free on the grid): a path could pass over it. The cells 8-connected to the
start then over-approximate the ground track of every 3-D path, and "G unreachable" stays
a proof.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order

from dualpilot.arrays import Array
from dualpilot.model.altitude import AltitudeBand
from dualpilot.model.geometry import Polytope, Rect, point_segment_d2
from dualpilot.model.prism import Prism

_EIGHT = np.ones((3, 3), dtype=bool)
BoolArray = NDArray[np.bool_]


def band_blockers(prisms: Sequence[Prism], band: AltitudeBand) -> tuple[Polytope, ...]:
    """The bases of the prisms that span ``band`` (:meth:`Prism.spans`): the planar hulls the
    grid test of a 3-D path may take (module docstring)."""
    return tuple(p.base for p in prisms if p.spans(band))


def possibly_free(hulls: Sequence[Polytope], clearance_m: float, area_size_m: float,
                  cell_m: float, cells: tuple[int, int, int, int] | None = None,
                  candidates: BoolArray | None = None) -> BoolArray:
    """Boolean grid (rows = y, columns = x) of the cells that may hold a point with the clearance.

    Each hull only marks the cells whose centre lies within ``clearance_m``
    of its bounding box, so the cost grows with the hulls' size, not the area.
    ``cells`` = (i0, j0, i1, j1), inclusive column/row bounds, limits the
    work to that block (cells outside it are left True). Only cells True in
    ``candidates`` (default: all) are tested; the others come back False.
    """
    n = int(np.ceil(area_size_m / cell_m))
    free = np.ones((n, n), dtype=bool) if candidates is None else candidates.copy()
    b0, c0, b1, c1 = (0, 0, n - 1, n - 1) if cells is None else cells
    threshold = clearance_m - cell_m / np.sqrt(2.0)
    if threshold <= 0:
        return free
    for hull in hulls:
        lo = hull.vertices.min(axis=0) - threshold
        hi = hull.vertices.max(axis=0) + threshold
        i0, j0 = np.maximum(np.floor(lo / cell_m - 0.5).astype(int), (b0, c0))
        i1, j1 = np.minimum(np.ceil(hi / cell_m - 0.5).astype(int), (b1, c1))
        if i0 > i1 or j0 > j1:
            continue
        block = free[j0:j1 + 1, i0:i1 + 1]  # a view: cells other hulls blocked are skipped
        rows, cols = np.nonzero(block)
        if not len(rows):
            continue
        centres = np.column_stack([cols + i0 + 0.5, rows + j0 + 0.5]) * cell_m
        block[rows, cols] = ~_within(centres, hull, threshold)
    return free


def start_component(start: Array, goal: Rect, hulls: Sequence[Polytope], clearance_m: float,
                    area_size_m: float, cell_m: float = 10.0,
                    start_clearance_m: float | None = None,
                    start_radius_m: float = 15.0,
                    coarse: BoolArray | None = None) -> tuple[BoolArray, bool]:
    """The possibly-free cells 8-connected to the start's cell, and whether they meet G.

    Every point of a path from ``start`` that keeps the clearance lies in
    these cells; the area is [0, ``area_size_m``]². ``start_clearance_m``
    (default ``clearance_m``) applies to points within ``start_radius_m`` of
    the start (the first RRT edge).
    ``coarse`` is the component already found on cells of side 2·``cell_m``
    (same start and clearances): a fine cell outside it cannot be in the
    fine component (its coarse cell would then hold a point with the
    clearance, joined to the start), so only the cells inside are tested.
    """
    p = np.asarray(start, dtype=float)[:2]
    n = int(np.ceil(area_size_m / cell_m))
    candidates = None
    if coarse is not None:
        candidates = np.repeat(np.repeat(coarse, 2, axis=0), 2, axis=1)[:n, :n]
    free = possibly_free(hulls, clearance_m, area_size_m, cell_m, candidates=candidates)
    near = start_clearance_m if start_clearance_m is not None else clearance_m
    if near < clearance_m:
        # cells around the start judged with the start's own clearance
        reach = start_radius_m + cell_m / np.sqrt(2.0)
        lo = np.maximum(np.floor((p - reach) / cell_m).astype(int), 0)
        hi = np.minimum(np.ceil((p + reach) / cell_m).astype(int), n - 1)
        local = possibly_free(hulls, near, area_size_m, cell_m, (lo[0], lo[1], hi[0], hi[1]),
                              candidates)
        free[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1] |= local[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1]
    si, sj = (np.clip((p // cell_m).astype(int), 0, n - 1))
    free[sj, si] = True  # the start itself is free (the caller checked it)
    labels, _ = ndimage.label(free, structure=_EIGHT)
    component = labels == labels[sj, si]
    gi0, gj0, gi1, gj1 = _goal_cells(goal, cell_m, n)
    return component, bool(np.any(component[gj0:gj1 + 1, gi0:gi1 + 1]))


def coarsen(cells: BoolArray) -> BoolArray:
    """Cells twice as large: a coarse cell is True if any of its 2×2 fine cells is.

    The inverse of the refinement in :func:`start_component` (``coarse``).
    """
    n = cells.shape[0]
    m = (n + 1) // 2
    padded = np.zeros((2 * m, 2 * m), dtype=bool)
    padded[:n, :n] = cells
    return np.asarray(padded.reshape(m, 2, m, 2).any(axis=(1, 3)), dtype=bool)


def _goal_cells(goal: Rect, cell_m: float, n: int) -> tuple[int, int, int, int]:
    """Inclusive column/row bounds (i0, j0, i1, j1) of the cells that meet G."""
    gi0, gj0 = np.clip((goal.lo // cell_m).astype(int), 0, n - 1)
    gi1, gj1 = np.clip((np.ceil(goal.hi / cell_m) - 1).astype(int), 0, n - 1)
    return int(gi0), int(gj0), int(gi1), int(gj1)


def corridor(component: BoolArray, start: Array, goal: Rect, cell_m: float) -> NDArray[np.int64]:
    """Cells (k, 2) as (column, row) of a fewest-cell 8-connected chain from the start to G.

    A breadth-first search over the cells where ``component`` is True, from
    the start's cell to the first cell meeting G it reaches. Empty when the
    component does not meet G. The chain hints where a narrow passage lies;
    it is not a path (its cells are only *possibly* free).
    """
    n = component.shape[0]
    index = np.full(component.shape, -1, dtype=np.int64)
    rows, cols = np.nonzero(component)
    index[rows, cols] = np.arange(len(rows))
    si, sj = np.clip((np.asarray(start, dtype=float)[:2] // cell_m).astype(int), 0, n - 1)
    if index[sj, si] < 0:
        return np.zeros((0, 2), dtype=np.int64)
    pairs = [(index[:, :-1], index[:, 1:]), (index[:-1, :], index[1:, :]),
             (index[:-1, :-1], index[1:, 1:]), (index[:-1, 1:], index[1:, :-1])]
    a = np.concatenate([u[(u >= 0) & (v >= 0)] for u, v in pairs])
    b = np.concatenate([v[(u >= 0) & (v >= 0)] for u, v in pairs])
    graph = coo_matrix((np.ones(len(a), dtype=np.int8), (a, b)), shape=(len(rows),) * 2).tocsr()
    order, pred = breadth_first_order(graph, int(index[sj, si]), directed=False,
                                      return_predecessors=True)
    gi0, gj0, gi1, gj1 = _goal_cells(goal, cell_m, n)
    targets = index[gj0:gj1 + 1, gi0:gi1 + 1].ravel()
    rank = np.full(len(rows), -1, dtype=np.int64)
    rank[order] = np.arange(len(order))
    targets = targets[(targets >= 0) & (rank[np.maximum(targets, 0)] >= 0)]
    if not len(targets):
        return np.zeros((0, 2), dtype=np.int64)
    chain = [int(targets[np.argmin(rank[targets])])]
    while pred[chain[-1]] >= 0:
        chain.append(int(pred[chain[-1]]))
    chain.reverse()
    return np.column_stack([cols[chain], rows[chain]]).astype(np.int64)


def certainly_unreachable(start: Array, goal: Rect, hulls: Sequence[Polytope],
                          clearance_m: float, area_size_m: float, cell_m: float = 10.0,
                          start_clearance_m: float | None = None,
                          start_radius_m: float = 15.0) -> bool:
    """True only if no path from ``start`` into ``goal`` keeps ``clearance_m`` from every hull.

    False means "a path may exist", not that one does (see :func:`start_component`).
    """
    if not hulls:
        return False
    _, meets_goal = start_component(start, goal, hulls, clearance_m, area_size_m, cell_m,
                                    start_clearance_m, start_radius_m)
    return not meets_goal


def _within(points: Array, hull: Polytope, dist_m: float) -> BoolArray:
    """Whether each point (n, 2) lies nearer than ``dist_m`` to the convex polygon ``hull``.

    Inside the polygon the distance is 0; outside it is the distance to the
    nearest edge. The largest signed face distance is a lower bound on it, so
    only points in the band (0, ``dist_m``) of that bound need the edges.
    """
    worst = (points @ hull.A.T - hull.b).max(axis=1)  # ≤ the distance; ≤ 0 iff inside
    out = worst <= 0.0
    idx = np.nonzero((worst > 0.0) & (worst < dist_m))[0]  # the band that needs the edges
    if not len(idx):
        return out
    pts = points[idx]
    a = hull.vertices
    d = np.vstack([a[1:], a[:1]]) - a
    d2 = point_segment_d2(pts[:, :1], pts[:, 1:], a[:, 0], a[:, 1], d[:, 0], d[:, 1])
    out[idx] = d2.min(axis=1) < dist_m * dist_m  # (k, edges) -> nearest edge
    return out

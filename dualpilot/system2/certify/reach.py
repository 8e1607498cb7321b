"""Where each planned position can be, and what the way there costs at least.

Every trajectory of (P2) moves p_τ → p_{τ+1} by ΔT·v_τ with |v_τ,i| ≤ v_max on each axis
(the "axis" reading of X; the "norm" K-gon lies inside that box too), keeps each p_τ,
τ = 2..T, out of every ε-inflated hull (P2_3)-(P2_4), and stays in the reach box of
Eq. (1) (and the area). On a grid of closed square cells of side h = ΔT·v_max / k, the
cells that may hold p_τ are

    R_1 = {the cell of p_{t+1|t}},
    R_{τ+1} = dilate_k(R_τ) ∩ (cells meeting the reach box of p_{τ+1})
              ∖ (cells inside one ε-inflated hull),

where dilate_k adds every cell within k cells on each axis. A point of a closed cell c
moves at most k·h per axis, so it lands in a cell of dilate_k({c}): by induction every
feasible trajectory passes through cells c_τ ∈ R_τ, each within k of the one before
(the dilation is exact on the grid: the sets are as coarse as one cell and no coarser).
A cell is removed only when all four of its corners lie strictly inside one inflated
hull, so it holds no feasible point.

Along such a cell path ‖p_τ − G_o‖ ≥ d(c_τ), the distance from G_o to the closed cell,
so a shortest path through the layers (dynamic programming, F below) bounds the cost:

    F_1 = 0 at the cell of p_{t+1|t},
    F_τ(c) = d(c)² + min {F_{τ−1}(c′) : c′ ∈ R_{τ−1} within k of c},   c ∈ R_τ,

and every feasible trajectory has Σ_{σ=2..τ} ‖p_σ − G_o‖² ≥ min_c F_τ(c) =: ``prefix_m2``.
What the relaxation (:mod:`dualpilot.system2.certify.relaxation`) takes from it: each
p_τ lies in the bounding box of R_τ and ‖p_τ − G_o‖ ≥ ``floor_m`` = min_{c ∈ R_τ} d(c);
the sums of the first τ stage costs are at least ``prefix_m2``. Where a wall of hulls
stands between the UAV and G_o these are the distances and costs of going round it,
which no convex relaxation of one position at a time sees. An empty R_τ proves (P2)
infeasible. Lengths in m.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.geometry import Polytope

#: Cells per step of the speed limit on each axis: h = ΔT·v_max / CELLS_PER_STEP.
CELLS_PER_STEP = 5

#: A corner counts as inside an inflated hull only when this far inside every face (m).
_INSIDE_M = 1e-6

#: Relative margin taken off the prefix costs for their float32 storage (at most T
#: roundings of 2⁻²⁴ each).
_STORAGE_MARGIN = 1e-5


@dataclass(frozen=True)
class ReachSets:
    """Per planned position p_τ, τ = 1..T (row τ − 1): ``floor_m``, the least distance (m)
    from G_o any feasible p_τ can have; ``prefix_m2`` and ``suffix_m2``, the least
    Σ_{σ=2..τ} and Σ_{σ=τ..T} of ‖p_σ − G_o‖² (m²) of any feasible trajectory; the
    bounding box (lo, hi) of where p_τ can be; ``empty`` if some R_τ holds no cell, which
    proves (P2) infeasible. ``value`` (T, nx, ny) holds F_τ at each cell (inf off R_τ) and
    ``cells`` the cell boxes (i0, j0, i1, j1) of R_τ."""

    floor_m: Array
    prefix_m2: Array
    suffix_m2: Array
    lo: Array
    hi: Array
    empty: bool
    cell_m: float
    origin: Array
    value: AnyArray = field(repr=False)
    cells: AnyArray = field(repr=False)
    cells_per_step: int = CELLS_PER_STEP

    def corridor(self) -> Array | None:
        """Cell centres (T, 2), m, of the cheapest path through the cells (the one whose
        cost is ``prefix_m2[-1]``): a reference for a plan round the hulls, not itself
        feasible. None if some R_τ is empty."""
        if self.empty:
            return None
        cells = _cheapest_path(self.value, self.cells, self.cells_per_step)
        return self.origin + (cells + 0.5) * self.cell_m


def reach_sets(p1: Array, box_lo: Array, box_hi: Array, hulls: Sequence[Polytope],
               epsilon_m: float, goal: Array, step_m: float,
               cells_per_step: int = CELLS_PER_STEP) -> ReachSets:
    """The :class:`ReachSets` of p_1..p_T.

    Parameters
    ----------
    p1 : array
        p_{t+1|t} (2,), fixed by the state, m.
    box_lo, box_hi : array
        (T, 2) reach boxes of p_1..p_T (Eq. (1), clipped to the area), m.
    hulls : sequence of Polytope
        The hulls of (P2_3)-(P2_4); their ε-inflation is forbidden at τ = 2..T.
    epsilon_m : float
        ε of Eq. (P2_3), m.
    goal : array
        G_o (2,), m.
    step_m : float
        The most a position moves per step on each axis, ΔT·v_max, m.
    cells_per_step : int
        k: cells per step on each axis (the cell side is ``step_m`` / k).
    """
    lo, hi = np.asarray(box_lo, dtype=float), np.asarray(box_hi, dtype=float)
    T = len(lo)
    k = int(cells_per_step)
    h = float(step_m) / k
    origin = np.min(lo, axis=0)
    shape = np.maximum(np.ceil((np.max(hi, axis=0) - origin) / h).astype(np.int64), 1)
    blocked = _blocked(origin, h, (int(shape[0]), int(shape[1])), hulls, epsilon_m)
    # the cells each reach box meets, as index ranges [first, last]
    first = np.clip(np.floor((lo - origin) / h).astype(np.int64), 0, shape - 1)
    last = np.clip(np.ceil((hi - origin) / h).astype(np.int64) - 1, 0, shape - 1)
    last = np.maximum(last, first)
    start = np.clip(np.floor((np.asarray(p1, dtype=float)[:2] - origin) / h).astype(np.int64),
                    0, shape - 1)
    value = np.full((T, int(shape[0]), int(shape[1])), np.inf, dtype=np.float32)
    floor, prefix, box = _propagate(blocked, first, last, start, k, origin, h,
                                    np.asarray(goal, dtype=float)[:2], value)
    empty = bool(np.any(~np.isfinite(floor)))
    suffix = np.full(T, np.inf)
    if not empty:
        suffix = _suffix(value, box, k, origin, h, np.asarray(goal, dtype=float)[:2])
    prefix *= 1.0 - _STORAGE_MARGIN
    suffix *= 1.0 - _STORAGE_MARGIN
    out_lo = np.maximum(origin + box[:, :2] * h, lo)
    out_hi = np.minimum(origin + (box[:, 2:] + 1) * h, hi)
    return ReachSets(floor, prefix, suffix, out_lo, out_hi, empty, h, origin, value, box, k)


def _blocked(origin: AnyArray, h: float, shape: tuple[int, int], hulls: Sequence[Polytope],
             epsilon_m: float) -> AnyArray:
    """Cells (closed) whose four corners lie strictly inside one ε-inflated hull."""
    out = np.zeros(shape, dtype=np.bool_)
    for hull in hulls:
        vlo = np.min(hull.vertices, axis=0) - epsilon_m
        vhi = np.max(hull.vertices, axis=0) + epsilon_m
        i0, j0 = np.maximum(np.floor((vlo - origin) / h).astype(int), 0)
        i1, j1 = np.minimum(np.ceil((vhi - origin) / h).astype(int), shape)
        if i1 <= i0 or j1 <= j0:
            continue
        xs = origin[0] + h * np.arange(i0, i1 + 1)
        ys = origin[1] + h * np.arange(j0, j1 + 1)
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        margin = (hull.A[:, 0, None, None] * gx + hull.A[:, 1, None, None] * gy
                  - (hull.b + epsilon_m)[:, None, None])
        corner_in = np.all(margin < -_INSIDE_M, axis=0)
        cell_in = corner_in[:-1, :-1] & corner_in[1:, :-1] & corner_in[:-1, 1:] & corner_in[1:, 1:]
        out[i0:i1, j0:j1] |= cell_in
    return out


@njit(cache=True)
def _window_min(src: AnyArray, src_box: AnyArray, out: AnyArray, out_box: AnyArray, k: int,
                scratch: AnyArray, pre: AnyArray, suf: AnyArray) -> None:
    """out[i, j] = min of src over the cells within k of (i, j) (on each axis) that lie in
    ``src_box`` (i0, j0, i1, j1), for (i, j) in ``out_box``; inf where there are none.

    Separable (along x into ``scratch``, then along y), each pass the van Herk–Gil-Werman
    scheme: prefix and suffix minima (``pre``, ``suf``: work arrays of at least
    (nx + 2k, ny + 2k)) over blocks of 2k + 1 cells, three comparisons a cell.
    """
    w = 2 * k + 1
    inf = np.float32(np.inf)
    si0, sj0, si1, sj1 = src_box[0], src_box[1], src_box[2], src_box[3]
    oi0, oj0, oi1, oj1 = out_box[0], out_box[1], out_box[2], out_box[3]
    # along x: rows p = i - (oi0 - k), i over [oi0 - k, oi1 + k]; columns j over the source's
    n = oi1 - oi0 + 2 * k + 1
    ncol = sj1 - sj0 + 1
    for b0 in range(0, n, w):  # blocks of w rows: minima from the block's start and end
        b1 = min(b0 + w, n)
        for p in range(b0, b1):
            d = p + oi0 - k
            inside = si0 <= d <= si1
            for c in range(ncol):
                v = src[d, sj0 + c] if inside else inf
                pre[p, c] = v if p == b0 else min(pre[p - 1, c], v)
        for p in range(b1 - 1, b0 - 1, -1):
            d = p + oi0 - k
            inside = si0 <= d <= si1
            for c in range(ncol):
                v = src[d, sj0 + c] if inside else inf
                suf[p, c] = v if p == b1 - 1 else min(suf[p + 1, c], v)
    for i in range(oi0, oi1 + 1):
        p0 = i - oi0
        for c in range(ncol):
            scratch[i, sj0 + c] = min(suf[p0, c], pre[p0 + w - 1, c])
    # along y, one row at a time (the row's values first, inf outside the source)
    m = oj1 - oj0 + 2 * k + 1
    row, row_pre, row_suf = pre[0], pre[1], suf[0]
    for i in range(oi0, oi1 + 1):
        for q in range(m):
            d = q + oj0 - k
            row[q] = scratch[i, d] if sj0 <= d <= sj1 else inf
        for b0 in range(0, m, w):
            b1 = min(b0 + w, m)
            row_pre[b0] = row[b0]
            for q in range(b0 + 1, b1):
                row_pre[q] = min(row_pre[q - 1], row[q])
            row_suf[b1 - 1] = row[b1 - 1]
            for q in range(b1 - 2, b0 - 1, -1):
                row_suf[q] = min(row_suf[q + 1], row[q])
        for j in range(oj0, oj1 + 1):
            q0 = j - oj0
            out[i, j] = min(row_suf[q0], row_pre[q0 + w - 1])


@njit(cache=True)
def _cell_d2(origin: AnyArray, h: float, goal: AnyArray, i: int, j: int) -> float:
    """Squared distance (m²) from ``goal`` to the closed cell (i, j)."""
    dx = max(origin[0] + i * h - goal[0], goal[0] - origin[0] - (i + 1) * h, 0.0)
    dy = max(origin[1] + j * h - goal[1], goal[1] - origin[1] - (j + 1) * h, 0.0)
    return dx * dx + dy * dy


@njit(cache=True)
def _propagate(blocked: AnyArray, first: AnyArray, last: AnyArray, start: AnyArray, k: int,
               origin: AnyArray, h: float, goal: AnyArray,
               value: AnyArray) -> tuple[AnyArray, AnyArray, AnyArray]:
    """Floors (m), prefix costs (m²; both inf from the first empty R_τ on) and cell boxes
    (i0, j0, i1, j1) of R_1..R_T; ``value`` (T, nx, ny, all inf) gets F_τ on R_τ. A step
    is the window minimum of F_{τ−1}, in the window R_{τ−1} can reach within the reach
    box of p_τ."""
    nx, ny = blocked.shape
    T = value.shape[0]
    floor = np.full(T, np.inf)
    prefix = np.full(T, np.inf)
    box = np.zeros((T, 4), dtype=np.int64)
    scratch = np.empty((nx, ny), dtype=np.float32)
    near = np.empty((nx, ny), dtype=np.float32)
    pre = np.empty((nx + 2 * k + 1, ny + 2 * k + 1), dtype=np.float32)
    suf = np.empty((nx + 2 * k + 1, ny + 2 * k + 1), dtype=np.float32)
    value[0, start[0], start[1]] = 0.0
    box[0, 0], box[0, 1], box[0, 2], box[0, 3] = start[0], start[1], start[0], start[1]
    floor[0] = math.sqrt(_cell_d2(origin, h, goal, start[0], start[1]))
    prefix[0] = 0.0
    window = np.empty(4, dtype=np.int64)
    for tau in range(1, T):
        a0, b0, a1, b1 = box[tau - 1, 0], box[tau - 1, 1], box[tau - 1, 2], box[tau - 1, 3]
        window[0], window[2] = max(a0 - k, first[tau, 0]), min(a1 + k, last[tau, 0])
        window[1], window[3] = max(b0 - k, first[tau, 1]), min(b1 + k, last[tau, 1])
        if window[0] > window[2] or window[1] > window[3]:
            return floor, prefix, box
        _window_min(value[tau - 1], box[tau - 1], near, window, k, scratch, pre, suf)
        n0, n1, m0, m1 = nx, -1, ny, -1
        least_d2, least_f = np.inf, np.inf
        for i in range(window[0], window[2] + 1):
            for j in range(window[1], window[3] + 1):
                if near[i, j] < np.inf and not blocked[i, j]:
                    d2 = _cell_d2(origin, h, goal, i, j)
                    f = d2 + near[i, j]
                    value[tau, i, j] = f
                    n0, n1, m0, m1 = min(n0, i), max(n1, i), min(m0, j), max(m1, j)
                    least_d2, least_f = min(least_d2, d2), min(least_f, f)
        if n1 < 0:
            return floor, prefix, box
        box[tau, 0], box[tau, 1], box[tau, 2], box[tau, 3] = n0, m0, n1, m1
        floor[tau], prefix[tau] = math.sqrt(least_d2), least_f
    return floor, prefix, box


@njit(cache=True)
def _suffix(value: AnyArray, cells: AnyArray, k: int, origin: AnyArray, h: float,
            goal: AnyArray) -> AnyArray:
    """min_c V_τ(c) per τ, V the same program run backward over the cells of R_τ (finite
    F): V_T = d², V_τ(c) = d(c)² + min {V_{τ+1}(c′) : c′ ∈ R_{τ+1} within k of c}, so
    every feasible trajectory has Σ_{σ=τ..T} ‖p_σ − G_o‖² ≥ min V_τ (τ ≥ 2)."""
    T, nx, ny = value.shape
    out = np.full(T, np.inf)
    cur = np.full((nx, ny), np.inf, dtype=np.float32)
    nxt = np.full((nx, ny), np.inf, dtype=np.float32)
    near = np.empty((nx, ny), dtype=np.float32)
    scratch = np.empty((nx, ny), dtype=np.float32)
    pre = np.empty((nx + 2 * k + 1, ny + 2 * k + 1), dtype=np.float32)
    suf = np.empty((nx + 2 * k + 1, ny + 2 * k + 1), dtype=np.float32)
    for tau in range(T - 1, 0, -1):
        i0, j0, i1, j1 = cells[tau, 0], cells[tau, 1], cells[tau, 2], cells[tau, 3]
        if tau < T - 1:
            _window_min(nxt, cells[tau + 1], near, cells[tau], k, scratch, pre, suf)
        least = np.inf
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                if value[tau, i, j] < np.inf:
                    v = _cell_d2(origin, h, goal, i, j) + (near[i, j] if tau < T - 1 else 0.0)
                    cur[i, j] = v
                    least = min(least, v)
                else:
                    cur[i, j] = np.inf
        out[tau] = least
        cur, nxt = nxt, cur
    return out


@njit(cache=True)
def _cheapest_path(value: AnyArray, cells: AnyArray, k: int) -> AnyArray:
    """Cell indices (T, 2): the cell of R_T with the least F_T, then back through
    R_{T−1}..R_1 the cell within k of the one after it with the least F."""
    T = value.shape[0]
    out = np.zeros((T, 2), dtype=np.int64)
    best, bi, bj = np.inf, cells[T - 1, 0], cells[T - 1, 1]
    for i in range(cells[T - 1, 0], cells[T - 1, 2] + 1):
        for j in range(cells[T - 1, 1], cells[T - 1, 3] + 1):
            if value[T - 1, i, j] < best:
                best, bi, bj = value[T - 1, i, j], i, j
    out[T - 1, 0], out[T - 1, 1] = bi, bj
    for tau in range(T - 2, -1, -1):
        best, ci, cj = np.inf, bi, bj
        for i in range(max(bi - k, cells[tau, 0]), min(bi + k, cells[tau, 2]) + 1):
            for j in range(max(bj - k, cells[tau, 1]), min(bj + k, cells[tau, 3]) + 1):
                if value[tau, i, j] < best:
                    best, ci, cj = value[tau, i, j], i, j
        bi, bj = ci, cj
        out[tau, 0], out[tau, 1] = bi, bj
    return out

"""A lower bound on the flights to G around the boxes that stay put: a distance field.

Boxes present at every sub-step of a known future (the hulls of now,
:mod:`dualpilot.spacetime.known`) block the same cells at every time: a cell whose four
corners all lie within d of one of them holds no safe position ever (the distance to a
box is convex). A breadth-first search over the other cells, eight neighbours a move,
from the cells that meet G, gives D(c), the fewest cell moves from c to G. A flight
moves the UAV at most ΔT·v_max per axis and a path that visits k cells of a king's walk
spans at least (k − 1) cells per axis, so from a position in cell c at least
⌈(D(c) − 1)·cell / (ΔT·v_max)⌉ flights remain: the A*'s heuristic
(:func:`dualpilot.spacetime.lattice.astar`) takes the larger of it and its own. Lengths m.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from dualpilot.arrays import AnyArray, Array

#: a cell from which G cannot be reached around the boxes
UNREACHABLE = np.iinfo(np.int32).max


def no_field() -> AnyArray:
    """The empty field: no bound beyond the A*'s own."""
    return np.empty((0, 0), dtype=np.int32)


@njit(cache=True)
def static_field(boxes: Array, goal: Array, area: float, d: float, cell: float) -> AnyArray:
    """D(c) over the cells of [0, area]² (rows y, columns x) around ``boxes`` kept at ``d``,
    to ``goal`` (x_lo, y_lo, x_hi, y_hi); :data:`UNREACHABLE` where G cannot be reached."""
    n = math.ceil(area / cell)
    blocked = np.zeros((n, n), dtype=np.bool_)
    d2 = d * d
    for k in range(len(boxes)):
        x0, y0, x1, y1 = boxes[k, 0], boxes[k, 1], boxes[k, 2], boxes[k, 3]
        i0, i1 = max(0, math.floor((y0 - d) / cell)), min(n, math.floor((y1 + d) / cell) + 1)
        j0, j1 = max(0, math.floor((x0 - d) / cell)), min(n, math.floor((x1 + d) / cell) + 1)
        for i in range(i0, i1):
            for j in range(j0, j1):
                inside = True
                for cy in (cell * i, cell * (i + 1)):
                    gy = max(0.0, max(y0 - cy, cy - y1))
                    for cx in (cell * j, cell * (j + 1)):
                        gx = max(0.0, max(x0 - cx, cx - x1))
                        if gx * gx + gy * gy >= d2:
                            inside = False
                if inside:
                    blocked[i, j] = True
    dist = np.full((n, n), UNREACHABLE, dtype=np.int32)
    queue = np.empty((n * n, 2), dtype=np.int64)
    head, tail = 0, 0
    for i in range(max(0, math.floor(goal[1] / cell)), min(n, math.floor(goal[3] / cell) + 1)):
        for j in range(max(0, math.floor(goal[0] / cell)), min(n, math.floor(goal[2] / cell) + 1)):
            if not blocked[i, j]:
                dist[i, j] = 0
                queue[tail] = (i, j)
                tail += 1
    while head < tail:
        i, j = queue[head]
        head += 1
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                a, b = i + di, j + dj
                if 0 <= a < n and 0 <= b < n and not blocked[a, b] and dist[a, b] == UNREACHABLE:
                    dist[a, b] = dist[i, j] + 1
                    queue[tail] = (a, b)
                    tail += 1
    return dist


@njit(cache=True)
def field_flights(field: AnyArray, cell: float, x: float, y: float, reach: float) -> int:
    """The flights the field says remain from (x, y) (m), ``reach`` m a flight per axis; 0 with
    no field, a large number where G cannot be reached."""
    if field.shape[0] == 0:
        return 0
    n = field.shape[0]
    i = min(n - 1, max(0, math.floor(y / cell)))
    j = min(n - 1, max(0, math.floor(x / cell)))
    cells = field[i, j]
    if cells == UNREACHABLE:
        return 1 << 20
    return max(0, math.ceil((cells - 1) * cell / reach - 1e-9))

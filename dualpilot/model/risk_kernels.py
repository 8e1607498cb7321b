"""The compiled kernels of the forecast's risk zones (dualpilot.model.risk).

The connected groups of risky cells and each group's convex hull of cell corners. A module
of its own so that importing the risk zones (the mission's configuration, every service
through it) does not import Numba; :func:`~dualpilot.model.risk.cell_hulls` loads it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dualpilot.arrays import AnyArray
from dualpilot.model.hull_kernels import faces, monotone_chain


@njit(cache=True)
def group_hulls(comp: AnyArray, row: AnyArray, first: AnyArray, last: AnyArray, res: float,
                ox: float, oy: float) -> tuple[AnyArray, AnyArray, AnyArray, AnyArray]:
    """Each group's hull of its cell squares' corners (Polytope.from_vertices' operations):
    vertices, normals and offsets stacked, and the end row of each group's."""
    n_groups = comp.max() + 1
    verts = np.empty((4 * len(comp), 2))
    normals = np.empty((4 * len(comp), 2))
    offsets = np.empty(4 * len(comp))
    ends = np.empty(n_groups, dtype=np.int64)
    at = 0
    for k in range(n_groups):
        sel = np.flatnonzero(comp == k)
        m = len(sel)
        corners = np.empty((4 * m, 2))
        for q in range(m):
            i = sel[q]
            y0 = oy + row[i] * res
            y1 = y0 + res
            x0 = ox + first[i] * res
            x1 = ox + (last[i] + 1) * res
            corners[q, 0], corners[q, 1] = x0, y0
            corners[m + q, 0], corners[m + q, 1] = x1, y0
            corners[2 * m + q, 0], corners[2 * m + q, 1] = x0, y1
            corners[3 * m + q, 0], corners[3 * m + q, 1] = x1, y1
        hull, _ = monotone_chain(corners)
        nrm, b = faces(hull)
        h = len(hull)
        verts[at:at + h] = hull
        normals[at:at + h] = nrm
        offsets[at:at + h] = b
        at += h
        ends[k] = at
    return verts[:at].copy(), normals[:at].copy(), offsets[:at].copy(), ends


@njit(cache=True)
def groups(risky: AnyArray) -> tuple[AnyArray, AnyArray, AnyArray, AnyArray]:
    """The runs of risky cells of each row (row, first, last column) and the 8-connected
    group (0, 1, …) each belongs to (runs of adjacent rows touching or diagonal: one group)."""
    ny, nx = risky.shape
    rows: list[int] = []
    firsts: list[int] = []
    lasts: list[int] = []
    row_start = np.zeros(ny + 1, dtype=np.int64)
    for r in range(ny):
        row_start[r] = len(rows)
        c = 0
        while c < nx:
            if risky[r, c]:
                c0 = c
                while c + 1 < nx and risky[r, c + 1]:
                    c += 1
                rows.append(r)
                firsts.append(c0)
                lasts.append(c)
            c += 1
    row_start[ny] = len(rows)
    n = len(rows)
    parent = np.arange(n)

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for r in range(1, ny):
        for i in range(row_start[r], row_start[r + 1]):
            for j in range(row_start[r - 1], row_start[r]):
                if firsts[i] <= lasts[j] + 1 and firsts[j] <= lasts[i] + 1:
                    a, b = find(i), find(j)
                    if a != b:
                        parent[max(a, b)] = min(a, b)
    comp = np.empty(n, dtype=np.int64)
    ids = np.full(n, -1, dtype=np.int64)
    count = 0
    for i in range(n):
        root = find(i)
        if ids[root] < 0:
            ids[root] = count
            count += 1
        comp[i] = ids[root]
    return (comp, np.array(rows, dtype=np.int64), np.array(firsts, dtype=np.int64),
            np.array(lasts, dtype=np.int64))

"""The compiled kernels of the convex polygons (dualpilot.model.geometry).

Andrew's monotone chain, the faces {p : α_l·p ≤ β_l} of counter-clockwise vertices and
the segment-to-hulls distances of :class:`~dualpilot.model.geometry.SegmentChecker` (m).
A module of its own so that importing the geometry (the codecs, the vehicle, the viewer)
does not import Numba; the geometry loads it where a hull is made or checked.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dualpilot.arrays import AnyArray, Array


@njit(cache=True)
def _cross(ox: float, oy: float, ax: float, ay: float, bx: float, by: float) -> float:
    return (ax - ox) * (by - oy) - (ay - oy) * (bx - ox)


@njit(cache=True)
def monotone_chain(pts: Array) -> tuple[Array, int]:
    """Andrew's monotone chain over the distinct rows of ``pts``, sorted by (x, y).

    Returns the hull (counter-clockwise) and the number of distinct points.
    """
    order = np.argsort(pts[:, 1], kind="mergesort")
    order = order[np.argsort(pts[order, 0], kind="mergesort")]
    uniq = np.empty((len(pts), 2))
    k = 0
    for i in order:
        if k and pts[i, 0] == uniq[k - 1, 0] and pts[i, 1] == uniq[k - 1, 1]:
            continue
        uniq[k] = pts[i]
        k += 1
    if k < 3:
        return uniq[:k], k
    chain = np.empty((2 * k, 2))
    n = 0
    for i in range(k):  # lower chain
        while n >= 2 and _cross(chain[n - 2, 0], chain[n - 2, 1], chain[n - 1, 0],
                                chain[n - 1, 1], uniq[i, 0], uniq[i, 1]) <= 1e-9:
            n -= 1
        chain[n] = uniq[i]
        n += 1
    n -= 1  # the last point starts the upper chain
    base = n
    for i in range(k - 1, -1, -1):  # upper chain
        while n - base >= 2 and _cross(chain[n - 2, 0], chain[n - 2, 1], chain[n - 1, 0],
                                       chain[n - 1, 1], uniq[i, 0], uniq[i, 1]) <= 1e-9:
            n -= 1
        chain[n] = uniq[i]
        n += 1
    return chain[: n - 1].copy(), k


@njit(cache=True)
def faces(v: Array) -> tuple[Array, Array]:
    """Unit outward normals α_l and offsets β_l of the edges of CCW vertices ``v``."""
    k = len(v)
    normals = np.empty((k, 2))
    b = np.empty(k)
    for i in range(k):
        j = (i + 1) % k
        nx, ny = v[j, 1] - v[i, 1], -(v[j, 0] - v[i, 0])
        norm = np.sqrt(nx * nx + ny * ny)
        normals[i, 0], normals[i, 1] = nx / norm, ny / norm
        b[i] = normals[i, 0] * v[i, 0] + normals[i, 1] * v[i, 1]
    return normals, b


@njit(cache=True)
def pseg_d2(px: float, py: float, ax: float, ay: float, dx: float, dy: float,
             inv_len2: float) -> float:
    """:func:`point_segment_d2` for one point and one segment (the same operations)."""
    t = min(max(((px - ax) * dx + (py - ay) * dy) * inv_len2, 0.0), 1.0)
    ex = px - ax - t * dx
    ey = py - ay - t * dy
    return ex * ex + ey * ey


@njit(cache=True)
def hull_distances(p0: Array, p1: Array, ax: Array, ay: Array, dx: Array, dy: Array,
                    inv_len2: Array, nx: Array, ny: Array, offsets: Array,
                    starts: AnyArray) -> Array:
    """Distance from each segment p0[i]–p1[i] to the nearest of the hulls (0 on contact).

    The nearest of the endpoint-to-edge and vertex-to-segment distances, 0 when
    the segment properly crosses an edge or starts inside a hull (every face's
    slack ≤ 0); the hulls' faces are the runs of ``starts``.
    """
    n, m, h = len(p0), len(ax), len(starts)
    out = np.empty(n)
    for i in range(n):
        x0, y0, x1, y1 = p0[i, 0], p0[i, 1], p1[i, 0], p1[i, 1]
        sx, sy = x1 - x0, y1 - y0
        slen2 = sx * sx + sy * sy
        inv = 1.0 / (slen2 if slen2 > 0 else 1.0)
        best = np.inf
        hit = False
        for j in range(m):
            d2 = min(pseg_d2(x0, y0, ax[j], ay[j], dx[j], dy[j], inv_len2[j]),
                     pseg_d2(x1, y1, ax[j], ay[j], dx[j], dy[j], inv_len2[j]))
            d2 = min(d2, pseg_d2(ax[j], ay[j], x0, y0, sx, sy, inv))
            if d2 < best:
                best = d2
            # a proper crossing of the segment with edge j (orientation tests)
            o1 = sx * (ay[j] - y0) - sy * (ax[j] - x0)
            o2 = sx * (ay[j] + dy[j] - y0) - sy * (ax[j] + dx[j] - x0)
            o3 = dx[j] * (y0 - ay[j]) - dy[j] * (x0 - ax[j])
            o4 = dx[j] * (y1 - ay[j]) - dy[j] * (x1 - ax[j])
            if (o1 * o2) < 0 and (o3 * o4) < 0:
                hit = True
        for k in range(h):  # the first endpoint inside hull k: every slack ≤ 0
            stop = starts[k + 1] if k + 1 < h else m
            worst = -np.inf
            for j in range(starts[k], stop):
                slack = x0 * nx[j] + y0 * ny[j] - offsets[j]
                if slack > worst:
                    worst = slack
            if worst <= 0.0:
                hit = True
        out[i] = 0.0 if hit else np.sqrt(best)
    return out

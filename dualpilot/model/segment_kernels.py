"""The compiled 3-D segment distances (dualpilot.model.prism, segment3, hull3d).

Segment to segment, and segments to prisms (the planar edge distances, the faces' slab
test, :class:`~dualpilot.model.segment3.SegmentChecker3`'s kernels), in m². A module of
its own so that importing the prisms and their checker (the plan, the fire model, every
service through them) does not import Numba; they load it where a distance is asked.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.hull_kernels import pseg_d2  # the planar operations: the same numbers

#: Segments whose direction's squared length is below this (m²) are points.
_DEGENERATE_M2 = 1e-18
#: Below this |α·d| a face is parallel to the segment (as in prism.segment_meets).
_PARALLEL = 1e-12


@njit(cache=True)
def segment_segment_d2(p: Array, d: Array, q: Array, e: Array) -> float:
    """Squared distance (m²) between the segments p + s·d and q + t·e, s, t ∈ [0, 1].

    The closest pair of the two lines, clamped to the segments (Ericson, *Real-Time
    Collision Detection*, 2005, §5.1.9); a degenerate segment is its point, and parallel
    segments take s = 0 first (their distance is attained at an endpoint).
    """
    r0, r1, r2 = p[0] - q[0], p[1] - q[1], p[2] - q[2]
    a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    c_e = e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
    f = e[0] * r0 + e[1] * r1 + e[2] * r2
    if a <= _DEGENERATE_M2 and c_e <= _DEGENERATE_M2:
        s, t = 0.0, 0.0
    elif a <= _DEGENERATE_M2:
        s, t = 0.0, min(1.0, max(0.0, f / c_e))
    else:
        c = d[0] * r0 + d[1] * r1 + d[2] * r2
        if c_e <= _DEGENERATE_M2:
            s, t = min(1.0, max(0.0, -c / a)), 0.0
        else:
            b = d[0] * e[0] + d[1] * e[1] + d[2] * e[2]
            denom = a * c_e - b * b
            s = min(1.0, max(0.0, (b * f - c * c_e) / denom)) if denom > 1e-14 * a * c_e else 0.0
            t = (b * s + f) / c_e
            if t < 0.0:
                t, s = 0.0, min(1.0, max(0.0, -c / a))
            elif t > 1.0:
                t, s = 1.0, min(1.0, max(0.0, (b - c) / a))
    x = r0 + s * d[0] - t * e[0]
    y = r1 + s * d[1] - t * e[1]
    z = r2 + s * d[2] - t * e[2]
    return x * x + y * y + z * z


@njit(cache=True)
def edges_d2(p: Array, d: Array, starts: Array, vecs: Array) -> float:
    """The least squared distance (m²) from the segment p + s·d to the edges (rows)."""
    best = np.inf
    for j in range(len(starts)):
        best = min(best, segment_segment_d2(p, d, starts[j], vecs[j]))
    return best


@njit(cache=True)
def planar(p0: Array, p1: Array, fs: int, fe: int, ax: Array, ay: Array, dx: Array,
           dy: Array, inv_len2: Array, nx: Array, ny: Array, offsets: Array) -> tuple[float, bool]:
    """(least squared distance, contact) of the planar segment to one hull's edges fs..fe−1:
    hull_kernels.hull_distances for one hull."""
    x0, y0, x1, y1 = p0[0], p0[1], p1[0], p1[1]
    sx, sy = x1 - x0, y1 - y0
    slen2 = sx * sx + sy * sy
    inv = 1.0 / (slen2 if slen2 > 0 else 1.0)
    best = np.inf
    hit = False
    for j in range(fs, fe):
        d2 = min(pseg_d2(x0, y0, ax[j], ay[j], dx[j], dy[j], inv_len2[j]),
                 pseg_d2(x1, y1, ax[j], ay[j], dx[j], dy[j], inv_len2[j]))
        d2 = min(d2, pseg_d2(ax[j], ay[j], x0, y0, sx, sy, inv))
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
def meets(p0: Array, p1: Array, fs: int, fe: int, nx: Array, ny: Array, offsets: Array,
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
def point_d2(p: Array, fs: int, fe: int, ax: Array, ay: Array, dx: Array, dy: Array,
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
            d2 = min(d2, pseg_d2(p[0], p[1], ax[j], ay[j], dx[j], dy[j], inv_len2[j]))
    dz = max(0.0, zlo - p[2], p[2] - zhi)
    return d2 + dz * dz


@njit(cache=True)
def one_prism_d2(p0: Array, p1: Array, k: int, ax: Array, ay: Array, dx: Array, dy: Array,
                 inv_len2: Array, nx: Array, ny: Array, offsets: Array, starts: AnyArray,
                 zlo: Array, zhi: Array, e_start: Array, e_vec: Array,
                 e_first: AnyArray) -> float:
    """Squared distance (m²) from the segment p0–p1 to prism k (0 on contact)."""
    h = len(starts)
    fs = starts[k]
    fe = starts[k + 1] if k + 1 < h else len(ax)
    if zlo[k] <= p0[2] <= zhi[k] and zlo[k] <= p1[2] <= zhi[k]:
        best, hit = planar(p0, p1, fs, fe, ax, ay, dx, dy, inv_len2, nx, ny, offsets)
        return 0.0 if hit else best
    if meets(p0, p1, fs, fe, nx, ny, offsets, zlo[k], zhi[k]):
        return 0.0
    d = p1 - p0
    best = min(point_d2(p0, fs, fe, ax, ay, dx, dy, inv_len2, nx, ny, offsets, zlo[k],
                         zhi[k]),
               point_d2(p1, fs, fe, ax, ay, dx, dy, inv_len2, nx, ny, offsets, zlo[k],
                         zhi[k]))
    for j in range(e_first[k], e_first[k + 1]):
        best = min(best, segment_segment_d2(p0, d, e_start[j], e_vec[j]))
    return best


@njit(cache=True)
def prism_distances(p0: Array, p1: Array, ax: Array, ay: Array, dx: Array, dy: Array,
                    inv_len2: Array, nx: Array, ny: Array, offsets: Array, starts: AnyArray,
                    zlo: Array, zhi: Array, e_start: Array, e_vec: Array,
                    e_first: AnyArray) -> Array:
    """Distance (m) from each segment p0[i]–p1[i] to the nearest prism (0 on contact)."""
    n = len(p0)
    out = np.empty(n)
    for i in range(n):
        best = np.inf
        for k in range(len(starts)):
            d2 = one_prism_d2(p0[i], p1[i], k, ax, ay, dx, dy, inv_len2, nx, ny, offsets,
                               starts, zlo, zhi, e_start, e_vec, e_first)
            if d2 < best:
                best = d2
            if best == 0.0:
                break
        out[i] = np.sqrt(best)
    return out

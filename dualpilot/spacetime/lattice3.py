"""Compiled kernels of the oracle's search in 3-D: the A* of :mod:`.lattice` over the band.

A lattice state at step t is a position p = p_0 + h·(i_x, i_y, i_z) and a velocity
v = δ·(j_x, j_y, j_z), h = δ·ΔT, as in the plane, the vertical velocity on the
sub-lattice j_z ∈ {−1, 0, 1} (docs/three_d.md §9: a witness on a sub-lattice is still a
trajectory of Eq. (1), the control u = m·(v' − (1 − ζ)·v)/ΔT exact; completeness is
claimed on that lattice only). Positions keep i_z within [``iz_lo``, ``iz_hi``] (the
band, or a stage's part of it).

The regions are cuboids, rows (x_lo, y_lo, x_hi, y_hi, top) over the ground (bottom 0):
a point's distance is √(d_xy² + d_z²); a segment whose altitudes lie within [0, top] is
at its planar distance (:func:`~dualpilot.spacetime.lattice.segment_box_d2`), any other at
0 when it meets the cuboid (slab test) and else at the least of its ends' distances and its
distances to the cuboid's 12 edges (two disjoint convex sets are nearest at an end, an
edge or a vertex; :func:`~dualpilot.model.segment_kernels.segment_segment_d2`). The
failure rules and the heuristic (the largest of the three axes' fewest flights, each
admissible) are the plane's. Lengths m, speeds m/s.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numba import types as nbt
from numba.typed import Dict

from dualpilot.arrays import AnyArray, Array
from dualpilot.model.segment_kernels import segment_segment_d2
from dualpilot.spacetime.lattice import (
    BUDGET,
    EXHAUSTED,
    FOUND,
    _entry,
    _grown,
    _heap_pop,
    _heap_push,
    flights_needed,
    segment_box_d2,
)

__all__ = ["astar3", "move_clear3", "segment_cuboid_d2"]

#: bits of a heap entry that hold the node (as in the plane)
_ID_BITS = 26


@njit(cache=True)
def _point_d2(x: float, y: float, z: float, b: Array, k: int) -> float:
    gx = max(0.0, max(b[k, 0] - x, x - b[k, 2]))
    gy = max(0.0, max(b[k, 1] - y, y - b[k, 3]))
    gz = max(0.0, max(-z, z - b[k, 4]))
    return gx * gx + gy * gy + gz * gz


@njit(cache=True)
def _meets(a: Array, e: Array, lo: Array, hi: Array) -> bool:
    """Whether the segment a + s·e, s ∈ [0, 1], meets the box [lo, hi] (slabs)."""
    t0, t1 = 0.0, 1.0
    for i in range(3):
        if e[i] == 0.0:
            if a[i] < lo[i] or a[i] > hi[i]:
                return False
            continue
        r0, r1 = (lo[i] - a[i]) / e[i], (hi[i] - a[i]) / e[i]
        t0, t1 = max(t0, min(r0, r1)), min(t1, max(r0, r1))
        if t0 > t1:
            return False
    return True


@njit(cache=True)
def segment_cuboid_d2(ax: float, ay: float, az: float, bx: float, by: float, bz: float,
                      boxes: Array, k: int) -> float:
    """Squared distance (m²) between the segment a–b and cuboid ``boxes[k]`` (module
    docstring)."""
    top = boxes[k, 4]
    if min(az, bz) >= 0.0 and max(az, bz) <= top:
        return segment_box_d2(ax, ay, bx, by, boxes[k, 0], boxes[k, 1], boxes[k, 2],
                              boxes[k, 3])
    a = np.array([ax, ay, az])
    e = np.array([bx - ax, by - ay, bz - az])
    lo = np.array([boxes[k, 0], boxes[k, 1], 0.0])
    hi = np.array([boxes[k, 2], boxes[k, 3], top])
    if _meets(a, e, lo, hi):
        return 0.0
    best = min(_point_d2(ax, ay, az, boxes, k), _point_d2(bx, by, bz, boxes, k))
    corner = np.empty(3)
    edge = np.zeros(3)
    for axis in range(3):  # the 4 edges along each axis
        for u in range(2):
            for w in range(2):
                i1, i2 = (axis + 1) % 3, (axis + 2) % 3
                corner[axis] = lo[axis]
                corner[i1] = lo[i1] if u == 0 else hi[i1]
                corner[i2] = lo[i2] if w == 0 else hi[i2]
                edge[:] = 0.0
                edge[axis] = hi[axis] - lo[axis]
                best = min(best, segment_segment_d2(a, e, corner, edge))
    return best


@njit(cache=True)
def segment_clear3(ax: float, ay: float, az: float, bx: float, by: float, bz: float,
                   boxes: Array, lo: int, hi: int, d: float) -> bool:
    """Whether the segment a–b keeps at least ``d`` from every cuboid ``boxes[lo:hi]``."""
    lox, hix = min(ax, bx), max(ax, bx)
    loy, hiy = min(ay, by), max(ay, by)
    loz = min(az, bz)
    d2 = d * d
    for k in range(lo, hi):
        gx = max(0.0, max(boxes[k, 0] - hix, lox - boxes[k, 2]))
        gy = max(0.0, max(boxes[k, 1] - hiy, loy - boxes[k, 3]))
        gz = max(0.0, loz - boxes[k, 4])
        if gx * gx + gy * gy + gz * gz >= d2:
            continue
        if segment_cuboid_d2(ax, ay, az, bx, by, bz, boxes, k) < d2:
            return False
    return True


@njit(cache=True)
def move_clear3(a: Array, b: Array, t: int, k: int, boxes: Array, offsets: AnyArray,
                d: float) -> bool:
    """The failure rules of step t's move a → b (m, (3,) each) against the cuboids, ``k``
    sub-steps a step (:func:`dualpilot.spacetime.lattice.move_clear`'s, in 3-D)."""
    s = t * k + 1
    if not segment_clear3(a[0], a[1], a[2], a[0], a[1], a[2], boxes, offsets[s],
                          offsets[s + 1], d):
        return False
    for m in range(s + 1, (t + 1) * k + 1):
        if not segment_clear3(b[0], b[1], b[2], b[0], b[1], b[2], boxes, offsets[m],
                              offsets[m + 1], d):
            return False
    e = (t + 1) * k
    return segment_clear3(a[0], a[1], a[2], b[0], b[1], b[2], boxes, offsets[e],
                          offsets[e + 1], d)


@njit(cache=True)
def _successors3(t: int, p: Array, j: AnyArray, rel: Array, iz_next: int, iz_lo: int,
                 iz_hi: int, delta: float, n_vel: int, keep: float, acc: float, norm: bool,
                 max_steps: int, table: Array) -> AnyArray:
    """Rows (j_x, j_y, j_z, h) of the lattice velocities a step from ``j`` reaches (j_z on the
    sub-lattice, the next flight's end within [iz_lo, iz_hi]), with the heuristic of the
    node at ``p`` (m from the origin) at step t + 1; those that cannot reach G left out."""
    bounds = np.empty((3, 2), dtype=np.int64)
    for i in range(3):
        bounds[i, 0] = max(-n_vel, math.ceil((keep * j[i] * delta - acc) / delta - 1e-9))
        bounds[i, 1] = min(n_vel, math.floor((keep * j[i] * delta + acc) / delta + 1e-9))
    bounds[2, 0], bounds[2, 1] = max(bounds[2, 0], -1), min(bounds[2, 1], 1)
    out = np.empty((3 * (2 * n_vel + 1) ** 2, 4), dtype=np.int64)
    m, left = 0, max_steps - t - 1
    for kz in range(bounds[2, 0], bounds[2, 1] + 1):
        if not iz_lo <= iz_next + kz <= iz_hi:
            continue
        hz = flights_needed(p[2], kz, rel[2], rel[5], table, n_vel, left)
        if hz > left:
            continue
        for kx in range(bounds[0, 0], bounds[0, 1] + 1):
            hx = flights_needed(p[0], kx, rel[0], rel[3], table, n_vel, left)
            if hx > left:
                continue
            for ky in range(bounds[1, 0], bounds[1, 1] + 1):
                if norm and kx * kx + ky * ky + kz * kz > n_vel * n_vel:
                    continue
                hy = flights_needed(p[1], ky, rel[1], rel[4], table, n_vel, left)
                if hy > left:
                    continue
                out[m] = (kx, ky, kz, max(hx, hy, hz))
                m += 1
    return out[:m]


@njit(cache=True)
def astar3(origin: Array, t0: int, v_init: AnyArray, boxes: Array, offsets: AnyArray, k: int,
           goal: Array, area: float, iz_lo: int, iz_hi: int, d: float, delta: float, dt: float,
           n_vel: int, keep: float, acc: float, norm: bool, max_steps: int, budget: int,
           table: Array, weight16: int) -> tuple[int, AnyArray, int]:
    """Time-expanded A* from ``origin`` (3,) at step ``t0`` with any velocity of ``v_init``
    (rows j_x, j_y, j_z; the oracle's: at rest at step 0) to a flight that ends in ``goal``
    (x_lo, y_lo, z_lo, x_hi, y_hi, z_hi), the failure rules at ``d`` from the cuboids
    (module docstring), positions i_z within [``iz_lo``, ``iz_hi``] (lattice indices from
    the origin). Priority t + (weight16/16)·h; one node per step, position and velocity.
    Returns (outcome, path rows (t, i_x, i_y, i_z, j_x, j_y, j_z), expansions)."""
    h = delta * dt
    rel = goal - np.concatenate((origin, origin))
    seen = Dict.empty(key_type=nbt.int64, value_type=nbt.int8)
    nodes, goal_node, heap, n = _start3(v_init, t0, rel, table, n_vel, max_steps, weight16)
    size, expansions = n, 0
    a, b = np.empty(3), np.empty(3)
    while size > 0:
        if expansions >= budget or n >= (1 << _ID_BITS) - 64:
            return BUDGET, np.empty((0, 7), dtype=np.int64), expansions
        node = int(_heap_pop(heap, size) & ((1 << _ID_BITS) - 1))
        size -= 1
        if goal_node[node]:
            return FOUND, _path3(nodes, node), expansions
        expansions += 1
        t = nodes[node, 0]
        for i in range(3):
            a[i] = origin[i] + h * nodes[node, 1 + i]
            b[i] = a[i] + h * nodes[node, 4 + i]
        if t >= max_steps or not (0.0 <= b[0] <= area and 0.0 <= b[1] <= area) or \
                not move_clear3(a, b, t, k, boxes, offsets, d):
            continue
        i1 = nodes[node, 1:4] + nodes[node, 4:7]
        p1 = h * i1.astype(np.float64)
        landed = rel[0] <= p1[0] <= rel[3] and rel[1] <= p1[1] <= rel[4] and \
            rel[2] <= p1[2] <= rel[5]
        if landed:
            succ = np.zeros((1, 4), dtype=np.int64)
            succ[0, :3] = nodes[node, 4:7]
        else:
            succ = _successors3(t, p1, nodes[node, 4:7], rel, i1[2], iz_lo, iz_hi,
                                delta, n_vel, keep, acc, norm, max_steps, table)
        nodes, goal_node, heap, n, size = _children3(nodes, goal_node, heap, n, size, seen,
                                                     node, t, i1, succ, landed, n_vel,
                                                     weight16, max_steps)
    return EXHAUSTED, np.empty((0, 7), dtype=np.int64), expansions


@njit(cache=True)
def _children3(nodes: AnyArray, goal_node: AnyArray, heap: AnyArray, n: int, size: int,
               seen: Any, node: int, t: int, i1: AnyArray, succ: AnyArray, landed: bool,
               n_vel: int, weight16: int, max_steps: int
               ) -> tuple[AnyArray, AnyArray, AnyArray, int, int]:
    """Queue the children of ``node`` at lattice position ``i1``, step t + 1: a child whose
    step, position and velocity were queued before is dropped unless it ends the search."""
    nv = 2 * n_vel + 1
    base = ((((t + 1) * 4096 + i1[0] + 2048) * 4096 + i1[1] + 2048) * 256 + i1[2] + 128)
    for r in range(len(succ)):
        kx, ky, kz = succ[r, 0], succ[r, 1], succ[r, 2]
        key = ((base * nv + kx + n_vel) * nv + ky + n_vel) * 3 + kz + 1
        if not landed:
            if key in seen:
                continue
            seen[key] = np.int8(1)
        nodes = _grown(nodes, n + 1)
        goal_node = _grown(goal_node, n + 1)
        nodes[n] = (t + 1, i1[0], i1[1], i1[2], kx, ky, kz, node)
        goal_node[n] = landed
        heap = _heap_push(heap, size, _entry(t + 1, succ[r, 3], weight16, max_steps, n))
        n, size = n + 1, size + 1
    return nodes, goal_node, heap, n, size


@njit(cache=True)
def _start3(v_init: AnyArray, t0: int, rel: Array, table: Array, n_vel: int, max_steps: int,
            weight16: int) -> tuple[AnyArray, AnyArray, AnyArray, int]:
    """The queue at the start: the origin at step ``t0`` with each velocity of ``v_init`` that
    can still reach G (``rel``, relative to the origin) within ``max_steps``."""
    nodes = np.empty((1 << 14, 8), dtype=np.int64)  # t, i (3), j (3), parent
    goal_node = np.zeros(1 << 14, dtype=np.bool_)
    heap = np.empty(1 << 14, dtype=np.int64)
    n, left = 0, max_steps - t0
    for r in range(len(v_init)):
        first = max(flights_needed(0.0, v_init[r, 0], rel[0], rel[3], table, n_vel, left),
                    flights_needed(0.0, v_init[r, 1], rel[1], rel[4], table, n_vel, left),
                    flights_needed(0.0, v_init[r, 2], rel[2], rel[5], table, n_vel, left))
        if t0 + first <= max_steps:
            nodes[n] = (t0, 0, 0, 0, v_init[r, 0], v_init[r, 1], v_init[r, 2], -1)
            heap = _heap_push(heap, n, _entry(t0, first, weight16, max_steps, n))
            n += 1
    return nodes, goal_node, heap, n


@njit(cache=True)
def _path3(nodes: AnyArray, last: int) -> AnyArray:
    """Rows (t, i_x, i_y, i_z, j_x, j_y, j_z) from the start to ``last``."""
    count, node = 0, last
    while node >= 0:
        count += 1
        node = nodes[node, 7]
    out = np.empty((count, 7), dtype=np.int64)
    node = last
    for i in range(count - 1, -1, -1):
        out[i] = nodes[node, :7]
        node = nodes[node, 7]
    return out

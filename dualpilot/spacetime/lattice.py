"""Compiled kernels of the oracle's search: a time-expanded A* over a lattice of Eq. (1)'s states.

A lattice state at step t is a position p = p_0 + h·(i_x, i_y) and a velocity
v = δ·(j_x, j_y), h = δ·ΔT, so that p_{t+1} = p_t + ΔT·v_t (Eq. 1) stays on the
lattice. From v a step reaches every lattice velocity v' with
|v'_i − (1 − ζ)·v_i| ≤ ΔT·u_max/m per axis (|u_i| ≤ u_max) inside the speed limit
(per axis, or ‖v'‖ ≤ v_max): the control u = m·(v' − (1 − ζ)·v)/ΔT is exact.

The move of step t, p_t → p_t + ΔT·v_t, is fixed by the state; it is safe when
(the failure rules of dualpilot/mission/step.py with rule "any")

* p_t keeps ``d`` from every region after the step's planning sub-step tk + 1,
* p_{t+1} keeps ``d`` from every region after each of the step's motion sub-steps,
* the segment p_t–p_{t+1} keeps ``d`` from every region after the step's last
  sub-step (t + 1)k,

and p_{t+1} lies in the area. The search is A* on (t, p, v) with the number of
flights as the cost and an admissible heuristic: per axis, the fewest flights whose
reachable displacement interval meets G (:func:`reach_table`), the larger of the
two axes. Ties go to the deeper node. Lengths m, speeds m/s.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numba import types as nbt
from numba.typed import Dict

from dualpilot.arrays import AnyArray, Array
from dualpilot.spacetime.field import field_flights

#: search outcomes
FOUND, EXHAUSTED, BUDGET = 0, 1, 2
#: a heuristic for a goal out of reach within the steps left
FAR = 1 << 20


@njit(cache=True)
def segment_box_d2(ax: float, ay: float, bx: float, by: float, x0: float, y0: float,
                   x1: float, y1: float) -> float:
    """Squared distance (m²) between the segment a–b and the box [x0, x1] × [y0, y1]."""
    dx, dy = bx - ax, by - ay
    t0, t1 = 0.0, 1.0  # Liang–Barsky: does the segment cross the box?
    crosses = True
    for p, q in ((-dx, ax - x0), (dx, x1 - ax), (-dy, ay - y0), (dy, y1 - ay)):
        if p == 0.0:
            if q < 0.0:
                crosses = False
                break
        else:
            r = q / p
            if p < 0.0:
                t0 = max(t0, r)
            else:
                t1 = min(t1, r)
            if t0 > t1:
                crosses = False
                break
    if crosses:
        return 0.0
    best = math.inf
    for px, py in ((ax, ay), (bx, by)):  # the ends against the box
        gx = max(0.0, max(x0 - px, px - x1))
        gy = max(0.0, max(y0 - py, py - y1))
        best = min(best, gx * gx + gy * gy)
    seg2 = dx * dx + dy * dy
    for cx, cy in ((x0, y0), (x1, y0), (x1, y1), (x0, y1)):  # the corners against the segment
        s = 0.0 if seg2 == 0.0 else min(1.0, max(0.0, ((cx - ax) * dx + (cy - ay) * dy) / seg2))
        ex, ey = ax + s * dx - cx, ay + s * dy - cy
        best = min(best, ex * ex + ey * ey)
    return best


@njit(cache=True)
def segment_clear(ax: float, ay: float, bx: float, by: float, boxes: Array, lo: int, hi: int,
                  d: float) -> bool:
    """Whether the segment a–b keeps at least ``d`` from every box ``boxes[lo:hi]``."""
    lox, hix = min(ax, bx), max(ax, bx)
    loy, hiy = min(ay, by), max(ay, by)
    d2 = d * d
    for k in range(lo, hi):
        x0, y0, x1, y1 = boxes[k, 0], boxes[k, 1], boxes[k, 2], boxes[k, 3]
        gx = max(0.0, max(x0 - hix, lox - x1))
        gy = max(0.0, max(y0 - hiy, loy - y1))
        if gx * gx + gy * gy >= d2:
            continue
        if segment_box_d2(ax, ay, bx, by, x0, y0, x1, y1) < d2:
            return False
    return True


@njit(cache=True)
def move_clear(ax: float, ay: float, bx: float, by: float, t: int, k: int, boxes: Array,
               offsets: AnyArray, d: float) -> bool:
    """The failure rules of step t's move a → b (module docstring), ``k`` sub-steps a step."""
    s = t * k + 1
    if not segment_clear(ax, ay, ax, ay, boxes, offsets[s], offsets[s + 1], d):
        return False
    for m in range(s + 1, (t + 1) * k + 1):
        if not segment_clear(bx, by, bx, by, boxes, offsets[m], offsets[m + 1], d):
            return False
    e = (t + 1) * k
    return segment_clear(ax, ay, bx, by, boxes, offsets[e], offsets[e + 1], d)


def reach_table(n_vel: int, delta: float, keep: float, acc: float, v_max: float, dt: float,
                steps: int) -> Array:
    """D[j + n_vel, k]: the largest displacement along an axis after k flights from the
    lattice velocity j·δ (m), every later velocity at min((1 − ζ)·v + ΔT·u_max/m, v_max)."""
    table = np.zeros((2 * n_vel + 1, steps + 1))
    for j in range(-n_vel, n_vel + 1):
        w, total = j * delta, 0.0
        for k in range(1, steps + 1):
            total += dt * w
            table[j + n_vel, k] = total
            w = min(keep * w + acc, v_max)
    return table


@njit(cache=True)
def flights_needed(p: float, j: int, lo: float, hi: float, table: Array, n_vel: int,
                   limit: int) -> int:
    """The fewest flights k ≥ 1 after which the displacement interval from p with velocity
    index j meets [lo, hi] (``FAR`` when none within ``limit``)."""
    for k in range(1, limit + 1):
        up = p + table[j + n_vel, k]
        down = p - table[n_vel - j, k]
        if up >= lo and down <= hi:
            return k
    return FAR


@njit(cache=True)
def _grown(a: AnyArray, n: int) -> AnyArray:
    """``a`` with room for at least ``n`` rows (doubled)."""
    if n <= len(a):
        return a
    out = np.empty((max(n, 2 * len(a)),) + a.shape[1:], dtype=a.dtype)
    out[: len(a)] = a
    return out


@njit(cache=True)
def _heap_push(heap: AnyArray, size: int, item: np.int64) -> AnyArray:
    heap = _grown(heap, size + 1)
    i = size
    heap[i] = item
    while i > 0:
        parent = (i - 1) >> 1
        if heap[parent] <= heap[i]:
            break
        heap[parent], heap[i] = heap[i], heap[parent]
        i = parent
    return heap


@njit(cache=True)
def _heap_pop(heap: AnyArray, size: int) -> np.int64:
    """The smallest item; the heap's first ``size - 1`` entries are a heap again."""
    top = heap[0]
    size -= 1
    heap[0] = heap[size]
    i = 0
    while True:
        left, small = 2 * i + 1, i
        if left < size and heap[left] < heap[small]:
            small = left
        if left + 1 < size and heap[left + 1] < heap[small]:
            small = left + 1
        if small == i:
            break
        heap[small], heap[i] = heap[i], heap[small]
        i = small
    return top


#: bits of a heap entry that hold the node (the rest: the priority)
_ID_BITS = 26


@njit(cache=True)
def _entry(t: int, hval: int, weight16: int, max_steps: int, node: int) -> np.int64:
    """A heap entry: priority 16·t + weight16·h (then the deeper node first), then the node."""
    prio = (np.int64(16 * t + weight16 * hval) << 12) | min(4095, max_steps - t)
    return (prio << _ID_BITS) | node


@njit(cache=True)
def _successors(t: int, px: float, py: float, jx: int, jy: int, goal: Array, delta: float,
                dt: float, n_vel: int, keep: float, acc: float, v_max: float, norm: bool,
                max_steps: int, table: Array) -> AnyArray:
    """Rows (j_x, j_y, h) of the lattice velocities a step from velocity (j_x, j_y) can reach,
    with the heuristic h of the node at (px, py) relative to the lattice origin, step t + 1;
    those that cannot reach G within ``max_steps`` flights left out."""
    lox = max(-n_vel, math.ceil((keep * jx * delta - acc) / delta - 1e-9))
    hix = min(n_vel, math.floor((keep * jx * delta + acc) / delta + 1e-9))
    loy = max(-n_vel, math.ceil((keep * jy * delta - acc) / delta - 1e-9))
    hiy = min(n_vel, math.floor((keep * jy * delta + acc) / delta + 1e-9))
    out = np.empty((max(0, (hix - lox + 1) * (hiy - loy + 1)), 3), dtype=np.int64)
    m, left = 0, max_steps - t - 1
    for kx in range(lox, hix + 1):
        hx = flights_needed(px, kx, goal[0], goal[2], table, n_vel, left)
        if hx > left:
            continue
        for ky in range(loy, hiy + 1):
            if norm and (kx * kx + ky * ky) * delta * delta > v_max * v_max + 1e-9:
                continue
            hy = flights_needed(py, ky, goal[1], goal[3], table, n_vel, left)
            if hy > left:
                continue
            out[m] = (kx, ky, max(hx, hy))
            m += 1
    return out[:m]


@njit(cache=True)
def astar(origin: Array, t0: int, v_init: AnyArray, boxes: Array, offsets: AnyArray, k: int,
          goal: Array, area: float, d: float, delta: float, dt: float, n_vel: int, keep: float,
          acc: float, v_max: float, norm: bool, max_steps: int, budget: int, table: Array,
          weight16: int, bucket: int, field: AnyArray, field_cell: float, survive: int = 0
          ) -> tuple[int, AnyArray, int]:
    """Time-expanded A* from ``origin`` at step ``t0`` with any velocity of ``v_init`` (rows
    j_x, j_y) to a flight that ends in ``goal`` (x_lo, y_lo, x_hi, y_hi); the failure rules of
    the module docstring at distance ``d``, the fires of step t in sub-steps t·k + 1..(t+1)·k.

    Priority t + (weight16/16)·h (16: A*, the fewest flights on the lattice; more: weighted
    A*, faster and within that factor of the fewest). A node is dropped when one with the
    same t and velocity was already queued in its square of ``bucket`` × ``bucket`` lattice
    positions (1: none is). ``field`` (cells of ``field_cell`` m over the area,
    :mod:`dualpilot.spacetime.field`; empty: none) bounds the flights left around the boxes
    that stay put. With ``survive`` > 0 the search is for a path that lasts until step
    ``survive`` anywhere (``goal`` is then the area it may go). Returns (outcome, path,
    expansions): ``path`` rows (t, i_x, i_y, j_x, j_y) from ``origin`` to the first state in
    G (outcome FOUND), or empty (EXHAUSTED: no path within ``max_steps`` flights; BUDGET:
    ``budget`` expansions spent).
    """
    h = delta * dt
    sx, sy = origin[0], origin[1]
    frame = _frame(sx, sy, h, area, bucket, n_vel)
    rel = np.array([goal[0] - sx, goal[1] - sy, goal[2] - sx, goal[3] - sy])
    seen = Dict.empty(key_type=nbt.int64, value_type=nbt.int8)
    reach = dt * v_max
    floor0 = field_flights(field, field_cell, sx, sy, reach)
    nodes, goal_node, heap, n = _start(v_init, t0, rel, table, n_vel, max_steps, floor0,
                                       weight16)
    size, expansions = n, 0
    while size > 0:
        if expansions >= budget or n >= (1 << _ID_BITS) - 64:
            return BUDGET, np.empty((0, 5), dtype=np.int64), expansions
        node = int(_heap_pop(heap, size) & ((1 << _ID_BITS) - 1))
        size -= 1
        if goal_node[node]:
            return FOUND, _path(nodes, node), expansions
        expansions += 1
        t, ix, iy, jx, jy = nodes[node, 0], nodes[node, 1], nodes[node, 2], nodes[node, 3], \
            nodes[node, 4]
        ax, ay = sx + h * ix, sy + h * iy
        bx, by = ax + h * jx, ay + h * jy
        if t >= max_steps or not (0.0 <= bx <= area and 0.0 <= by <= area) or not move_clear(
                ax, ay, bx, by, t, k, boxes, offsets, d):
            continue
        ix1, iy1 = ix + jx, iy + jy
        landed = _lands(t, h * ix1, h * iy1, rel, survive)
        floor = 0 if landed else field_flights(field, field_cell, bx, by, reach)
        if t + 1 + floor > max_steps:
            continue
        succ = np.array([[jx, jy, 0]], dtype=np.int64) if landed else _successors(
            t, h * ix1, h * iy1, jx, jy, rel, delta, dt, n_vel, keep, acc, v_max, norm,
            max_steps, table)
        nodes, goal_node, heap, n, size = _children(
            nodes, goal_node, heap, n, size, seen, frame, node, t, ix1, iy1, succ, landed,
            floor, weight16, max_steps)
    return EXHAUSTED, np.empty((0, 5), dtype=np.int64), expansions


@njit(cache=True)
def _frame(sx: float, sy: float, h: float, area: float, bucket: int, n_vel: int
           ) -> tuple[int, int, int, int, int, int]:
    """The grid of the duplicate check: (i_x0, i_y0, nx, ny, ``bucket``, ``n_vel``), the lowest
    lattice indices inside the area from the origin (sx, sy) at spacing ``h`` (m), the
    buckets of ``bucket`` × ``bucket`` positions a side, and the velocities an axis."""
    ix0, iy0 = math.ceil(-sx / h - 1e-9), math.ceil(-sy / h - 1e-9)
    nx = (math.floor((area - sx) / h + 1e-9) - ix0) // bucket + 1
    ny = (math.floor((area - sy) / h + 1e-9) - iy0) // bucket + 1
    return ix0, iy0, nx, ny, bucket, n_vel


@njit(cache=True)
def _start(v_init: AnyArray, t0: int, rel: Array, table: Array, n_vel: int, max_steps: int,
           floor0: int, weight16: int) -> tuple[AnyArray, AnyArray, AnyArray, int]:
    """The queue at the start: the origin (lattice position 0, 0) at step ``t0`` with each
    velocity of ``v_init`` that can still reach G (``rel``, relative to the origin) within
    ``max_steps``. Returns (nodes, goal flags, heap, count), one heap entry per node."""
    nodes = np.empty((1 << 14, 6), dtype=np.int64)  # t, i_x, i_y, j_x, j_y, parent
    goal_node = np.zeros(1 << 14, dtype=np.bool_)
    heap = np.empty(1 << 14, dtype=np.int64)
    n = 0
    for r in range(len(v_init)):
        jx, jy = v_init[r, 0], v_init[r, 1]
        first = max(flights_needed(0.0, jx, rel[0], rel[2], table, n_vel, max_steps - t0),
                    flights_needed(0.0, jy, rel[1], rel[3], table, n_vel, max_steps - t0),
                    floor0)
        if t0 + first <= max_steps:
            nodes, goal_node, heap = _queued(nodes, goal_node, heap, n, n, t0, 0, 0, jx, jy,
                                             -1, False,
                                             _entry(t0, first, weight16, max_steps, n))
            n += 1
    return nodes, goal_node, heap, n


@njit(cache=True)
def _lands(t: int, px: float, py: float, rel: Array, survive: int) -> bool:
    """Whether the flight of step t that ends at (px, py) (m from the origin) ends the
    search: it ends in G (``rel``), or step t + 1 reaches ``survive`` (> 0)."""
    if survive > 0:
        return t + 1 >= survive
    return rel[0] <= px <= rel[2] and rel[1] <= py <= rel[3]


@njit(cache=True)
def _children(nodes: AnyArray, goal_node: AnyArray, heap: AnyArray, n: int, size: int,
              seen: Any, frame: tuple[int, int, int, int, int, int], node: int, t: int,
              ix1: int, iy1: int, succ: AnyArray, landed: bool, floor: int, weight16: int,
              max_steps: int) -> tuple[AnyArray, AnyArray, AnyArray, int, int]:
    """Queue the children of ``node``, at lattice position (i_x1, i_y1) at step t + 1 with the
    velocities and heuristics of ``succ`` (at least ``floor``). A child whose step, bucket
    and velocity (``frame``, :func:`_frame`) were queued before (``seen``) is dropped,
    unless it ends the search (``landed``: a terminal node, h = 0)."""
    ix0, iy0, nx, ny, bucket, n_vel = frame
    nv = 2 * n_vel + 1
    cell = (((t + 1) * nx + (ix1 - ix0) // bucket) * ny + (iy1 - iy0) // bucket) * nv
    for r in range(len(succ)):
        kx, ky = succ[r, 0], succ[r, 1]
        key = (cell + kx + n_vel) * nv + ky + n_vel
        if not landed:
            if key in seen:
                continue
            seen[key] = np.int8(1)
        hval = max(succ[r, 2], floor)
        nodes, goal_node, heap = _queued(nodes, goal_node, heap, n, size, t + 1, ix1, iy1, kx,
                                         ky, node, landed,
                                         _entry(t + 1, hval, weight16, max_steps, n))
        n, size = n + 1, size + 1
    return nodes, goal_node, heap, n, size


@njit(cache=True)
def _queued(nodes: AnyArray, goal_node: AnyArray, heap: AnyArray, n: int, size: int, t: int,
            ix: int, iy: int, jx: int, jy: int, parent: int, landed: bool, entry: np.int64
            ) -> tuple[AnyArray, AnyArray, AnyArray]:
    """Node n = (t, i_x, i_y, j_x, j_y, parent), ending the search if ``landed``, with its
    heap ``entry`` pushed (the heap holding ``size`` entries); the arrays grown as needed."""
    nodes = _grown(nodes, n + 1)
    goal_node = _grown(goal_node, n + 1)
    nodes[n] = (t, ix, iy, jx, jy, parent)
    goal_node[n] = landed
    heap = _heap_push(heap, size, entry)
    return nodes, goal_node, heap


@njit(cache=True)
def _path(nodes: AnyArray, last: int) -> AnyArray:
    """Rows (t, i_x, i_y, j_x, j_y) from the start to ``last``."""
    count, node = 0, last
    while node >= 0:
        count += 1
        node = nodes[node, 5]
    out = np.empty((count, 5), dtype=np.int64)
    node = last
    for i in range(count - 1, -1, -1):
        out[i] = nodes[node, :5]
        node = nodes[node, 5]
    return out

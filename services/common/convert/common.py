"""common.proto ↔ core types: geometry (Vec2, Rect, Polygon), forces, the Clock, Error replies.

Every decoder checks what the core would otherwise trust: finite numbers, ranges
and sizes (services/common/limits.py); a bad message raises
:class:`~services.common.rejections.CodecError`. The building blocks of the
other converters of this package (one module per .proto file).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from dualpilot.model.dynamics import Array
from dualpilot.model.geometry import Polytope, Rect
from services.common.clock import Anchor, SimClock, check_speed_factor
from services.common.limits import (
    MAX_ABS_M,
    MAX_CLOCK_SKEW_S,
    MAX_FORCE_N,
    MAX_TEXT,
    MAX_VERTICES,
    MIN_SPEED_FACTOR,
    check_count,
    check_floats,
    finite,
)
from services.common.rejections import Reason, invalid
from services.common.wire import Stamper
from services.msgs import common_pb2


def rect_to_msg(r: Rect, out: common_pb2.Rect) -> common_pb2.Rect:
    out.center_east_m, out.center_north_m = r.center_x, r.center_y
    out.width_m, out.height_m = r.width, r.height
    return out


def rect_from_msg(m: common_pb2.Rect, what: str = "rect") -> Rect:
    cx, cy, w, h = check_floats([m.center_east_m, m.center_north_m, m.width_m, m.height_m],
                                 what, MAX_ABS_M)
    if w <= 0 or h <= 0:
        raise invalid(f"{what} sides must be positive, got {w} x {h}", Reason.OUT_OF_RANGE)
    return Rect(float(cx), float(cy), float(w), float(h))


def points_to_msg(points: Array, out: Any) -> None:
    """Append (k, 2) points to a repeated Vec2 field."""
    for e, n in np.asarray(points, dtype=float).reshape(-1, 2):
        out.add(east_m=float(e), north_m=float(n))


def points_from_msg(vs: Sequence[common_pb2.Vec2], what: str, limit: int) -> Array:
    check_count(len(vs), what, limit)
    flat = finite((c for v in vs for c in (v.east_m, v.north_m)), what, MAX_ABS_M)
    return flat.reshape(-1, 2)


def packed_to_msg(points: Array, out: Any) -> None:
    """Append (k, c) values row-major to a packed repeated double field."""
    out.extend(np.asarray(points, dtype=float).ravel().tolist())


def packed_from_msg(values: Sequence[float], what: str, width: int, limit: int,
                    bound: float) -> Array:
    """A packed repeated double field as (k, width) rows; checks count, finiteness and range."""
    n = len(values)
    if n % width:
        raise invalid(f"{what}: {n} values is not a multiple of {width}", Reason.SIZE)
    check_count(n // width, what, limit)
    return np.array(check_floats(list(values), what, bound), dtype=float).reshape(-1, width)


def polygon_to_msg(poly: Polytope, out: common_pb2.Polygon) -> common_pb2.Polygon:
    packed_to_msg(poly.vertices, out.vertices_m)
    return out


def polygon_from_msg(m: common_pb2.Polygon, what: str = "polygon") -> Polytope:
    pts = packed_from_msg(m.vertices_m, what, 2, MAX_VERTICES, MAX_ABS_M)
    if len(pts) < 3:
        raise invalid(f"{what} needs at least 3 vertices, got {len(pts)}", Reason.SIZE)
    try:
        poly = _ccw_polytope(pts) or Polytope.from_vertices(pts)
    except (ValueError, ArithmeticError) as err:
        raise invalid(f"{what}: {err}") from err
    if not (np.all(np.isfinite(poly.A)) and np.all(np.isfinite(poly.b))):
        raise invalid(f"{what}: degenerate polygon (no finite face normals)")
    return poly


def _ccw_polytope(v: Array) -> Polytope | None:
    """The polytope of vertices that already form a strictly convex CCW polygon, else None.

    The sender's hulls come from :meth:`Polytope.from_vertices`, so their
    vertices are canonical (counter-clockwise from the lowest (x, y)) and
    recomputing the hull would return them unchanged, at ≈ 0.5 ms a hull.
    The checks run in plain Python (faster than numpy for a few vertices);
    A and b use from_vertices' own formula, so the result is identical.
    """
    pts = v.tolist()
    n = len(pts)
    if min(pts) != pts[0]:
        return None
    falling = False
    for i in range(n):
        (x0, y0), (x1, y1), (x2, y2) = pts[i], pts[(i + 1) % n], pts[(i + 2) % n]
        ex, ey, fx, fy = x1 - x0, y1 - y0, x2 - x1, y2 - y1
        if ex * fy - ey * fx <= 1e-9:  # strict left turns...
            return None
        if ex < 0:
            falling = True
        elif ex > 0 and falling:  # ...winding once: x rises, then falls (no star polygons)
            return None
    edges = np.concatenate((v[1:], v[:1])) - v
    normals = np.column_stack([edges[:, 1], -edges[:, 0]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    b = np.einsum("ij,ij->i", normals, v)
    return Polytope(vertices=v, A=normals, b=b)


def force_from_msg(m: common_pb2.Force2, what: str = "force", dim: int = 2) -> Array:
    """A force of ``dim`` entries (N); a planar one (``dim`` 2) with an ``up_n`` is refused."""
    if dim == 3:
        return finite((m.east_n, m.north_n, m.up_n), what, MAX_FORCE_N)
    if m.up_n != 0.0:
        raise invalid(f"{what}: a planar force carries no up_n, got {m.up_n!r}",
                      Reason.OUT_OF_RANGE)
    return finite((m.east_n, m.north_n), what, MAX_FORCE_N)


def clock_to_msg(anchor: Anchor, out: common_pb2.Clock) -> common_pb2.Clock:
    out.sim_time_s = anchor.sim_time_s
    out.speed_factor = anchor.speed_factor
    out.anchor_wall_ns = anchor.wall_ns
    return out


def clock_from_msg(m: common_pb2.Clock, now_ns: int | None = None) -> Anchor:
    """A Clock as an Anchor; a paced clock's anchor must lie within
    :data:`MAX_CLOCK_SKEW_S` of ``now_ns`` (default: this machine's wall clock)."""
    check_floats([m.sim_time_s], "clock sim_time_s", 1e12)
    if m.sim_time_s < 0:
        raise invalid(f"clock sim_time_s must be >= 0, got {m.sim_time_s}", Reason.OUT_OF_RANGE)
    if math.isnan(m.speed_factor):
        raise invalid("clock speed_factor is NaN", Reason.NOT_FINITE)
    try:
        factor = check_speed_factor(m.speed_factor)
    except ValueError as err:
        raise invalid(str(err), Reason.OUT_OF_RANGE) from err
    if factor and not MIN_SPEED_FACTOR <= factor <= 1e9:
        raise invalid(f"clock speed_factor must be 0 (unpaced) or in [{MIN_SPEED_FACTOR:g}, 1e9],"
                      f" got {factor}", Reason.OUT_OF_RANGE)
    if m.anchor_wall_ns < 0:
        raise invalid("clock anchor must be >= 0", Reason.OUT_OF_RANGE)
    now_ns = time.time_ns() if now_ns is None else now_ns
    if factor and abs(m.anchor_wall_ns - now_ns) > MAX_CLOCK_SKEW_S * 1e9:
        raise invalid(f"clock anchor {m.anchor_wall_ns} ns is more than {MAX_CLOCK_SKEW_S:g} s "
                      "from this machine's clock", Reason.OUT_OF_RANGE)
    return Anchor(float(m.sim_time_s), int(m.anchor_wall_ns), factor)


def error_msg(stamper: Stamper, code: common_pb2.ErrorCode, message: str) -> common_pb2.Error:
    """An Error reply's payload: its code and a message cut to the text limit."""
    err = common_pb2.Error(code=code, message=message[:MAX_TEXT])
    stamper.stamp(err.header)
    return err


def sim_clock_to_msg(clock: SimClock, out: common_pb2.Clock) -> common_pb2.Clock:
    """``out`` as the anchor that maps the master clock's current τ_t to the wall clock."""
    a = clock.anchor
    out.speed_factor = a.speed_factor
    out.sim_time_s = clock.now_s
    out.anchor_wall_ns = int(a.wall_at(clock.now_s) * 1e9) if a.speed_factor else a.wall_ns
    return out

"""vehicle.proto ↔ core types: the vehicle's state and the operator's waypoints (System 1).

Decoders check finiteness and ranges (services/common/limits.py) and raise
:class:`~services.common.rejections.CodecError` for a bad message.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualpilot.model.dynamics import Array
from services.common.convert.common import points_from_msg, points_to_msg
from services.common.limits import MAX_ABS_M, MAX_WAYPOINTS, check_state_values, check_text, finite
from services.common.rejections import Reason, invalid
from services.common.wire import Stamper
from services.msgs import vehicle_pb2


def state_to_msg(x: Array, step: int, out: vehicle_pb2.VehicleState,
                 altitude_m: float = 0.0) -> vehicle_pb2.VehicleState:
    """A core state as a VehicleState: a planar one (4 entries) at the fixed ``altitude_m``,
    or a 3-D one (6 entries: its own altitude and climb rate, ``dim`` 3)."""
    x = check_state_values(x)
    out.step = step
    if len(x) == 6:
        (out.east_m, out.north_m, out.altitude_m, out.velocity_east_mps,
         out.velocity_north_mps, out.velocity_up_mps) = (float(v) for v in x)
        out.dim = 3
        return out
    out.east_m, out.north_m, out.velocity_east_mps, out.velocity_north_mps = (float(v) for v in x)
    out.altitude_m = float(altitude_m)
    return out


def state_from_msg(m: vehicle_pb2.VehicleState) -> Array:
    """The core state of a VehicleState: 4 entries (``dim`` 0 or 2), 6 (``dim`` 3); CodecError
    for another dim, a planar state with a climb rate, values out of range."""
    if m.dim == 3:
        x = np.array([m.east_m, m.north_m, m.altitude_m, m.velocity_east_mps,
                      m.velocity_north_mps, m.velocity_up_mps])
        return check_state_values(x)
    if m.dim not in (0, 2):
        raise invalid(f"vehicle state dim must be 2 or 3, got {m.dim}", Reason.OUT_OF_RANGE)
    if m.velocity_up_mps != 0.0:
        raise invalid("a planar vehicle state (dim 2) carries no velocity_up_mps",
                      Reason.OUT_OF_RANGE)
    x = np.array([m.east_m, m.north_m, m.velocity_east_mps, m.velocity_north_mps])
    return check_state_values(x)


@dataclass(frozen=True)
class Waypoints:
    """Operator waypoints of one mission, at a revision (1, 2, …; 0: none sent)."""

    mission_id: str
    revision: int
    points: Array | None  # (k, 2) or None (cleared)


def waypoints_msg(w: Waypoints, stamper: Stamper) -> vehicle_pb2.OperatorWaypoints:
    m = vehicle_pb2.OperatorWaypoints(mission_id=w.mission_id, revision=w.revision)
    stamper.stamp(m.header)
    if w.points is not None:
        points_to_msg(w.points, m.waypoints)
    return m


def waypoints_from_msg(m: vehicle_pb2.OperatorWaypoints) -> Waypoints:
    pts = points_from_msg(m.waypoints, "operator waypoints", MAX_WAYPOINTS)
    return Waypoints(check_text(m.mission_id, "mission_id", 256), int(m.revision),
                     pts if len(pts) else None)


def parse_waypoints(text: str) -> Array | None:
    """``"e1,n1;e2,n2"`` (m) → (k, 2) waypoints; empty text → None. For CLI flags."""
    text = text.strip()
    if not text:
        return None
    try:
        pts = np.array([[float(c) for c in p.split(",")] for p in text.split(";")])
    except ValueError as err:
        raise ValueError(f"waypoints must look like 'e1,n1;e2,n2', got {text!r}") from err
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"waypoints must look like 'e1,n1;e2,n2', got {text!r}")
    return finite(pts.ravel(), "waypoints", MAX_ABS_M).reshape(-1, 2)


def vehicle_state_msg(x: Array, step: int, stamper: Stamper, sim_time_s: float,
                      altitude_m: float = 0.0) -> vehicle_pb2.VehicleState:
    """The vehicle's state at step ``step`` as a stamped VehicleState."""
    m = vehicle_pb2.VehicleState()
    stamper.stamp(m.header, sim_time_s)
    return state_to_msg(x, step, m, altitude_m)

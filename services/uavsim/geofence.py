"""The geofence: inclusion and exclusion polygons and circles (mission type FENCE), as PX4's.

A ground station uploads the fence with the mission protocol
(``mission_type`` = MAV_MISSION_TYPE_FENCE): each polygon as consecutive
NAV_FENCE_POLYGON_VERTEX_INCLUSION/EXCLUSION items whose ``param1`` is the
vertex count, each circle as one NAV_FENCE_CIRCLE_INCLUSION/EXCLUSION item
with the radius (m) in ``param1`` (MAVSDK's geofence plugin sends exactly
this). The vehicle is inside when it lies in at least one inclusion zone (if
there are any) and in no exclusion zone (PX4's
``Geofence::isInsidePolygonOrCircle``); a radius-0 circle, which MAVSDK's
example uploads as a placeholder, contains nothing. What a breach does is
``GF_ACTION`` (services/uavsim/failsafe.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from services.common import mav

m = mav.mavlink

POLYGON_IN = int(m.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION)
POLYGON_OUT = int(m.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION)
CIRCLE_IN = int(m.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION)
CIRCLE_OUT = int(m.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION)
RETURN_POINT = int(m.MAV_CMD_NAV_FENCE_RETURN_POINT)
FENCE_COMMANDS = frozenset({POLYGON_IN, POLYGON_OUT, CIRCLE_IN, CIRCLE_OUT, RETURN_POINT})


@dataclass(frozen=True)
class Zone:
    """One fence zone in the local frame (m east, north)."""

    inclusion: bool
    polygon: np.ndarray | None = None  #: (k, 2) vertices
    center: tuple[float, float] = (0.0, 0.0)
    radius_m: float = 0.0

    def contains(self, east: float, north: float) -> bool:
        if self.polygon is None:
            return math.hypot(east - self.center[0], north - self.center[1]) < self.radius_m
        return point_in_polygon(east, north, self.polygon)


def point_in_polygon(x: float, y: float, poly: np.ndarray) -> bool:
    """Even-odd rule (ray casting) for a simple polygon."""
    inside = False
    n = len(poly)
    for k in range(n):
        (x1, y1), (x2, y2) = poly[k], poly[(k + 1) % n]
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


def zones(items: list[mav.MissionItem], origin: tuple[float, float]) -> list[Zone]:
    """The zones of a fence upload; raises ValueError naming the item that does not fit
    (a polygon cut short or with fewer than 3 vertices, a circle without a finite radius ≥ 0)."""
    out: list[Zone] = []
    k = 0
    while k < len(items):
        it = items[k]
        if it.command in (CIRCLE_IN, CIRCLE_OUT):
            if not (math.isfinite(it.param1) and it.param1 >= 0):
                raise ValueError(f"fence item {it.seq}: circle radius {it.param1}")
            out.append(Zone(it.command == CIRCLE_IN, None, mav.to_local(it.lat, it.lon, origin),
                            float(it.param1)))
            k += 1
        elif it.command in (POLYGON_IN, POLYGON_OUT):
            n = int(it.param1) if math.isfinite(it.param1) else 0
            group = items[k:k + n]
            if n < 3 or len(group) < n or any(g.command != it.command for g in group):
                raise ValueError(f"fence item {it.seq}: polygon of {it.param1} vertices")
            poly = np.array([mav.to_local(g.lat, g.lon, origin) for g in group])
            out.append(Zone(it.command == POLYGON_IN, poly))
            k += n
        elif it.command == RETURN_POINT:
            k += 1
        else:
            raise ValueError(f"fence item {it.seq}: command {it.command} is not a fence item")
    return out


@dataclass
class Geofence:
    """The stored fence: inside / outside (module docstring)."""

    zones: tuple[Zone, ...] = ()

    def inside(self, east: float, north: float) -> bool:
        if not self.zones:
            return True
        inclusions = [z for z in self.zones if z.inclusion]
        if inclusions and not any(z.contains(east, north) for z in inclusions):
            return False
        return not any(z.contains(east, north) for z in self.zones if not z.inclusion)

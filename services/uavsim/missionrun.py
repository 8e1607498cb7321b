"""Flying an uploaded mission item by item (the MISSION state, on the vehicle's own clock).

The items a mission may hold (:data:`FLOWN`, :data:`SKIPPED`), and what each
does when it is the current one:

====================  ====================================================================
NAV_WAYPOINT          fly to it at the cruise speed; reached within ``param2`` m (else
                      MIS_ACC_RAD) and 1 m of its altitude; then wait ``param1`` s
NAV_TAKEOFF           climb to its altitude where the vehicle is
NAV_LAND              fly to it (here if its position is 0, 0) and land
NAV_RETURN_TO_LAUNCH  return (the RETURN state: climb, fly home, land)
NAV_LOITER_UNLIM      fly to it and stay (the mission never ends)
NAV_LOITER_TIME       fly to it, stay ``param1`` s
NAV_DELAY             stay ``param1`` s
DO_CHANGE_SPEED       ``param2`` m/s becomes the cruise speed
camera, gimbal items  skipped: the vehicle carries no payload
====================  ====================================================================

Altitudes: GLOBAL_RELATIVE_ALT frames are above home, GLOBAL frames above
mean sea level (less home's). ArduPilot's home slot (item 0 in a GLOBAL frame,
MAVProxy's ``wp`` files) is not flown. A mission started on the ground without a
take-off item first climbs to its first altitude (at least MIS_TAKEOFF_ALT),
as PX4 does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from services.common import mav

m = mav.mavlink

WAYPOINT, LOITER_UNLIM, LOITER_TIME = 16, 17, 19
RTL, LAND, TAKEOFF, DELAY, CHANGE_SPEED = 20, 21, 22, 93, 178
FLOWN = frozenset({WAYPOINT, LOITER_UNLIM, LOITER_TIME, RTL, LAND, TAKEOFF, DELAY, CHANGE_SPEED})
SKIPPED = frozenset({int(m.MAV_CMD_DO_MOUNT_CONTROL), int(m.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW),
                     int(m.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE), int(m.MAV_CMD_IMAGE_START_CAPTURE),
                     int(m.MAV_CMD_IMAGE_STOP_CAPTURE), int(m.MAV_CMD_VIDEO_START_CAPTURE),
                     int(m.MAV_CMD_VIDEO_STOP_CAPTURE), int(m.MAV_CMD_DO_SET_CAM_TRIGG_DIST)})
POSITIONAL = frozenset({WAYPOINT, LOITER_UNLIM, LOITER_TIME, LAND, TAKEOFF})
RELATIVE_FRAMES = frozenset({int(m.MAV_FRAME_GLOBAL_RELATIVE_ALT),
                             int(m.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)})
ALT_TOLERANCE_M = 1.0


def flown_position(item: mav.MissionItem) -> bool:
    """An item that flies to a position (the home slot is not flown)."""
    return item.command in POSITIONAL and not item.is_home()


@dataclass(frozen=True)
class Goal:
    """Where the current item wants the vehicle: east, north (m), altitude above home (m)."""

    east: float
    north: float
    alt: float


@dataclass
class Frame:
    """How mission coordinates map to the local frame."""

    origin: tuple[float, float]  #: deg lat, lon of the local frame's origin
    home_amsl_m: float

    def goal(self, item: mav.MissionItem, here: Goal) -> Goal:
        """The item's position (``here``'s where it has none) and altitude above home."""
        if item.x == 0 and item.y == 0:
            east, north = here.east, here.north
        else:
            east, north = mav.to_local(item.lat, item.lon, self.origin)
        alt = item.z if item.frame in RELATIVE_FRAMES else item.z - self.home_amsl_m
        return Goal(east, north, alt if math.isfinite(alt) else here.alt)


@dataclass
class Step:
    """What the mission asks of the vehicle this step."""

    goal: Goal
    landing: bool = False  #: descend where the goal is
    reached: list[int] | None = None  #: items reached now (MISSION_ITEM_REACHED)
    speed: float | None = None  #: a new cruise speed (DO_CHANGE_SPEED)
    rtl: bool = False  #: the mission says return
    done: bool = False  #: past the last item


class MissionRun:
    """The current item and its progress; :meth:`step` once per ΔT of flight."""

    def __init__(self, items: list[mav.MissionItem], frame: Frame, acc_rad_m: float,
                 takeoff_alt_m: float):
        self.items = items
        self.frame = frame
        self.acc_rad_m = acc_rad_m
        self.takeoff_alt_m = takeoff_alt_m
        self.index = 0
        self.wait_s = 0.0  #: simulated s still to stay at the current item
        self.arrived = False
        self.climb_first: float | None = None  #: a take-off the mission did not have

    def start(self, seq: int, here: Goal, landed: bool) -> None:
        self.index = next((k for k, it in enumerate(self.items) if it.seq >= seq), 0)
        self.arrived, self.wait_s = False, 0.0
        first = next((it for it in self.items[self.index:] if flown_position(it)), None)
        if landed and first is not None and first.command != TAKEOFF:
            alt = self.frame.goal(first, here).alt
            self.climb_first = max(self.takeoff_alt_m, alt)

    @property
    def current_seq(self) -> int:
        return self.items[self.index].seq if self.index < len(self.items) else len(self.items)

    def step(self, here: Goal, dt_s: float) -> Step:
        """The goal of this step (``here``: where the vehicle is)."""
        if self.climb_first is not None:
            if abs(here.alt - self.climb_first) > ALT_TOLERANCE_M:
                return Step(Goal(here.east, here.north, self.climb_first))
            self.climb_first = None
        reached: list[int] = []
        speed = None
        while self.index < len(self.items):
            item = self.items[self.index]
            if item.command == CHANGE_SPEED:
                speed = item.param2 if math.isfinite(item.param2) and item.param2 > 0 else speed
            elif item.command not in SKIPPED and not item.is_home():
                break
            if not item.is_home():
                reached.append(item.seq)
            self.index += 1
        if self.index >= len(self.items):
            return Step(here, reached=reached, speed=speed, done=True)
        out = self._item(self.items[self.index], here, dt_s)
        out.reached = reached + (out.reached or [])
        out.speed = speed if out.speed is None else out.speed
        return out

    def _item(self, item: mav.MissionItem, here: Goal, dt_s: float) -> Step:
        if item.command == RTL:
            return Step(here, rtl=True, reached=[item.seq])
        if item.command == DELAY:
            return self._wait(item, here, dt_s, item.param1)
        goal = self.frame.goal(item, here)
        if item.command == TAKEOFF:
            goal = Goal(here.east, here.north, goal.alt)
        if item.command == LAND:
            near = math.hypot(goal.east - here.east, goal.north - here.north) < 1.0
            return Step(Goal(goal.east, goal.north, here.alt if not near else 0.0),
                        landing=near)
        radius = item.param2 if item.command == WAYPOINT and item.param2 > 0 else self.acc_rad_m
        at = (math.hypot(goal.east - here.east, goal.north - here.north) <= radius
              and abs(goal.alt - here.alt) <= ALT_TOLERANCE_M)
        if not (at or self.arrived):
            return Step(goal)
        if item.command == LOITER_UNLIM:
            first = not self.arrived
            self.arrived = True
            return Step(goal, reached=[item.seq] if first else [])
        hold = item.param1 if item.command in (WAYPOINT, LOITER_TIME) else 0.0
        return self._wait(item, goal, dt_s, hold)

    def _wait(self, item: mav.MissionItem, goal: Goal, dt_s: float, hold_s: float) -> Step:
        """Stay at ``goal`` for ``hold_s`` (from arrival: reported reached then), then move on."""
        reached: list[int] = []
        if not self.arrived:
            self.arrived = True
            self.wait_s = hold_s if math.isfinite(hold_s) and hold_s > 0 else 0.0
            reached = [item.seq]
        else:
            self.wait_s -= dt_s
        if self.wait_s <= 0:
            self.arrived, self.wait_s = False, 0.0
            self.index += 1
        return Step(goal, reached=reached)

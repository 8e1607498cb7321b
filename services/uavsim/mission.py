"""The vehicle's side of the MAVLink mission protocol (upload, download, clear, current item).

Upload (https://mavlink.io/en/services/mission.html): MISSION_COUNT, then a
MISSION_REQUEST_INT per item (re-requested after ``item_timeout_s``, at most
``retries`` times). Two mission types are stored: the mission (MISSION) and
the geofence (FENCE, services/uavsim/geofence.py); rally points are
UNSUPPORTED. Which items are accepted depends on what the vehicle flies
(the bounds, checked item by item):

* :class:`PlanningBounds` (lockstep: a planning mission, the uploaded waypoints
  are System 1's operator waypoints): NAV_WAYPOINT items in a global frame
  inside the area [0, area]² (m east/north of the geodetic origin);
* :class:`FreeBounds` (the vehicle on its own clock flies missions itself):
  the items services/uavsim/missionrun.py flies or skips, fence items, wherever
  the user puts them within ``range_m`` of the origin.

A bad item ends the transfer with its MAV_MISSION_* result, the previous
mission stays, and ``on_reject`` counts it. A completed upload replaces the
stored items atomically; a mission's bumps :attr:`MissionServer.version`
(``MIS_ID``). Download: MISSION_REQUEST_LIST → MISSION_COUNT, then each item
as asked.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from services.common import mav, rejections
from services.common.log import fields
from services.common.mavlink_codec import SETPOINT_AREA_MARGIN

from . import missionrun
from .geofence import FENCE_COMMANDS
from .outbox import Outbox

log = logging.getLogger(__name__)
m = mav.mavlink

MAX_ITEMS = 500
MISSION = int(m.MAV_MISSION_TYPE_MISSION)
FENCE = int(m.MAV_MISSION_TYPE_FENCE)
ALL = int(m.MAV_MISSION_TYPE_ALL)
STORED = (MISSION, FENCE)
_PARAM_RESULT = (m.MAV_MISSION_INVALID_PARAM1, m.MAV_MISSION_INVALID_PARAM2,
                 m.MAV_MISSION_INVALID_PARAM3, m.MAV_MISSION_INVALID_PARAM4)
#: the counter reason of each refusal (MAV_MISSION_* result)
_REASON = {
    int(m.MAV_MISSION_UNSUPPORTED): rejections.Reason.INVALID,
    int(m.MAV_MISSION_UNSUPPORTED_FRAME): rejections.Reason.INVALID,
    int(m.MAV_MISSION_INVALID_PARAM1): rejections.Reason.NOT_FINITE,
    int(m.MAV_MISSION_INVALID_PARAM2): rejections.Reason.NOT_FINITE,
    int(m.MAV_MISSION_INVALID_PARAM3): rejections.Reason.NOT_FINITE,
    int(m.MAV_MISSION_INVALID_PARAM4): rejections.Reason.NOT_FINITE,
    int(m.MAV_MISSION_INVALID_PARAM7): rejections.Reason.NOT_FINITE,
    int(m.MAV_MISSION_INVALID_PARAM5_X): rejections.Reason.OUT_OF_RANGE,
    int(m.MAV_MISSION_INVALID_PARAM6_Y): rejections.Reason.OUT_OF_RANGE,
}


@dataclass
class Upload:
    """An upload in progress from one peer on one link."""

    link: str
    peer: tuple[int, int]
    count: int
    mission_type: int = MISSION
    items: list[mav.MissionItem] = field(default_factory=list)
    requested_at: float = 0.0
    retries: int = 0


def _finite_fields(item: mav.MissionItem, positional: bool) -> int:
    """MAV_MISSION_ACCEPTED, or the result for ±inf in a parameter or a bad coordinate."""
    for k, p in enumerate((item.param1, item.param2, item.param3, item.param4)):
        if math.isinf(p):
            return int(_PARAM_RESULT[k])
    if positional and not math.isfinite(item.z):
        return int(m.MAV_MISSION_INVALID_PARAM7)
    if abs(item.x) > 900_000_000:
        return int(m.MAV_MISSION_INVALID_PARAM5_X)
    if abs(item.y) > 1_800_000_000:
        return int(m.MAV_MISSION_INVALID_PARAM6_Y)
    return int(m.MAV_MISSION_ACCEPTED)


@dataclass(frozen=True)
class PlanningBounds:
    """Lockstep: NAV_WAYPOINT items inside the planning area (System 1's operator waypoints)."""

    origin: tuple[float, float]  #: deg lat, lon of the local frame's origin
    area_size_m: float
    types: tuple[int, ...] = (MISSION,)  #: the mission types it stores

    def within(self, east: float, north: float) -> bool:
        """In the area grown by the setpoint margin (services/common/mavlink_codec.py)."""
        margin = SETPOINT_AREA_MARGIN * self.area_size_m
        return all(-margin <= v <= self.area_size_m + margin for v in (east, north))

    def check(self, item: mav.MissionItem, mission_type: int) -> int:
        """MAV_MISSION_ACCEPTED or the MAV_MISSION_* result that rejects ``item``."""
        if mission_type != MISSION:
            return int(m.MAV_MISSION_UNSUPPORTED)
        if item.command != m.MAV_CMD_NAV_WAYPOINT:
            return int(m.MAV_MISSION_UNSUPPORTED)
        if item.frame not in mav.GLOBAL_FRAMES:
            return int(m.MAV_MISSION_UNSUPPORTED_FRAME)
        result = _finite_fields(item, True)
        if result != m.MAV_MISSION_ACCEPTED or item.is_home():
            return result
        east, north = mav.to_local(item.lat, item.lon, self.origin)
        if not 0.0 <= north <= self.area_size_m:
            return int(m.MAV_MISSION_INVALID_PARAM5_X)
        if not 0.0 <= east <= self.area_size_m:
            return int(m.MAV_MISSION_INVALID_PARAM6_Y)
        return int(m.MAV_MISSION_ACCEPTED)


@dataclass(frozen=True)
class FreeBounds:
    """On its own clock: the items the vehicle flies (missionrun.py) and fence items, within
    ``range_m`` of the origin."""

    origin: tuple[float, float]
    range_m: float
    types: tuple[int, ...] = STORED

    def within(self, east: float, north: float) -> bool:
        return abs(east) <= self.range_m and abs(north) <= self.range_m

    def check(self, item: mav.MissionItem, mission_type: int) -> int:
        known = (missionrun.FLOWN | missionrun.SKIPPED if mission_type == MISSION
                 else FENCE_COMMANDS if mission_type == FENCE else frozenset())
        if item.command not in known:
            return int(m.MAV_MISSION_UNSUPPORTED)
        positional = mission_type == FENCE or item.command in missionrun.POSITIONAL
        if positional and item.frame not in mav.GLOBAL_FRAMES:
            return int(m.MAV_MISSION_UNSUPPORTED_FRAME)
        result = _finite_fields(item, positional and mission_type == MISSION)
        if result != m.MAV_MISSION_ACCEPTED or not positional or item.is_home():
            return result
        if item.x == 0 and item.y == 0:
            return result  # "here" (MAVSDK's placeholder fence circle, a land item)
        east, north = mav.to_local(item.lat, item.lon, self.origin)
        if abs(north) > self.range_m:
            return int(m.MAV_MISSION_INVALID_PARAM5_X)
        if abs(east) > self.range_m:
            return int(m.MAV_MISSION_INVALID_PARAM6_Y)
        return result


Bounds = PlanningBounds | FreeBounds


class MissionServer:
    """The stored mission and fence and the transfers in progress, per link.

    Messages go out through ``outbox`` (services/uavsim/outbox.py);
    ``on_change(mission_type)`` is called after an upload or clear changed the
    stored items of that type; ``bounds`` checks each item (module docstring).
    """

    def __init__(self, outbox: Outbox, bounds: Bounds,
                 on_change: Callable[[int], None] = lambda _t: None,
                 max_items: int = MAX_ITEMS, item_timeout_s: float = 0.5, retries: int = 5,
                 on_reject: Callable[[str, rejections.CodecError], None] = lambda _l, _e: None,
                 empty_upload_clears: bool = False):
        self.outbox = outbox
        self.bounds = bounds
        self.empty_upload_clears = empty_upload_clears
        self.on_reject = on_reject
        self.on_change = on_change
        self.max_items = max_items
        self.item_timeout_s = item_timeout_s
        self.retries = retries
        self.stored: dict[int, list[mav.MissionItem]] = {t: [] for t in STORED}
        self.version = 0
        self.current = 0
        self.uploads: dict[str, Upload] = {}
        self._waypoints: list[tuple[int, float, float]] = []

    @property
    def items(self) -> list[mav.MissionItem]:
        """The mission's items (MISSION type)."""
        return self.stored[MISSION]

    # -- messages ------------------------------------------------------------------------------
    def handle(self, link: str, msg: Any, now: float) -> bool | None:
        """Handle a mission-protocol message from ``link``: None if ``msg`` is not one, False if
        it was refused as bad input (and reported to ``on_reject``), else True."""
        kind = msg.get_type()
        handler = {
            "MISSION_COUNT": self._on_count, "MISSION_ITEM_INT": self._on_item,
            "MISSION_ITEM": self._on_item, "MISSION_REQUEST_LIST": self._on_request_list,
            "MISSION_REQUEST_INT": self._on_request, "MISSION_REQUEST": self._on_request,
            "MISSION_CLEAR_ALL": self._on_clear, "MISSION_SET_CURRENT": self._on_set_current,
            "MISSION_ACK": self._on_ack,
        }.get(kind)
        if handler is None:
            return None
        return handler(link, msg, now) is not False

    @staticmethod
    def _peer(msg: Any) -> tuple[int, int]:
        return int(msg.get_srcSystem()), int(msg.get_srcComponent())

    @staticmethod
    def _type(msg: Any) -> int:
        return int(getattr(msg, "mission_type", MISSION))

    def _ack(self, link: str, peer: tuple[int, int], result: int, mission_type: int) -> None:
        self.outbox.send(link, "mission_ack", peer[0], peer[1], result, mission_type)

    def _request(self, up: Upload, now: float) -> None:
        up.requested_at = now
        self.outbox.send(up.link, "mission_request_int", up.peer[0], up.peer[1], len(up.items),
                         up.mission_type)

    def _on_count(self, link: str, msg: Any, now: float) -> bool:
        peer, mission_type = self._peer(msg), self._type(msg)
        if mission_type not in self.bounds.types:
            self._ack(link, peer, m.MAV_MISSION_UNSUPPORTED, mission_type)
            return True
        self.uploads.pop(link, None)  # a new count restarts the transfer
        if msg.count > self.max_items:
            self.on_reject(link, rejections.invalid(
                f"MISSION_COUNT {msg.count} (at most {self.max_items} items)",
                rejections.Reason.SIZE))
            self._ack(link, peer, m.MAV_MISSION_NO_SPACE, mission_type)
            return False
        if msg.count == 0:
            self._commit(mission_type, [])
            self._ack(link, peer, m.MAV_MISSION_ACCEPTED, mission_type)
            return True
        up = Upload(link, peer, int(msg.count), mission_type)
        self.uploads[link] = up
        log.info("mission upload", extra=fields(link=link, count=up.count, sysid=peer[0],
                                                mission_type=mission_type))
        self._request(up, now)
        return True

    def _result(self, msg: Any, mission_type: int) -> tuple[int, mav.MissionItem | None]:
        """The MAV_MISSION_* result for an item message, and the item if it converts."""
        try:
            item = mav.MissionItem.from_msg(msg)
        except ValueError as err:
            return (int(m.MAV_MISSION_INVALID_PARAM5_X) if str(err) == "x"
                    else int(m.MAV_MISSION_INVALID_PARAM6_Y)), None
        return self.bounds.check(item, mission_type), item

    def _refused(self, link: str, msg: Any, result: int) -> None:
        name = m.enums["MAV_MISSION_RESULT"][result].name
        reason = _REASON.get(result, rejections.Reason.INVALID)
        if not all(math.isfinite(float(v)) for v in (msg.x, msg.y)):
            reason = rejections.Reason.NOT_FINITE  # MISSION_ITEM's float lat/lon
        self.on_reject(link, rejections.invalid(
            f"{msg.get_type()} seq {int(msg.seq)}: {name} (x={msg.x!r}, y={msg.y!r}, "
            f"z={msg.z!r})", reason))

    def _on_item(self, link: str, msg: Any, now: float) -> bool:
        up = self.uploads.get(link)
        if up is None or self._type(msg) != up.mission_type:
            result, _ = self._result(msg, self._type(msg))  # not uploading (a late duplicate):
            if result != m.MAV_MISSION_ACCEPTED:  # ignored, as PX4 does; a bad one is counted
                self._refused(link, msg, result)
                return False
            return True
        if (self.empty_upload_clears and up.mission_type == MISSION and up.count == 1
                and msg.seq == 0 and msg.get_type() == "MISSION_ITEM_INT" and msg.x == 0
                and msg.y == 0):
            # ArduPilot's way to clear (MAVSDK sends it): a mission of only an empty item 0
            del self.uploads[link]
            self._commit(MISSION, [])
            self._ack(link, up.peer, m.MAV_MISSION_ACCEPTED, MISSION)
            return True
        if msg.seq != len(up.items):
            if msg.seq > len(up.items):
                self._request(up, now)  # out of order: ask again for the one we need
            return True
        result, item = self._result(msg, up.mission_type)
        if result != m.MAV_MISSION_ACCEPTED or item is None:
            return self._end_upload(up, msg, result)
        up.items.append(item)
        up.retries = 0
        if len(up.items) < up.count:
            self._request(up, now)
            return True
        return self._end_upload(up, msg, int(m.MAV_MISSION_ACCEPTED))

    def _end_upload(self, up: Upload, msg: Any, result: int) -> bool:
        """The last item is in (ACCEPTED: commit) or one was refused (the stored ones stay)."""
        del self.uploads[up.link]
        if result == m.MAV_MISSION_ACCEPTED:
            try:
                self._commit(up.mission_type, up.items)
            except ValueError as err:  # a fence that is no fence (geofence.zones)
                log.warning("upload refused", extra=fields(error=str(err)))
                result = int(m.MAV_MISSION_INVALID_PARAM1)
                self.on_reject(up.link, rejections.invalid(str(err)))
        else:
            self._refused(up.link, msg, result)
        self._ack(up.link, up.peer, result, up.mission_type)
        return result == m.MAV_MISSION_ACCEPTED

    def _on_request_list(self, link: str, msg: Any, now: float) -> None:
        mission_type = self._type(msg)
        count = len(self.stored.get(mission_type, ()))
        peer = self._peer(msg)
        self.outbox.send(link, "mission_count", peer[0], peer[1], count, mission_type)

    def _on_request(self, link: str, msg: Any, now: float) -> None:
        peer, mission_type = self._peer(msg), self._type(msg)
        items = self.stored.get(mission_type, [])
        if not 0 <= msg.seq < len(items):
            self._ack(link, peer, m.MAV_MISSION_INVALID_SEQUENCE, mission_type)
            return
        item = items[msg.seq]
        kind = "mission_item_int" if msg.get_type() == "MISSION_REQUEST_INT" else "mission_item"
        self.outbox.send(link, kind, *item.fields(peer, float_latlon=kind == "mission_item"),
                         mission_type)

    def _on_clear(self, link: str, msg: Any, now: float) -> None:
        mission_type = self._type(msg)
        for t in STORED if mission_type == ALL else (mission_type,):
            if t in STORED:
                self.uploads.pop(link, None)
                self._commit(t, [])
        self._ack(link, self._peer(msg), m.MAV_MISSION_ACCEPTED, mission_type)

    def _on_set_current(self, link: str, msg: Any, now: float) -> None:
        if 0 <= msg.seq < len(self.items):
            self.current = int(msg.seq)
        self.send_current(link)

    def _on_ack(self, link: str, msg: Any, now: float) -> None:
        """The end of a download (nothing to do), or a ground station cancelling an upload."""
        up = self.uploads.get(link)
        if up is not None and msg.type != m.MAV_MISSION_ACCEPTED:
            del self.uploads[link]
            log.info("mission upload cancelled by the peer", extra=fields(link=link))

    # -- time ----------------------------------------------------------------------------------
    def poll(self, now: float) -> None:
        """Re-request an overdue item; cancel the transfer after ``retries`` re-requests."""
        for link, up in list(self.uploads.items()):
            if now - up.requested_at < self.item_timeout_s:
                continue
            if up.retries >= self.retries:
                del self.uploads[link]
                log.warning("mission upload timed out", extra=fields(link=link,
                                                                     seq=len(up.items)))
                self._ack(link, up.peer, m.MAV_MISSION_OPERATION_CANCELLED, up.mission_type)
                continue
            up.retries += 1
            self._request(up, now)

    # -- the stored items ----------------------------------------------------------------------
    def _commit(self, mission_type: int, items: list[mav.MissionItem]) -> None:
        """Store ``items`` (raises ValueError, storing nothing, if ``on_change`` refuses them)."""
        before = self.stored[mission_type]
        self.stored[mission_type] = list(items)
        try:
            if mission_type == MISSION:
                self.version += 1
                self.current = next((it.seq for it in items if it.is_waypoint()), 0)
                self._waypoints = [(it.seq, *mav.to_local(it.lat, it.lon, self.bounds.origin))
                                   for it in items if it.is_waypoint()]
            self.on_change(mission_type)
        except ValueError:
            self.stored[mission_type] = before
            raise
        log.info("mission stored", extra=fields(items=len(items), version=self.version,
                                                mission_type=mission_type))

    def send_current(self, link: str | None = None) -> None:
        """MISSION_CURRENT (current item, total items) on ``link`` or every link."""
        state = (m.MISSION_STATE_NO_MISSION if not self.items else
                 m.MISSION_STATE_ACTIVE if self.current < len(self.items)
                 else m.MISSION_STATE_COMPLETE)
        self.outbox.send(link, "mission_current", self.current, len(self.items), state)

    def progress(self, east_m: float, north_m: float, radius_m: float) -> list[int]:
        """Waypoints reached at this position (within ``radius_m`` of the current one or of a
        later one); advances the current item and returns the seqs passed."""
        hits = [k for k, (seq, e, n) in enumerate(self._waypoints)
                if seq >= self.current and math.hypot(east_m - e, north_m - n) <= radius_m]
        if not hits:
            return []
        last = hits[-1]
        reached = [s for s, _, _ in self._waypoints[: last + 1] if s >= self.current]
        self.current = (self._waypoints[last + 1][0] if last + 1 < len(self._waypoints)
                        else len(self.items))
        return reached

"""The vehicle's side of the MAVLink mission protocol (upload, download, clear, current item).

Upload (https://mavlink.io/en/services/mission.html): MISSION_COUNT, then a
MISSION_REQUEST_INT per item (re-requested after ``item_timeout_s``, at most
``retries`` times). Only NAV_WAYPOINT items in a global frame inside the area
[0, area]² (m east/north of the geodetic origin) are accepted; a bad item ends
the transfer with its MAV_MISSION_* result, the previous mission stays, and
``on_reject`` counts it. A completed upload replaces the mission atomically
and bumps :attr:`MissionServer.version` (``MIS_ID``). Download:
MISSION_REQUEST_LIST → MISSION_COUNT, then each item as asked.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from services.common import mav, rejections
from services.common.log import fields

log = logging.getLogger(__name__)
m = mav.mavlink

MAX_ITEMS = 500
MISSION = m.MAV_MISSION_TYPE_MISSION
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
    items: list[mav.MissionItem] = field(default_factory=list)
    requested_at: float = 0.0
    retries: int = 0


class MissionServer:
    """The stored mission and the transfers in progress, per link.

    ``senders`` maps a link name to its :class:`services.common.mav.Sender`;
    ``on_change`` is called after an upload or clear changed the mission.
    """

    def __init__(self, senders: dict[str, mav.Sender], origin: tuple[float, float],
                 area_size_m: float, on_change: Callable[[], None] = lambda: None,
                 max_items: int = MAX_ITEMS, item_timeout_s: float = 0.5, retries: int = 5,
                 on_reject: Callable[[str, rejections.CodecError], None] = lambda _l, _e: None,
                 empty_upload_clears: bool = False):
        self.senders = senders
        self.empty_upload_clears = empty_upload_clears
        self.on_reject = on_reject
        self.origin = origin
        self.area_size_m = area_size_m
        self.on_change = on_change
        self.max_items = max_items
        self.item_timeout_s = item_timeout_s
        self.retries = retries
        self.items: list[mav.MissionItem] = []
        self.version = 0
        self.current = 0
        self.uploads: dict[str, Upload] = {}
        self._waypoints: list[tuple[int, float, float]] = []

    # -- checks ---------------------------------------------------------------------------------
    def check(self, item: mav.MissionItem) -> int:
        """MAV_MISSION_ACCEPTED or the MAV_MISSION_* result that rejects ``item``."""
        if item.command != m.MAV_CMD_NAV_WAYPOINT:
            return int(m.MAV_MISSION_UNSUPPORTED)
        if item.frame not in mav.GLOBAL_FRAMES:
            return int(m.MAV_MISSION_UNSUPPORTED_FRAME)
        for k, p in enumerate((item.param1, item.param2, item.param3, item.param4)):
            if math.isinf(p):
                return int(_PARAM_RESULT[k])
        if not math.isfinite(item.z):
            return int(m.MAV_MISSION_INVALID_PARAM7)
        if abs(item.x) > 900_000_000:
            return int(m.MAV_MISSION_INVALID_PARAM5_X)
        if abs(item.y) > 1_800_000_000:
            return int(m.MAV_MISSION_INVALID_PARAM6_Y)
        if item.is_home():
            return int(m.MAV_MISSION_ACCEPTED)
        east, north = mav.to_local(item.lat, item.lon, self.origin)
        if not 0.0 <= north <= self.area_size_m:
            return int(m.MAV_MISSION_INVALID_PARAM5_X)
        if not 0.0 <= east <= self.area_size_m:
            return int(m.MAV_MISSION_INVALID_PARAM6_Y)
        return int(m.MAV_MISSION_ACCEPTED)

    # -- messages ---------------------------------------------------------------------------------
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

    def _peer(self, msg: Any) -> tuple[int, int]:
        return int(msg.get_srcSystem()), int(msg.get_srcComponent())

    def _ack(self, link: str, peer: tuple[int, int], result: int, mission_type: int) -> None:
        self.senders[link]("mission_ack", peer[0], peer[1], result, mission_type)

    def _request(self, up: Upload, now: float) -> None:
        up.requested_at = now
        self.senders[up.link]("mission_request_int", up.peer[0], up.peer[1], len(up.items),
                              MISSION)

    def _on_count(self, link: str, msg: Any, now: float) -> bool:
        peer = self._peer(msg)
        mission_type = int(getattr(msg, "mission_type", MISSION))
        if mission_type != MISSION:
            self._ack(link, peer, m.MAV_MISSION_UNSUPPORTED, mission_type)
            return True
        self.uploads.pop(link, None)  # a new count restarts the transfer
        if msg.count > self.max_items:
            self.on_reject(link, rejections.invalid(
                f"MISSION_COUNT {msg.count} (at most {self.max_items} items)",
                rejections.Reason.SIZE))
            self._ack(link, peer, m.MAV_MISSION_NO_SPACE, MISSION)
            return False
        if msg.count == 0:
            self._commit([])
            self._ack(link, peer, m.MAV_MISSION_ACCEPTED, MISSION)
            return True
        up = Upload(link, peer, int(msg.count))
        self.uploads[link] = up
        log.info("mission upload", extra=fields(link=link, count=up.count, sysid=peer[0]))
        self._request(up, now)
        return True

    def _result(self, msg: Any) -> tuple[int, mav.MissionItem | None]:
        """The MAV_MISSION_* result for an item message, and the item if it converts."""
        try:
            item = mav.MissionItem.from_msg(msg)
        except ValueError as err:
            return (int(m.MAV_MISSION_INVALID_PARAM5_X) if str(err) == "x"
                    else int(m.MAV_MISSION_INVALID_PARAM6_Y)), None
        return self.check(item), item

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
        if up is None or int(getattr(msg, "mission_type", MISSION)) != MISSION:
            result, _ = self._result(msg)  # not uploading (a late duplicate): ignored, as PX4
            if result != m.MAV_MISSION_ACCEPTED:  # does; a bad one is still counted
                self._refused(link, msg, result)
                return False
            return True
        if (self.empty_upload_clears and up.count == 1 and msg.seq == 0
                and msg.get_type() == "MISSION_ITEM_INT" and msg.x == 0 and msg.y == 0):
            # ArduPilot's way to clear (MAVSDK sends it): a mission of only an empty item 0
            del self.uploads[link]
            self._commit([])
            self._ack(link, up.peer, m.MAV_MISSION_ACCEPTED, MISSION)
            return True
        if msg.seq != len(up.items):
            if msg.seq > len(up.items):
                self._request(up, now)  # out of order: ask again for the one we need
            return True
        result, item = self._result(msg)
        if result != m.MAV_MISSION_ACCEPTED or item is None:
            del self.uploads[link]
            self._refused(link, msg, result)
            self._ack(link, up.peer, result, MISSION)
            return False
        up.items.append(item)
        up.retries = 0
        if len(up.items) < up.count:
            self._request(up, now)
            return True
        del self.uploads[link]
        self._commit(up.items)
        self._ack(link, up.peer, m.MAV_MISSION_ACCEPTED, MISSION)
        return True

    def _on_request_list(self, link: str, msg: Any, now: float) -> None:
        mission_type = int(getattr(msg, "mission_type", MISSION))
        count = len(self.items) if mission_type == MISSION else 0
        peer = self._peer(msg)
        self.senders[link]("mission_count", peer[0], peer[1], count, mission_type)

    def _on_request(self, link: str, msg: Any, now: float) -> None:
        peer = self._peer(msg)
        mission_type = int(getattr(msg, "mission_type", MISSION))
        if mission_type != MISSION or not 0 <= msg.seq < len(self.items):
            self._ack(link, peer, m.MAV_MISSION_INVALID_SEQUENCE, mission_type)
            return
        item = self.items[msg.seq]
        if msg.get_type() == "MISSION_REQUEST_INT":
            item.send_int(self.senders[link], peer)
        else:
            item.send_float(self.senders[link], peer)

    def _on_clear(self, link: str, msg: Any, now: float) -> None:
        mission_type = int(getattr(msg, "mission_type", MISSION))
        if mission_type in (MISSION, m.MAV_MISSION_TYPE_ALL):
            self.uploads.pop(link, None)
            self._commit([])
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

    # -- time -----------------------------------------------------------------------------------
    def poll(self, now: float) -> None:
        """Re-request an overdue item; cancel the transfer after ``retries`` re-requests."""
        for link, up in list(self.uploads.items()):
            if now - up.requested_at < self.item_timeout_s:
                continue
            if up.retries >= self.retries:
                del self.uploads[link]
                log.warning("mission upload timed out", extra=fields(link=link,
                                                                     seq=len(up.items)))
                self._ack(link, up.peer, m.MAV_MISSION_OPERATION_CANCELLED, MISSION)
                continue
            up.retries += 1
            self._request(up, now)

    # -- the stored mission ---------------------------------------------------------------------
    def _commit(self, items: list[mav.MissionItem]) -> None:
        self.items = list(items)
        self.version += 1
        self.current = next((it.seq for it in self.items if it.is_waypoint()), 0)
        self._waypoints = [(it.seq, *mav.to_local(it.lat, it.lon, self.origin))
                           for it in self.items if it.is_waypoint()]
        log.info("mission stored", extra=fields(items=len(self.items), version=self.version,
                                                waypoints=len(self._waypoints)))
        self.on_change()

    def send_current(self, link: str | None = None) -> None:
        """MISSION_CURRENT (current item, total items) on ``link`` or every link."""
        state = (m.MISSION_STATE_NO_MISSION if not self.items else
                 m.MISSION_STATE_ACTIVE if self.current < len(self.items)
                 else m.MISSION_STATE_COMPLETE)
        for k, name in enumerate([link] if link else list(self.senders)):
            send = self.senders[name]  # the tlog gets the frame once
            send.message(send.mav.mission_current_encode(self.current, len(self.items), state),
                         log=k == 0)

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

"""The operator's mission on the vehicle, downloaded whenever its ``MIS_ID`` changes.

The link asks for the parameter ``MIS_ID`` once a second
(:meth:`MissionDownload.poll`); when its value is not the mission last
downloaded, a watcher thread (:meth:`MissionDownload.watch`, each time
:meth:`MissionDownload.check`) downloads the vehicle's mission with the
mission protocol (MISSION_REQUEST_LIST → MISSION_COUNT → MISSION_REQUEST_INT
for each item → MISSION_ACK, re-requesting lost ones), as MAVProxy's ``wp``
module does. Its waypoints become System 1's operator waypoints, in the local
frame of the vehicle's geodetic origin.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from dualpilot.model.dynamics import Array
from services.common import mav
from services.common.log import fields

from .connection import Send

log = logging.getLogger("services.supervisor.link")
m = mav.mavlink

MISSION = m.MAV_MISSION_TYPE_MISSION


class MissionDownload:
    """The vehicle's mission as last downloaded, and the download itself."""

    MESSAGES = ("PARAM_VALUE", "MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ACK")

    def __init__(self, send: Send, target: tuple[int, int],
                 origin: Callable[[], tuple[float, float] | None]):
        """``origin()``: the vehicle's geodetic origin (lat, lon degrees; None not known yet)."""
        self.send = send
        self.target = target
        self.origin = origin
        self.cond = threading.Condition()
        self.mission_id_seen: float | None = None
        self.mission_id_loaded: float | None = None
        self.mission_items: list[mav.MissionItem] | None = None
        self.mission_rev = 0
        self._q: queue.Queue[Any] = queue.Queue()
        self._changed = threading.Event()
        self._stop = threading.Event()

    def on_message(self, msg: Any) -> None:
        if msg.get_type() != "PARAM_VALUE":
            self._q.put(msg)
        elif msg.param_id == "MIS_ID":
            self.mission_id_seen = float(msg.param_value)
            if self.mission_id_seen != self.mission_id_loaded:
                self._changed.set()

    def poll(self) -> None:
        """Ask for ``MIS_ID`` (once a second, from the link's poll)."""
        self.send("param_request_read", *self.target, b"MIS_ID", -1)

    def close(self) -> None:
        """End :meth:`watch` and any download under way."""
        self._stop.set()
        self._changed.set()

    def _expect(self, kind: str, timeout_s: float, seq: int | None = None) -> Any:
        deadline = time.monotonic() + timeout_s
        while (remaining := deadline - time.monotonic()) > 0 and not self._stop.is_set():
            try:
                msg = self._q.get(timeout=min(remaining, 0.1))
            except queue.Empty:
                continue
            if msg.get_type() == kind and (seq is None or msg.seq == seq) and int(
                    getattr(msg, "mission_type", MISSION)) == MISSION:
                return msg
        return None

    def download(self, timeout_s: float = 0.5, retries: int = 5) -> list[mav.MissionItem]:
        """The vehicle's mission, item by item (mission protocol, re-requesting lost ones)."""
        while not self._q.empty():
            self._q.get_nowait()
        count_msg = None
        for _ in range(retries):
            self.send("mission_request_list", *self.target, MISSION)
            if (count_msg := self._expect("MISSION_COUNT", timeout_s)) is not None:
                break
        if count_msg is None:
            raise TimeoutError("no MISSION_COUNT from the vehicle")
        items: list[mav.MissionItem] = []
        for seq in range(int(count_msg.count)):
            for _ in range(retries):
                self.send("mission_request_int", *self.target, seq, MISSION)
                if (item := self._expect("MISSION_ITEM_INT", timeout_s, seq)) is not None:
                    items.append(mav.MissionItem.from_msg(item))
                    break
            else:
                raise TimeoutError(f"no MISSION_ITEM_INT {seq} from the vehicle")
        self.send("mission_ack", *self.target, m.MAV_MISSION_ACCEPTED, MISSION)
        return items

    def watch(self) -> None:
        """Download the mission whenever ``MIS_ID`` names another one, until :meth:`close`."""
        while not self._stop.is_set():
            self._changed.wait(1.0)  # set by the reader when MIS_ID is heard
            self._changed.clear()
            self.check()

    def check(self) -> None:
        """Download the vehicle's mission if ``MIS_ID`` names another than the one loaded."""
        seen = self.mission_id_seen
        if seen is None or seen == self.mission_id_loaded:
            return
        try:
            items = self.download()
        except TimeoutError as err:
            log.warning("mission download failed", extra=fields(error=str(err)))
            return
        with self.cond:
            self.mission_items, self.mission_id_loaded = items, seen
            self.mission_rev += 1
            self.cond.notify_all()
        log.info("mission downloaded", extra=fields(mission_id=seen, items=len(items),
                                                    waypoints=sum(i.is_waypoint()
                                                                  for i in items)))

    def wait_downloaded(self, timeout_s: float, stop: threading.Event) -> bool:
        """Wait until the vehicle's current mission (its MIS_ID) has been downloaded."""
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while self.mission_id_seen is None or self.mission_id_loaded != self.mission_id_seen:
                remaining = deadline - time.monotonic()
                if remaining <= 0 or stop.is_set():
                    return False
                self.cond.wait(min(remaining, 0.1))
            return True

    def operator_waypoints(self) -> tuple[int, Array | None, float | None]:
        """(revision, local waypoints (k, 2) east/north m or None, mission id) of the newest
        downloaded mission; revision 0 means none downloaded yet."""
        with self.cond:
            rev, items, mid = self.mission_rev, self.mission_items, self.mission_id_loaded
        if not rev or items is None:
            return rev, None, mid
        origin = self.origin()
        if origin is None:
            return 0, None, None  # not convertible yet: the next step tries again
        wps = mav.waypoints_local(items, origin)
        return rev, (np.array(wps, dtype=float) if wps else None), mid

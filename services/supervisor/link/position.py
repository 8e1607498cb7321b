"""Where the vehicle is: LOCAL_POSITION_NED on its own clock, its GPS fix and geodetic origin.

The newest LOCAL_POSITION_NED is kept with its ``time_boot_ms`` (the
vehicle's simulated clock), as the state of the mission's dimension
(:meth:`Position.set_dim`: in 3-D with its z and vz, down positive, as the altitude and
the climb); a frame that moves the state without a new time is counted (lockstep: only a
step moves the vehicle). GLOBAL_POSITION_INT not at 0/0 is a valid fix; GPS_GLOBAL_ORIGIN
(asked at 1 Hz until it comes) is the origin of the local frame, which converts the
operator's mission.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Any

import numpy as np

from dualpilot.model.dynamics import Array
from services.common import mav, mavlink_codec, rejections

from .connection import Send

log = logging.getLogger("services.supervisor.link")
m = mav.mavlink


class Position:
    """The vehicle's position as the link last heard it."""

    MESSAGES = ("LOCAL_POSITION_NED", "GLOBAL_POSITION_INT", "GPS_GLOBAL_ORIGIN")

    def __init__(self, send: Send, target: tuple[int, int]):
        self.send = send
        self.target = target
        self.cond = threading.Condition()
        self.state: Array | None = None
        self.state_time_ms = -1
        self.global_ok = False
        self.origin: tuple[float, float] | None = None
        #: LOCAL_POSITION_NED that changed the state without a new time_boot_ms (no step)
        self.moved_without_step = 0
        self.dim = 2  #: of the states kept (the mission's: :meth:`set_dim`)

    def set_dim(self, dim: int) -> None:
        """Keep states of ``dim`` (2: planar, 3: with the altitude and climb) from now on; a
        state of the other dimension is forgotten (the next LOCAL_POSITION_NED brings one)."""
        with self.cond:
            if dim != self.dim:
                self.dim = dim
                self.state, self.state_time_ms = None, -1

    def on_message(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "LOCAL_POSITION_NED":
            self._on_local(msg)
        elif kind == "GLOBAL_POSITION_INT":
            self.global_ok = msg.lat != 0 or msg.lon != 0
        else:
            lat, lon = msg.latitude / 1e7, msg.longitude / 1e7
            if math.isfinite(lat) and abs(lat) < 85 and abs(lon) <= 180:
                self.origin = (lat, lon)

    def _on_local(self, msg: Any) -> None:
        try:
            if self.dim == 3:
                x = mavlink_codec.state_from_ned(msg.x, msg.y, msg.vx, msg.vy, msg.z, msg.vz)
            else:
                x = mavlink_codec.state_from_ned(msg.x, msg.y, msg.vx, msg.vy)
        except rejections.CodecError as err:
            rejections.rejected("LOCAL_POSITION_NED", err, log)
            return
        with self.cond:
            if msg.time_boot_ms >= self.state_time_ms:
                if (msg.time_boot_ms == self.state_time_ms and self.state is not None
                        and not np.array_equal(x, self.state)):
                    self.moved_without_step += 1  # lockstep: only a step moves it
                self.state, self.state_time_ms = x, int(msg.time_boot_ms)
                self.cond.notify_all()

    def poll(self) -> None:
        """Ask for the origin until it comes (once a second, from the link's poll)."""
        if self.origin is None:
            self.send("command_long", *self.target, m.MAV_CMD_REQUEST_MESSAGE, 0,
                      m.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN, 0, 0, 0, 0, 0, 0)

    def valid(self) -> bool:
        """A GPS fix and a local position: the vehicle can be taken."""
        return self.global_ok and self.state is not None

    def latest(self) -> tuple[Array, int] | None:
        """(the newest state, its ``time_boot_ms``), None before the first."""
        with self.cond:
            if self.state is None:
                return None
            return self.state.copy(), self.state_time_ms

    def wait_state(self, min_time_ms: int, timeout_s: float,
                   stop: threading.Event) -> tuple[int, Array] | None:
        """The newest state stamped at or after ``min_time_ms`` (None on timeout or stop)."""
        deadline = time.monotonic() + timeout_s
        with self.cond:
            while self.state is None or self.state_time_ms < min_time_ms:
                remaining = deadline - time.monotonic()
                if remaining <= 0 or stop.is_set():
                    return None
                self.cond.wait(min(remaining, 0.1))
            return self.state_time_ms, self.state.copy()

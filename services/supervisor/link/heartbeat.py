"""What the vehicle's HEARTBEAT says: its autopilot, mode and arming, and whether it is alive.

The mode numbers are the autopilot's (PX4's OFFBOARD is main mode 6,
ArduPilot's GUIDED 4: services/common/mavmodes.py), read from the HEARTBEAT's
``autopilot`` field. Every change of mode or arming is kept with the
STATUSTEXT before it, and each time the vehicle leaves offboard control while
armed is counted (a fault of the mission: services/supervisor/faults.py). The
vehicle counts as lost after ``lost_after_s`` without a heartbeat, counted
from when the reader last listened (:func:`heard_within`).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from services.common import mav, mavmodes
from services.common.log import fields

from ..linkloop import READER_PERIOD_S

log = logging.getLogger("services.supervisor.link")
m = mav.mavlink


@dataclass(frozen=True)
class ModeChange:
    """The vehicle's mode or arming changed (as its HEARTBEAT said)."""

    at_s: float  #: monotonic s the heartbeat was read
    mode: str  #: the autopilot's name (OFFBOARD, AUTO.LOITER, GUIDED, LOITER, …)
    armed: bool
    text: str  #: the last STATUSTEXT before it (the vehicle's reason)


def heard_within(now_s: float, heartbeat_s: float, listened_s: float, lost_after_s: float,
                 reader_period_s: float = READER_PERIOD_S) -> bool:
    """Whether a vehicle last heard at ``heartbeat_s`` still counts as alive at ``now_s``
    (monotonic s): within ``lost_after_s``, less the time the reader was kept from listening
    beyond its period since ``listened_s`` (heartbeats wait in the socket meanwhile)."""
    deaf_s = max(0.0, now_s - listened_s - reader_period_s)
    return now_s - heartbeat_s - deaf_s <= lost_after_s


class VehicleStatus:
    """The vehicle's HEARTBEAT and STATUSTEXT, as the link last heard them."""

    MESSAGES = ("HEARTBEAT", "STATUSTEXT")

    def __init__(self, target_system: int, lost_after_s: float,
                 listened: Callable[[], float], clock: Callable[[], float] = time.monotonic):
        """``listened()``: when the reader last waited for the vehicle (monotonic s)."""
        self.target_system = target_system
        self.lost_after_s = lost_after_s
        self.listened = listened
        self.clock = clock
        self.cond = threading.Condition()
        self.seen = threading.Event()
        self.last_heartbeat = 0.0
        self.mode = -1
        self.armed = False
        #: the vehicle's mode numbers, from its HEARTBEAT's autopilot field (None: not heard)
        self.modes: mavmodes.ModeMap | None = None
        #: every change of mode or arming: (monotonic s, mode name, armed, last STATUSTEXT)
        self.mode_changes: list[ModeChange] = []
        #: times the vehicle left offboard mode while armed, and the last STATUSTEXT before it
        self.holds = 0
        self.hold_reasons: list[str] = []
        self.last_text = ""

    def on_message(self, msg: Any) -> None:
        if msg.get_type() == "STATUSTEXT":
            self.last_text = str(msg.text)[:50]
        else:
            self._on_heartbeat(msg)

    def _on_heartbeat(self, msg: Any) -> None:
        """The vehicle's autopilot (its mode numbers), mode and arming; a change is kept, and
        leaving offboard control while armed is counted (a fault of the mission)."""
        with self.cond:
            modes = mavmodes.for_autopilot(int(msg.autopilot))
            if not self.seen.is_set() or not self.alive() or modes != self.modes:
                log.info("vehicle heartbeat", extra=fields(
                    sysid=self.target_system, mav_type=msg.type, autopilot=modes.family))
            self.modes = modes
            self.last_heartbeat = self.clock()
            mode, armed = int(msg.custom_mode), bool(
                msg.base_mode & m.MAV_MODE_FLAG_SAFETY_ARMED)
            if (mode, armed) != (self.mode, self.armed):
                self.mode_changes.append(ModeChange(self.last_heartbeat, modes.name(mode), armed,
                                                    self.last_text))
                if self.seen.is_set():
                    log.info("vehicle mode", extra=fields(mode=modes.name(mode), armed=armed))
                if self.mode == modes.offboard and self.armed and mode != modes.offboard:
                    self.holds += 1  # it left offboard control: a fault of the mission
                    self.hold_reasons.append(self.last_text)
            self.mode, self.armed = mode, armed
            self.seen.set()
            self.cond.notify_all()

    def alive(self) -> bool:
        """A heartbeat from the vehicle within ``lost_after_s`` — counted from when the reader
        last listened: a reader kept off the CPU has not heard the vehicle, but has not missed
        it either (its heartbeats wait in the socket)."""
        if not self.seen.is_set():
            return False
        return heard_within(self.clock(), self.last_heartbeat, self.listened(),
                            self.lost_after_s)

    def offboard(self) -> bool:
        """Alive, armed and in offboard mode (PX4 OFFBOARD, ArduPilot GUIDED): the setpoints
        fly it."""
        return (self.alive() and self.armed and self.modes is not None
                and self.mode == self.modes.offboard)

    def mode_name(self, mode: int | None = None) -> str:
        mode = self.mode if mode is None else mode
        return self.modes.name(mode) if self.modes is not None else str(mode)

    def status(self) -> str:
        if not self.alive():
            return "lost"
        armed = "armed" if self.armed else "disarmed"
        return f"{self.mode_name()}, {armed}"

    def wait_vehicle(self, timeout_s: float, stop: threading.Event) -> bool:
        """Wait for the vehicle's first heartbeat (False at the timeout or on stop)."""
        deadline = time.monotonic() + timeout_s
        while not self.seen.wait(0.1):
            if stop.is_set() or time.monotonic() > deadline:
                return False
        return True

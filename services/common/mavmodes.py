"""Flight-mode numbers of the two autopilots the project speaks (HEARTBEAT ``custom_mode``).

A vehicle's HEARTBEAT ``autopilot`` field says how to read its ``custom_mode``
(MAVSDK, MAVProxy and QGroundControl read it so): ArduPilot's numbers for
MAV_AUTOPILOT_ARDUPILOTMEGA (ArduCopter/mode.h: GUIDED 4, LOITER 5, …), PX4's
otherwise (``px4_custom_mode.h``: ``custom_mode = main_mode << 16 | sub_mode << 24``,
OFFBOARD is main mode 6, AUTO.LOITER main 4 sub 3). The supervisor takes
its mode map from the vehicle's heartbeat (:func:`for_autopilot`), never
from a constant; uavsim builds its flavours (services/uavsim/flavour.py) on
the same numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

from services.common import mav

m = mav.mavlink

#: PX4 main modes and AUTO sub modes (px4_custom_mode.h)
PX4_MAIN = {1: "MANUAL", 2: "ALTCTL", 3: "POSCTL", 4: "AUTO", 5: "ACRO", 6: "OFFBOARD",
            7: "STABILIZED", 8: "RATTITUDE"}
PX4_AUTO_SUB = {1: "READY", 2: "TAKEOFF", 3: "LOITER", 4: "MISSION", 5: "RTL", 6: "LAND",
                8: "FOLLOW_TARGET", 9: "PRECLAND"}
#: ArduCopter mode numbers (ArduCopter/mode.h)
COPTER = {0: "STABILIZE", 1: "ACRO", 2: "ALT_HOLD", 3: "AUTO", 4: "GUIDED", 5: "LOITER",
          6: "RTL", 7: "CIRCLE", 9: "LAND", 16: "POSHOLD", 17: "BRAKE", 21: "SMART_RTL"}


def px4_mode(main: int, sub: int = 0) -> int:
    """PX4's ``custom_mode`` for a main mode and an AUTO sub mode."""
    return (main << 16) | (sub << 24)


def px4_name(custom_mode: int) -> str:
    """PX4's name of a custom mode: OFFBOARD, AUTO.LOITER, …"""
    main, sub = (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
    name = PX4_MAIN.get(main, str(main))
    return f"{name}.{PX4_AUTO_SUB.get(sub, sub)}" if main == 4 else name


def copter_name(custom_mode: int) -> str:
    return COPTER.get(custom_mode, str(custom_mode))


@dataclass(frozen=True)
class ModeMap:
    """What an offboard companion needs of an autopilot's modes."""

    family: str  #: "px4" or "ardupilot"
    offboard: int  #: custom_mode of offboard control (PX4 OFFBOARD, ArduPilot GUIDED)
    hold: int  #: custom_mode of the hold (PX4 AUTO.LOITER, ArduPilot LOITER)
    #: DO_SET_MODE param2 and param3 that ask for offboard control
    offboard_request: tuple[float, float]

    def name(self, custom_mode: int) -> str:
        return px4_name(custom_mode) if self.family == "px4" else copter_name(custom_mode)


PX4_MODES = ModeMap("px4", px4_mode(6), px4_mode(4, 3), (6.0, 0.0))
ARDUPILOT_MODES = ModeMap("ardupilot", mav.MODE_GUIDED, mav.MODE_LOITER,
                          (float(mav.MODE_GUIDED), 0.0))


def for_autopilot(autopilot: int) -> ModeMap:
    """The mode map of a vehicle heartbeating ``autopilot`` (as MAVSDK reads it: ArduPilot's
    numbers for MAV_AUTOPILOT_ARDUPILOTMEGA, PX4's otherwise)."""
    return ARDUPILOT_MODES if autopilot == m.MAV_AUTOPILOT_ARDUPILOTMEGA else PX4_MODES

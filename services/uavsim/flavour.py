"""The autopilot a vehicle claims to be: HEARTBEAT ``autopilot`` and its ``custom_mode`` numbers.

Ground stations and SDKs decode ``custom_mode`` by the HEARTBEAT's
``autopilot`` field (MAVSDK: ArduPilot numbers for MAV_AUTOPILOT_ARDUPILOTMEGA,
PX4's otherwise; MAVProxy and QGroundControl likewise), so the vehicle sends
the numbers of the autopilot it names:

* **ardupilot** (MAV_AUTOPILOT_ARDUPILOTMEGA, ArduCopter numbers): GUIDED 4
  is offboard, LOITER 5 is hold; DO_SET_MODE ``param2`` and SET_MODE
  ``custom_mode`` carry the number.
* **px4** (MAV_AUTOPILOT_PX4, ``px4_custom_mode.h``): ``custom_mode`` is
  ``main_mode << 16 | sub_mode << 24``; OFFBOARD is main mode 6, hold is
  AUTO.LOITER (main 4, sub 3); DO_SET_MODE carries main mode in ``param2``
  and sub mode in ``param3``.

uavsim flies two of the autopilot's modes: :data:`OFFBOARD` (the companion's
setpoints) and :data:`HOLD` (stop and stay). The others are named, so a
request for them is answered UNSUPPORTED by name rather than mis-read.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from services.common import mav

m = mav.mavlink

OFFBOARD = "offboard"
HOLD = "hold"

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


@dataclass(frozen=True)
class Flavour:
    """One autopilot's identity and mode numbering."""

    name: str
    autopilot: int
    #: HEARTBEAT.custom_mode of OFFBOARD and HOLD
    modes: dict[str, int]

    def custom_mode(self, mode: str) -> int:
        return self.modes[mode]

    def mode_of(self, custom_mode: int) -> str | None:
        """OFFBOARD, HOLD, or None for a mode uavsim does not fly."""
        for mode, value in self.modes.items():
            if value == custom_mode:
                return mode
        return None

    def name_of(self, custom_mode: int) -> str:
        """The autopilot's own name for a custom mode (GUIDED, AUTO.LOITER, …)."""
        if self.name == "px4":
            main, sub = (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
            name = PX4_MAIN.get(main, str(main))
            return f"{name}.{PX4_AUTO_SUB.get(sub, sub)}" if main == 4 else name
        return COPTER.get(custom_mode, str(custom_mode))

    def from_command(self, param2: float, param3: float) -> int | None:
        """The custom mode DO_SET_MODE asks for (param2, and PX4's sub mode in param3).

        NaN in param3 means unset (sub mode 0); None for a non-integer or NaN param2.
        """
        if not math.isfinite(param2) or param2 != int(param2) or param2 < 0:
            return None
        if self.name == "px4":
            sub = 0 if math.isnan(param3) else int(param3)
            return px4_mode(int(param2), sub)
        return int(param2)


ARDUPILOT = Flavour("ardupilot", int(m.MAV_AUTOPILOT_ARDUPILOTMEGA),
                    {OFFBOARD: mav.MODE_GUIDED, HOLD: mav.MODE_LOITER})
PX4 = Flavour("px4", int(m.MAV_AUTOPILOT_PX4),
              {OFFBOARD: px4_mode(6), HOLD: px4_mode(4, 3)})
FLAVOURS = {f.name: f for f in (ARDUPILOT, PX4)}

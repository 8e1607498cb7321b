"""The autopilot a vehicle claims to be: HEARTBEAT ``autopilot``, its mode numbers and SITL habits.

Ground stations and SDKs decode ``custom_mode`` by the HEARTBEAT's
``autopilot`` field (MAVSDK: ArduPilot numbers for MAV_AUTOPILOT_ARDUPILOTMEGA,
PX4's otherwise; MAVProxy and QGroundControl likewise), so the vehicle sends
the numbers of the autopilot it names. The navigation states themselves
(:class:`Nav`) are PX4 commander's (``vehicle_status.nav_state``); each
flavour maps them onto its own mode numbers:

=========  ===========================  ================  ==============================
Nav        PX4 (``px4_custom_mode.h``)   ArduCopter        what the vehicle flies
=========  ===========================  ================  ==============================
OFFBOARD   OFFBOARD (main 6)             GUIDED (4)        the companion's setpoints
HOLD       AUTO.LOITER (4/3)             LOITER (5)        stays where it is
TAKEOFF    AUTO.TAKEOFF (4/2)            GUIDED (4)        climbs to the take-off altitude
LAND       AUTO.LAND (4/6)               LAND (9)          descends where it is, disarms
RETURN     AUTO.RTL (4/5)                RTL (6)           climbs, flies home, lands
MISSION    AUTO.MISSION (4/4)            AUTO (3)          the uploaded mission
POSITION   POSCTL (3)                    POSHOLD (16)      the sticks (MANUAL_CONTROL)
=========  ===========================  ================  ==============================

PX4 encodes ``custom_mode`` as ``main_mode << 16 | sub_mode << 24``;
DO_SET_MODE carries the main mode in ``param2`` and the AUTO sub mode in
``param3``. ArduPilot's number is ``custom_mode`` and DO_SET_MODE's
``param2``. Beside the numbers, a flavour carries the habits of its
autopilot: the MAV_RESULT of a refused command (PX4's commander answers
TEMPORARILY_REJECTED, ArduPilot FAILED), ArduPilot's GUIDED semantics
(:attr:`Flavour.guided`: GUIDED needs no setpoint stream, a take-off and a
reposition stay in GUIDED, AUTO refuses to start on the ground without a
take-off item) and the links and home of its SITL (:attr:`Flavour.sitl`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

from services.common import mav
from services.common.mavmodes import copter_name, px4_mode, px4_name

m = mav.mavlink


class Nav(StrEnum):
    """The navigation states the vehicle flies (PX4 commander's nav_state)."""

    OFFBOARD = "offboard"
    HOLD = "hold"
    TAKEOFF = "takeoff"
    LAND = "land"
    RETURN = "return"
    MISSION = "mission"
    POSITION = "position"


@dataclass(frozen=True)
class Sitl:
    """What the autopilot's SITL does on its own: where it sends, where home is."""

    offboard_url: str  #: the API / companion link
    gcs_url: str  #: the ground-station link
    home: tuple[float, float, float]  #: deg lat, lon, m AMSL of the local frame's origin
    start: tuple[float, float]  #: m east, north of the origin where the vehicle boots


#: PX4 SITL: the vehicle *sends* to 14540 (onboard/API: MAVSDK's ``udpin://0.0.0.0:14540``) and
#: 14550 (QGroundControl listens there) from ports of its own; home is PX4's default
#: (PX4_HOME_LAT/LON/ALT), the local frame's origin, where the vehicle boots
PX4_SITL = Sitl("udpout:127.0.0.1:14540", "udpout:127.0.0.1:14550",
                (47.397742, 8.545594, 488.0), (0.0, 0.0))
#: ArduPilot SITL: TCP servers, SERIAL0 on 5760 (the ground station: MAVProxy's --master) and
#: SERIAL1 on 5762 (a second MAVLink link: the companion); the project's area as home
ARDUPILOT_SITL = Sitl("tcpin:127.0.0.1:5762", "tcpin:127.0.0.1:5760",
                      (35.1450, 33.4110, 0.0), (50.0, 50.0))


@dataclass(frozen=True)
class Flavour:
    """One autopilot's identity, mode numbering and habits."""

    name: str
    autopilot: int  #: HEARTBEAT.autopilot
    modes: dict[Nav, int]  #: HEARTBEAT.custom_mode of each navigation state
    #: the navigation state a requested custom mode asks for (several numbers may ask for one)
    requests: dict[int, Nav]
    names: dict[Nav, str]  #: the autopilot's own name of each state (STATUSTEXT, logs)
    refused: int  #: MAV_RESULT of a command the state machine refuses
    guided: bool  #: ArduPilot's GUIDED semantics (module docstring)
    sitl: Sitl

    def custom_mode(self, nav: Nav) -> int:
        return self.modes[nav]

    def nav_of(self, custom_mode: int) -> Nav | None:
        """The state a requested custom mode asks for; None for a mode the vehicle lacks."""
        return self.requests.get(custom_mode)

    def name_of(self, custom_mode: int) -> str:
        """The autopilot's own name for any custom mode (GUIDED, AUTO.LOITER, …)."""
        return px4_name(custom_mode) if self.name == "px4" else copter_name(custom_mode)

    def from_command(self, param2: float, param3: float) -> int | None:
        """The custom mode DO_SET_MODE asks for (param2, and PX4's sub mode in param3).

        NaN in param3 means unset (sub mode 0); None for a non-integer or NaN param2.
        """
        if not math.isfinite(param2) or param2 != int(param2) or param2 < 0:
            return None
        if self.name == "px4":
            sub = 0 if not math.isfinite(param3) else int(param3)
            return px4_mode(int(param2), sub)
        return int(param2)


_PX4_MODES = {Nav.OFFBOARD: px4_mode(6), Nav.HOLD: px4_mode(4, 3), Nav.TAKEOFF: px4_mode(4, 2),
              Nav.LAND: px4_mode(4, 6), Nav.RETURN: px4_mode(4, 5), Nav.MISSION: px4_mode(4, 4),
              Nav.POSITION: px4_mode(3)}
PX4 = Flavour(
    "px4", int(m.MAV_AUTOPILOT_PX4), _PX4_MODES,
    # AUTO without a sub mode is MISSION (Commander.cpp); POSCTL's sub modes are all POSITION
    {**{v: k for k, v in _PX4_MODES.items()}, px4_mode(4): Nav.MISSION},
    {Nav.OFFBOARD: "Offboard", Nav.HOLD: "Hold", Nav.TAKEOFF: "Takeoff", Nav.LAND: "Land",
     Nav.RETURN: "Return", Nav.MISSION: "Mission", Nav.POSITION: "Position"},
    int(m.MAV_RESULT_TEMPORARILY_REJECTED), False, PX4_SITL)
ARDUPILOT = Flavour(
    "ardupilot", int(m.MAV_AUTOPILOT_ARDUPILOTMEGA),
    {Nav.OFFBOARD: 4, Nav.HOLD: 5, Nav.TAKEOFF: 4, Nav.LAND: 9, Nav.RETURN: 6, Nav.MISSION: 3,
     Nav.POSITION: 16},
    {4: Nav.OFFBOARD, 5: Nav.HOLD, 17: Nav.HOLD, 9: Nav.LAND, 6: Nav.RETURN, 3: Nav.MISSION,
     16: Nav.POSITION},
    {Nav.OFFBOARD: "GUIDED", Nav.HOLD: "LOITER", Nav.TAKEOFF: "GUIDED", Nav.LAND: "LAND",
     Nav.RETURN: "RTL", Nav.MISSION: "AUTO", Nav.POSITION: "POSHOLD"},
    int(m.MAV_RESULT_FAILED), True, ARDUPILOT_SITL)
FLAVOURS = {f.name: f for f in (ARDUPILOT, PX4)}

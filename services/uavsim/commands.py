"""The vehicle's COMMAND_LONG handling: arming, take-off and landing, modes, message requests.

Parameters (https://mavlink.io/en/services/command.html): NaN means *unset*
(use the default), which is how MAVSDK fills every parameter a command does
not use; ±inf is never a value. So a command is refused as bad input
(counted ``not_finite``, COMMAND_ACK DENIED) only for ±inf anywhere or NaN in
a parameter it needs (:data:`REQUIRED`); NaN elsewhere is read as the default.

=====================================  ==============================================
command                                what the vehicle does
=====================================  ==============================================
COMPONENT_ARM_DISARM                   arm (refused with an empty battery); disarm on
                                       the ground, or in the air with param2 = 21196
DO_SET_MODE / SET_MODE                 offboard (needs a live setpoint stream) or hold,
                                       in the flavour's numbers (services/uavsim/flavour.py)
NAV_TAKEOFF                            armed: airborne at SIM_ALT_M at once (Sec. IV is 2-D)
NAV_LAND                               on the ground at once, holding (then disarm)
REQUEST_MESSAGE, GET_HOME_POSITION,    the message after the ACK
REQUEST_AUTOPILOT_CAPABILITIES
SET_MESSAGE_INTERVAL / GET_…           the stream rate (services/uavsim/intervals.py)
RETURN_TO_LAUNCH, MISSION_START        DENIED: operator missions are flown by System 1
anything else                          UNSUPPORTED
=====================================  ==============================================
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from services.common import mav, rejections
from services.common.log import fields

from . import flavour as fl
from . import telemetry

if TYPE_CHECKING:
    from .endpoint import Endpoint

log = logging.getLogger("services.uavsim")
m = mav.mavlink

#: commands that steer the vehicle: only from the link and peer in control (Endpoint.may_control)
CONTROL_COMMANDS = frozenset({m.MAV_CMD_COMPONENT_ARM_DISARM, m.MAV_CMD_DO_SET_MODE,
                              m.MAV_CMD_NAV_TAKEOFF, m.MAV_CMD_NAV_LAND})
FORCE_DISARM_MAGIC = 21196  # MAV_CMD_COMPONENT_ARM_DISARM param2: disarm even in the air
#: parameters (1-based) a command cannot do without: NaN there is refused
REQUIRED: dict[int, tuple[int, ...]] = {
    m.MAV_CMD_COMPONENT_ARM_DISARM: (1,),
    m.MAV_CMD_DO_SET_MODE: (1, 2),
    m.MAV_CMD_REQUEST_MESSAGE: (1,),
    m.MAV_CMD_SET_MESSAGE_INTERVAL: (1, 2),
    m.MAV_CMD_GET_MESSAGE_INTERVAL: (1,),
}
#: AUTOPILOT_VERSION.flight_sw_version: 0.1.0, release (major<<24 | minor<<16 | patch<<8 | type)
FLIGHT_SW_VERSION = (0 << 24) | (1 << 16) | (0 << 8) | 255
#: what the vehicle really does: MAVLink 2 and signing on the offboard link, MISSION_ITEM_INT
#: and MISSION_ITEM uploads, float parameters, SET_POSITION_TARGET_LOCAL_NED. Not claimed:
#: COMMAND_INT (answered UNSUPPORTED), FTP, terrain, SET_ATTITUDE_TARGET, fences/rally.
CAPABILITIES = (m.MAV_PROTOCOL_CAPABILITY_MAVLINK2 | m.MAV_PROTOCOL_CAPABILITY_MISSION_INT
                | m.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT | m.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
                | m.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED)


class CommandParams:
    """COMMAND_LONG param1..7 with MAVLink's NaN = unset (see the module docstring)."""

    def __init__(self, msg: Any):
        self.values = [float(getattr(msg, f"param{k}")) for k in range(1, 8)]

    def check(self, command: int) -> None:
        """Raise CodecError (``not_finite``) for ±inf anywhere or NaN in a required param."""
        for k, v in enumerate(self.values, start=1):
            if math.isinf(v) or (math.isnan(v) and k in REQUIRED.get(command, ())):
                raise rejections.invalid(f"COMMAND_LONG.param{k} is {v}",
                                         rejections.Reason.NOT_FINITE)

    def __getitem__(self, k: int) -> float:
        """param ``k`` (1-based), NaN (unset) as 0."""
        v = self.values[k - 1]
        return 0.0 if math.isnan(v) else v

    def raw(self, k: int) -> float:
        return self.values[k - 1]


def command_name(cmd: int) -> str:
    entry = m.enums["MAV_CMD"].get(cmd)
    return entry.name if entry is not None else str(cmd)


class Commands:
    """COMMAND_LONG and SET_MODE for one :class:`~services.uavsim.endpoint.Endpoint`."""

    def __init__(self, ep: Endpoint):
        self.ep = ep
        self._after_ack: Callable[[], None] | None = None

    # -- modes ----------------------------------------------------------------------------------
    def mode_request(self, base_mode: int, custom_mode: int | None) -> int:
        ep = self.ep
        if not base_mode & m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED or custom_mode is None:
            return int(m.MAV_RESULT_UNSUPPORTED)
        mode = ep.flavour.mode_of(custom_mode)
        if mode == fl.OFFBOARD:
            if not ep.stream_live(time.monotonic()):
                ep.statustext(f"{ep.mode_name(fl.OFFBOARD)} refused: no setpoint stream",
                              m.MAV_SEVERITY_WARNING)
                return int(m.MAV_RESULT_DENIED)
            ep.end_failsafe(time.monotonic())
            if ep.armed:
                ep.airborne = True
            ep.set_mode(fl.OFFBOARD, "offboard control")
            return int(m.MAV_RESULT_ACCEPTED)
        if mode == fl.HOLD:
            ep.end_failsafe(time.monotonic())
            if ep.mode != fl.HOLD:
                ep.vehicle.brake()
            ep.set_mode(fl.HOLD, "hold (commanded)")
            return int(m.MAV_RESULT_ACCEPTED)
        log.info("mode not flown", extra=fields(mode=ep.flavour.name_of(custom_mode)))
        return int(m.MAV_RESULT_UNSUPPORTED)

    # -- arming, take-off, landing ------------------------------------------------------------
    def arm(self, arm: bool, force: bool) -> int:
        ep = self.ep
        if arm:
            if ep.vehicle.battery_fraction <= 0:
                ep.statustext("arming refused: battery empty", m.MAV_SEVERITY_WARNING)
                return int(m.MAV_RESULT_DENIED)
            if not ep.armed:
                ep.armed = True
                if ep.mode == fl.OFFBOARD:
                    ep.airborne = True  # offboard take-off straight to SIM_ALT_M (2-D)
                log.info("armed", extra=fields(mode=ep.mode_name()))
                ep.statustext("armed")
                ep.heartbeat()
            return int(m.MAV_RESULT_ACCEPTED)
        if ep.airborne and not force:
            ep.statustext("disarm refused: in the air", m.MAV_SEVERITY_WARNING)
            return int(m.MAV_RESULT_DENIED)
        if ep.armed:
            ep.armed = ep.airborne = False
            ep.vehicle.brake()
            log.info("disarmed", extra=fields(forced=force))
            ep.statustext("disarmed")
            ep.heartbeat()
        return int(m.MAV_RESULT_ACCEPTED)

    def takeoff(self) -> int:
        ep = self.ep
        if not ep.armed:
            return int(m.MAV_RESULT_DENIED)
        if not ep.airborne:  # 2-D evaluation: the climb to SIM_ALT_M is instantaneous
            ep.airborne = True
            ep.statustext("airborne")
        return int(m.MAV_RESULT_ACCEPTED)

    def land(self) -> int:
        ep = self.ep
        if ep.airborne:  # as the take-off: on the ground at once, where it is
            ep.vehicle.brake()
            ep.airborne = False
            ep.set_mode(fl.HOLD, "landed")
            ep.statustext("landed")
        return int(m.MAV_RESULT_ACCEPTED)

    # -- messages -------------------------------------------------------------------------------
    def request_message(self, link: str, msg_id: int) -> int:
        ep = self.ep
        senders: dict[int, Callable[[], None]] = {
            m.MAVLINK_MSG_ID_AUTOPILOT_VERSION: lambda: self.autopilot_version(link),
            m.MAVLINK_MSG_ID_HOME_POSITION: lambda: telemetry.home_position(ep, link),
            m.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: lambda: telemetry.home_position(ep, link),
            m.MAVLINK_MSG_ID_HEARTBEAT: ep.heartbeat,
            m.MAVLINK_MSG_ID_MISSION_CURRENT: lambda: ep.mission.send_current(link),
        }
        fn = senders.get(msg_id)
        if fn is None and msg_id in (m.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
                                     m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                                     m.MAVLINK_MSG_ID_ATTITUDE, m.MAVLINK_MSG_ID_SYS_STATUS,
                                     m.MAVLINK_MSG_ID_GPS_RAW_INT,
                                     m.MAVLINK_MSG_ID_EXTENDED_SYS_STATE):
            fn = lambda: telemetry.stream(ep, msg_id)  # noqa: E731
        if fn is None:
            return int(m.MAV_RESULT_UNSUPPORTED)
        self._after_ack = fn
        return int(m.MAV_RESULT_ACCEPTED)

    def autopilot_version(self, link: str) -> None:
        ep = self.ep
        ep.send[link]("autopilot_version", CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0,
                      [0] * 8, [0] * 8, [0] * 8, 0, 0, ep.sysid)

    def message_interval(self, link: str, msg_id: int) -> None:
        self.ep.send[link]("message_interval", msg_id, self.ep.schedule.interval_us(msg_id))

    # -- COMMAND_LONG -------------------------------------------------------------------------
    def on_command(self, link: str, msg: Any) -> bool:
        ep = self.ep
        cmd = int(msg.command)
        self._after_ack = None
        result = int(m.MAV_RESULT_UNSUPPORTED)
        p = CommandParams(msg)
        ack: Callable[[int], None] = lambda res: ep.send[link](  # noqa: E731
            "command_ack", cmd, res, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())
        try:
            p.check(cmd)
        except rejections.CodecError as err:  # ±inf, or NaN where the vehicle needs a number
            ep.reject(link, err, "COMMAND_LONG")
            ack(int(m.MAV_RESULT_DENIED))
            return False
        if cmd in CONTROL_COMMANDS and not ep.may_control(link, msg, time.monotonic()):
            ack(int(m.MAV_RESULT_DENIED))  # not from the link and peer in control
            return False
        if cmd == m.MAV_CMD_COMPONENT_ARM_DISARM:
            result = self.arm(p[1] >= 0.5, int(p[2]) == FORCE_DISARM_MAGIC)
        elif cmd == m.MAV_CMD_NAV_TAKEOFF:
            result = self.takeoff()
        elif cmd == m.MAV_CMD_NAV_LAND:
            result = self.land()
        elif cmd == m.MAV_CMD_DO_SET_MODE:
            result = self.mode_request(int(p[1]), ep.flavour.from_command(p.raw(2), p.raw(3)))
        elif cmd == m.MAV_CMD_REQUEST_MESSAGE:
            result = self.request_message(link, int(p[1]))
        elif cmd == m.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            result = self.request_message(link, m.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        elif cmd == m.MAV_CMD_GET_HOME_POSITION:
            result = self.request_message(link, m.MAVLINK_MSG_ID_HOME_POSITION)
        elif cmd == m.MAV_CMD_SET_MESSAGE_INTERVAL:
            result = ep.schedule.set_interval(int(p[1]), p[2], time.monotonic())
        elif cmd == m.MAV_CMD_GET_MESSAGE_INTERVAL:
            msg_id = int(p[1])
            self._after_ack = lambda: self.message_interval(link, msg_id)
            result = int(m.MAV_RESULT_ACCEPTED)
        elif cmd in (m.MAV_CMD_NAV_RETURN_TO_LAUNCH, m.MAV_CMD_MISSION_START):
            result = int(m.MAV_RESULT_DENIED)  # operator missions are flown by System 1
        ack(result)
        if result != m.MAV_RESULT_ACCEPTED:
            log.info("command refused", extra=fields(
                link=link, command=command_name(cmd),
                result=m.enums["MAV_RESULT"][result].name))
            self._after_ack = None
        if self._after_ack is not None:
            self._after_ack()
            self._after_ack = None
        return True

    def hands_back(self, msg: Any) -> bool:
        """A mode command (SET_MODE or DO_SET_MODE) that asks for offboard mode."""
        if msg.get_type() == "SET_MODE":
            custom: int | None = int(msg.custom_mode)
        else:
            custom = self.ep.flavour.from_command(float(msg.param2), float(msg.param3))
        return custom is not None and self.ep.flavour.mode_of(custom) == fl.OFFBOARD

    def on_set_mode(self, link: str, msg: Any) -> None:
        """The legacy SET_MODE message (MAVProxy's ``mode``): acked as ArduPilot does."""
        if not self.ep.may_control(link, msg, time.monotonic()):
            self.ep.send[link]("command_ack", m.MAVLINK_MSG_ID_SET_MODE, m.MAV_RESULT_DENIED,
                               0, 0, msg.get_srcSystem(), msg.get_srcComponent())
            return
        result = self.mode_request(int(msg.base_mode), int(msg.custom_mode))
        self.ep.send[link]("command_ack", m.MAVLINK_MSG_ID_SET_MODE, result, 0, 0,
                           msg.get_srcSystem(), msg.get_srcComponent())

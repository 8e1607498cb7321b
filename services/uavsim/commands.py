"""The vehicle's commands: COMMAND_LONG, COMMAND_INT and SET_MODE, checked, routed, answered.

Parameters (https://mavlink.io/en/services/command.html): NaN means *unset*
(use the default, or for DO_REPOSITION "leave unchanged"), which is how
MAVSDK fills every parameter a command does not use; ±inf is never a value.
So a command is refused as bad input (counted ``not_finite``, COMMAND_ACK
DENIED) only for ±inf anywhere or NaN in a parameter it needs
(:data:`REQUIRED`). Control commands count only from the link and peer in
control (services/uavsim/control.py); the state machine
(services/uavsim/commander.py) decides the rest, and every refusal is
answered with a STATUSTEXT as well as the ACK.

=====================================  ==============================================
command                                what the vehicle does
=====================================  ==============================================
COMPONENT_ARM_DISARM                   arm (pre-arm checks); disarm on the ground, in
                                       the air with param2 = 21196
DO_SET_MODE / SET_MODE                 a navigation state, in the flavour's numbers
NAV_TAKEOFF                            Takeoff to param7 (ArduPilot: m above home;
                                       PX4: m AMSL) or MIS_TAKEOFF_ALT
NAV_LAND / NAV_RETURN_TO_LAUNCH        Land / Return
MISSION_START                          Mission from item param1, arming (PX4)
DO_REPOSITION (LONG or INT)            goto: Hold (PX4) / GUIDED (ArduPilot) at the
                                       point; NaN keeps a coordinate, param1 > 0 is the
                                       ground speed
DO_CHANGE_SPEED                        param2 m/s becomes the cruise speed
REQUEST_MESSAGE, GET_HOME_POSITION,    the message after the ACK
REQUEST_AUTOPILOT_CAPABILITIES
SET_MESSAGE_INTERVAL / GET_…           the stream rate (services/uavsim/intervals.py)
anything else                          UNSUPPORTED
=====================================  ==============================================
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Any

from services.common import mav, rejections
from services.common.log import fields

from .autopilot import Autopilot
from .commander import Conditions, Outcome
from .control import GCS, OFFBOARD, ControlArbiter, Peer
from .flavour import Nav
from .intervals import Schedule
from .missionrun import RELATIVE_FRAMES
from .outbox import Outbox, statustext

log = logging.getLogger("services.uavsim")
m = mav.mavlink

FORCE_DISARM_MAGIC = 21196  # MAV_CMD_COMPONENT_ARM_DISARM param2: disarm even in the air
ARM, SET_MODE = int(m.MAV_CMD_COMPONENT_ARM_DISARM), int(m.MAV_CMD_DO_SET_MODE)
TAKEOFF, LAND = int(m.MAV_CMD_NAV_TAKEOFF), int(m.MAV_CMD_NAV_LAND)
RTL, MISSION_START = int(m.MAV_CMD_NAV_RETURN_TO_LAUNCH), int(m.MAV_CMD_MISSION_START)
REPOSITION, CHANGE_SPEED = int(m.MAV_CMD_DO_REPOSITION), int(m.MAV_CMD_DO_CHANGE_SPEED)
#: commands that steer the vehicle: only from the link and peer in control
CONTROL = frozenset({ARM, SET_MODE, TAKEOFF, LAND, RTL, MISSION_START, REPOSITION, CHANGE_SPEED})
#: the control commands a ground station takes control with (a forced disarm too)
TAKEOVER = frozenset({SET_MODE, LAND, RTL, MISSION_START, REPOSITION})
#: parameters (1-based) a command cannot do without: NaN there is refused
REQUIRED: dict[int, tuple[int, ...]] = {
    ARM: (1,), SET_MODE: (1, 2),
    int(m.MAV_CMD_REQUEST_MESSAGE): (1,),
    int(m.MAV_CMD_SET_MESSAGE_INTERVAL): (1, 2),
    int(m.MAV_CMD_GET_MESSAGE_INTERVAL): (1,),
}
#: COMMAND_INT x/y that mean "unchanged"
INT_UNSET = 2**31 - 1
#: s between two STATUSTEXTs about refused control (a flood must not flood the ground station)
REFUSAL_NOTE_S = 2.0


class CommandParams:
    """param1..7 with MAVLink's NaN = unset (see the module docstring)."""

    def __init__(self, values: list[float]):
        self.values = values

    @staticmethod
    def of(msg: Any) -> CommandParams:
        return CommandParams([float(getattr(msg, f"param{k}")) for k in range(1, 8)])

    def check(self, command: int, what: str = "COMMAND_LONG") -> None:
        """Raise CodecError (``not_finite``) for ±inf anywhere or NaN in a required param."""
        for k, v in enumerate(self.values, start=1):
            if math.isinf(v) or (math.isnan(v) and k in REQUIRED.get(command, ())):
                raise rejections.invalid(f"{what}.param{k} is {v}",
                                         rejections.Reason.NOT_FINITE)

    def __getitem__(self, k: int) -> float:
        """param ``k`` (1-based), NaN (unset) as 0."""
        v = self.values[k - 1]
        return 0.0 if math.isnan(v) else v

    def raw(self, k: int) -> float:
        return self.values[k - 1]

    def given(self, k: int) -> float | None:
        """param ``k``, or None when unset (NaN)."""
        v = self.values[k - 1]
        return None if math.isnan(v) else v


def command_name(cmd: int) -> str:
    entry = m.enums["MAV_CMD"].get(cmd)
    return entry.name if entry is not None else str(cmd)


Sender = Callable[[str, int], Callable[[], None] | None]
Decide = Callable[[Conditions], Outcome]


class Commands:
    """COMMAND_LONG, COMMAND_INT and SET_MODE for one vehicle.

    ``messages(link, msg_id)`` gives the function that sends a requested
    message (None: not one the vehicle has); ``reject(link, err, what)``
    counts a refused input.
    """

    def __init__(self, autopilot: Autopilot, arbiter: ControlArbiter, outbox: Outbox,
                 schedule: Schedule, messages: Sender,
                 reject: Callable[[str, rejections.CodecError, str], None]):
        self.ap = autopilot
        self.arbiter = arbiter
        self.outbox = outbox
        self.schedule = schedule
        self.messages = messages
        self.reject = reject
        self.last_refusal_note = -1e18

    # -- entry points --------------------------------------------------------------------------
    def on_command_long(self, link: str, peer: Peer, msg: Any, now: float) -> bool:
        cmd = int(msg.command)
        p = CommandParams.of(msg)
        if not self._checked(link, msg, cmd, p, "COMMAND_LONG"):
            return False
        out, after = self._long(link, peer, cmd, p, now)
        self._answer(link, msg, cmd, out, after)
        return True

    def on_command_int(self, link: str, peer: Peer, msg: Any, now: float) -> bool:
        cmd = int(msg.command)
        p = CommandParams([float(msg.param1), float(msg.param2), float(msg.param3),
                           float(msg.param4), 0.0, 0.0, float(msg.z)])
        if not self._checked(link, msg, cmd, p, "COMMAND_INT"):
            return False
        if cmd == REPOSITION and int(msg.frame) in mav.GLOBAL_FRAMES:
            lat = None if int(msg.x) == INT_UNSET else int(msg.x) / 1e7
            lon = None if int(msg.y) == INT_UNSET else int(msg.y) / 1e7
            out = self._goto(link, peer, now, p, lat, lon,
                             relative=int(msg.frame) in RELATIVE_FRAMES)
        elif cmd == CHANGE_SPEED:
            out = self._speed(link, peer, now, p)
        else:
            out = Outcome(int(m.MAV_RESULT_UNSUPPORTED))
        self._answer(link, msg, cmd, out, None)
        return True

    def on_set_mode(self, link: str, peer: Peer, msg: Any, now: float) -> bool:
        """The legacy SET_MODE message (MAVProxy's ``mode``): acked as ArduPilot does."""
        out = self._mode(link, peer, now, int(msg.base_mode), int(msg.custom_mode))
        self._answer(link, msg, int(m.MAVLINK_MSG_ID_SET_MODE), out, None)
        return True

    def on_guided_item(self, link: str, peer: Peer, msg: Any, now: float) -> bool:
        """A MISSION_ITEM(_INT) with ``current`` = 2: ArduPilot's guided goto (MAVProxy's
        ``guided LAT LON ALT``), answered with MISSION_ACK."""
        try:
            item = mav.MissionItem.from_msg(msg)
        except ValueError:
            item = None
        if item is None or not math.isfinite(item.z):
            self.reject(link, rejections.invalid("guided item without a position",
                                                 rejections.Reason.NOT_FINITE), "MISSION_ITEM")
            return False
        p = CommandParams([math.nan, 1.0, math.nan, math.nan, 0.0, 0.0, item.z])
        out = self._goto(link, peer, now, p, item.lat, item.lon,
                         relative=item.frame in RELATIVE_FRAMES)
        result = m.MAV_MISSION_ACCEPTED if out.accepted else m.MAV_MISSION_ERROR
        self.outbox.send(link, "mission_ack", msg.get_srcSystem(), msg.get_srcComponent(),
                         result, 0)
        return True

    # -- checks and answers --------------------------------------------------------------------
    def _checked(self, link: str, msg: Any, cmd: int, p: CommandParams, what: str) -> bool:
        try:
            p.check(cmd, what)
        except rejections.CodecError as err:  # ±inf, or NaN where the vehicle needs a number
            self.reject(link, err, what)
            self._ack(link, msg, cmd, int(m.MAV_RESULT_DENIED))
            return False
        return True

    def _answer(self, link: str, msg: Any, cmd: int, out: Outcome,
                after: Callable[[], None] | None) -> None:
        self._ack(link, msg, cmd, out.result)
        if out.result != m.MAV_RESULT_ACCEPTED:
            log.info("command refused", extra=fields(
                link=link, command=command_name(cmd), text=out.text,
                result=m.enums["MAV_RESULT"][out.result].name))
        elif after is not None:
            after()

    def _ack(self, link: str, msg: Any, cmd: int, result: int) -> None:
        self.outbox.send(link, "command_ack", cmd, result, 0, 0, msg.get_srcSystem(),
                         msg.get_srcComponent())

    def refused_control(self, link: str, what: str, why: str, now: float) -> Outcome:
        """Count a control message refused (not from the link and peer in control) and say why
        on the ground station (at most every REFUSAL_NOTE_S)."""
        self.reject(link, rejections.invalid(f"{what} from the {link} link: {why}",
                                             rejections.Reason.WRONG_TARGET), "control")
        self.ap.params.add("CTL_REFUSED")
        out = Outcome(int(m.MAV_RESULT_DENIED), f"{what} refused: {why}",
                      int(m.MAV_SEVERITY_WARNING))
        if now - self.last_refusal_note >= REFUSAL_NOTE_S:
            self.last_refusal_note = now
            statustext(self.outbox, out.text, out.severity)
        return out

    def _control(self, link: str, peer: Peer, now: float, what: str, takeover: bool,
                 fn: Decide, then: Callable[[], None] | None = None,
                 hands_back: bool = False) -> Outcome:
        """A control command: from the link and peer in control (else refused), decided by the
        state machine; control moves only if it was accepted; ``then`` runs after that."""
        d = self.arbiter.check(link, peer, now, takeover, hands_back)
        if d.refused:
            return self.refused_control(link, what, d.refused, now)
        out = self.ap.decide(fn, now, link=d.link)
        if out.accepted:
            self.arbiter.commit(d, now)
            if then is not None:
                then()
        return out

    # -- the commands --------------------------------------------------------------------------
    def _long(self, link: str, peer: Peer, cmd: int, p: CommandParams, now: float
              ) -> tuple[Outcome, Callable[[], None] | None]:
        c = self.ap.commander
        if cmd == ARM:
            if p[1] >= 0.5:
                return self._control(link, peer, now, "Arming", False, c.arm), None
            forced = int(p[2]) == FORCE_DISARM_MAGIC
            return self._control(link, peer, now, "Disarming", forced,
                                 lambda cc: c.disarm(cc, forced)), None
        if cmd == SET_MODE:
            custom = self.ap.flavour.from_command(p.raw(2), p.raw(3))
            return self._mode(link, peer, now, int(p[1]), custom), None
        if cmd == TAKEOFF:
            self.ap.nav.takeoff_alt = self._takeoff_alt(p.given(7))
            return self._control(link, peer, now, "Takeoff", False, c.takeoff), None
        if cmd in (LAND, RTL):
            fn, what = (c.land, "Landing") if cmd == LAND else (c.rtl, "Return")
            return self._control(link, peer, now, what, True, fn), None
        if cmd == MISSION_START:
            first = int(p[1])
            if 0 <= first < len(self.ap.mission.items):
                self.ap.mission.current = self.ap.mission.items[first].seq
            return self._control(link, peer, now, "Mission start", True, c.mission_start), None
        if cmd == REPOSITION:
            return self._goto(link, peer, now, p, p.given(5), p.given(6), relative=False), None
        if cmd == CHANGE_SPEED:
            return self._speed(link, peer, now, p), None
        return self._message_command(link, cmd, p, now)

    def _mode(self, link: str, peer: Peer, now: float, base: int, custom: int | None
              ) -> Outcome:
        fl = self.ap.flavour
        nav = fl.nav_of(custom) if custom is not None else None
        if not base & m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED or custom is None or nav is None:
            name = fl.name_of(custom) if custom is not None else f"base mode {base}"
            out = Outcome(int(m.MAV_RESULT_UNSUPPORTED), f"{name}: mode not simulated",
                          int(m.MAV_SEVERITY_WARNING))
            statustext(self.outbox, out.text, out.severity)
            return out
        hands_back = (link == GCS and nav is Nav.OFFBOARD
                      and self.ap.signal.live(OFFBOARD, now, self.ap.params["COM_OF_LOSS_T"]))
        return self._control(link, peer, now, f"{fl.names[nav]} mode", True,
                             lambda cc: self.ap.commander.request(nav, cc), hands_back=hands_back)

    def _takeoff_alt(self, param7: float | None) -> float:
        """The take-off altitude above home: ArduPilot's param7 is relative, PX4's AMSL."""
        if param7 is not None and not self.ap.flavour.guided:
            param7 -= self.ap.nav.frame.home_amsl_m
        if param7 is None or not param7 > 0:
            return self.ap.params["MIS_TAKEOFF_ALT"]
        return param7

    def _goto(self, link: str, peer: Peer, now: float, p: CommandParams, lat: float | None,
              lon: float | None, relative: bool) -> Outcome:
        """DO_REPOSITION: a point (NaN / unset keeps a coordinate), altitude param7 (AMSL unless
        ``relative``), ground speed param1, mode change flag param2."""
        ap = self.ap
        here = ap.nav.here()
        east, north = here.east, here.north
        if lat is not None or lon is not None:
            origin = ap.nav.frame.origin
            h_lat, h_lon = mav.to_geodetic(here.east, here.north, origin)
            east, north = mav.to_local(h_lat if lat is None else lat,
                                       h_lon if lon is None else lon, origin)
        alt = p.given(7)
        if alt is not None and not relative:
            alt -= ap.nav.frame.home_amsl_m
        if not ap.mission.bounds.within(east, north):
            statustext(self.outbox, "Reposition denied: beyond the vehicle's range",
                       m.MAV_SEVERITY_WARNING)
            return Outcome(int(m.MAV_RESULT_DENIED))
        change_mode = int(p[2]) & int(m.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE) != 0
        return self._control(link, peer, now, "Reposition", True,
                             lambda cc: ap.commander.reposition(cc, change_mode),
                             then=lambda: ap.nav.reposition(east, north, alt, p.given(1)))

    def _speed(self, link: str, peer: Peer, now: float, p: CommandParams) -> Outcome:
        speed = p.given(2)
        if speed is None or not speed > 0:
            return Outcome(int(m.MAV_RESULT_DENIED))

        def change(_c: Conditions) -> Outcome:
            self.ap.nav.speed = min(float(speed), self.ap.params["MPC_XY_VEL_MAX"])
            return Outcome(int(m.MAV_RESULT_ACCEPTED))

        return self._control(link, peer, now, "Speed change", False, change)

    def _message_command(self, link: str, cmd: int, p: CommandParams, now: float
                         ) -> tuple[Outcome, Callable[[], None] | None]:
        """Message requests and stream rates (no control needed)."""
        msg_id = {int(m.MAV_CMD_REQUEST_MESSAGE): int(p[1]),
                  int(m.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES):
                      int(m.MAVLINK_MSG_ID_AUTOPILOT_VERSION),
                  int(m.MAV_CMD_GET_HOME_POSITION): int(m.MAVLINK_MSG_ID_HOME_POSITION)}.get(cmd)
        if msg_id is not None:
            fn = self.messages(link, msg_id)
            result = m.MAV_RESULT_ACCEPTED if fn is not None else m.MAV_RESULT_UNSUPPORTED
            return Outcome(int(result)), fn
        if cmd == m.MAV_CMD_SET_MESSAGE_INTERVAL:
            return Outcome(self.schedule.set_interval(int(p[1]), p[2], now)), None
        if cmd == m.MAV_CMD_GET_MESSAGE_INTERVAL:
            target = int(p[1])
            return Outcome(int(m.MAV_RESULT_ACCEPTED)), lambda: self.outbox.send(
                link, "message_interval", target, self.schedule.interval_us(target))
        return Outcome(int(m.MAV_RESULT_UNSUPPORTED)), None

"""The simulated vehicle's MAVLink side: its links, message handlers, modes and telemetry.

One :class:`Endpoint` per simulated vehicle (a vehicle host runs several,
services/uavsim/__main__.py): it reads its links (every datagram parsed on
its own, judged by when it arrived: services/uavsim/arrivals.py), answers
parameters (services/uavsim/params.py), commands (commands.py), the
mission protocol (mission.py), takes setpoints only from the link and peer
in control, flies Eq. (1) on either clock (clock.py, vehicle.py), runs the
offboard-loss failsafe (failsafe.py) and streams telemetry (intervals.py).
"""

from __future__ import annotations

import logging
import select
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from services.common import mav, mavlink_codec, rejections
from services.common.log import fields

from . import arrivals, params, telemetry
from . import clock as vclock
from . import flavour as fl
from .commands import Commands
from .failsafe import check_offboard
from .intervals import Schedule
from .mission import MissionServer
from .params import PARAMS, Param
from .setpoint import normalised
from .stream_stats import StreamStats
from .vehicle import Vehicle

log = logging.getLogger("services.uavsim")
m = mav.mavlink

#: UDP peers a ``udpin`` link sends to (those that sent a usable frame), the least recently
#: heard dropped first; a peer silent for CLIENT_TIMEOUT_S is dropped (one is always kept).
MAX_CLIENTS = 8
#: datagrams read from one link before the loop sends telemetry again (a flood cannot starve it)
MAX_DATAGRAMS_PER_POLL = 200
CLIENT_TIMEOUT_S = 10.0
#: Messages a ground station sends that the vehicle ignores without counting them as bad
#: input (housekeeping of MAVProxy and QGroundControl).
GCS_CHATTER = frozenset({
    "REQUEST_DATA_STREAM", "SYSTEM_TIME", "TIMESYNC", "PING", "MANUAL_CONTROL",
    "RC_CHANNELS_OVERRIDE", "PARAM_EXT_REQUEST_LIST", "PARAM_EXT_REQUEST_READ",
    "FILE_TRANSFER_PROTOCOL", "LOG_REQUEST_LIST", "COMMAND_ACK", "STATUSTEXT",
    "GPS_RTCM_DATA", "GPS_INJECT_DATA", "RADIO_STATUS",
})
#: Messages the vehicle acts on (besides the mission protocol, services/uavsim/mission.py).
HANDLED = frozenset({
    "HEARTBEAT", "SET_POSITION_TARGET_LOCAL_NED", "PARAM_REQUEST_LIST", "PARAM_REQUEST_READ",
    "PARAM_SET", "COMMAND_LONG", "COMMAND_INT", "SET_MODE",
    "MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_REQUEST_LIST",
    "MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT",
    "MISSION_ACK",
})


#: Messages a keyed ground-station link refuses unsigned (control, mission upload, parameters).
SIGNED_ONLY = frozenset({"SET_POSITION_TARGET_LOCAL_NED", "COMMAND_LONG", "COMMAND_INT",
                         "SET_MODE", "PARAM_SET", "MISSION_COUNT", "MISSION_ITEM_INT",
                         "MISSION_ITEM", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT"})


@dataclass(frozen=True)
class VehicleSetup:
    """What a vehicle is told at start: its identity, frame, failsafe and clock."""

    sysid: int  #: MAVLink system id (component 1)
    altitude_m: float  #: the fixed flight altitude (SIM_ALT_M)
    home: tuple[float, float]  #: deg lat, lon of the local frame's origin
    offboard_loss_s: float  #: hold after this long without setpoints (COM_OF_LOSS_T)
    area_size_m: float = 1000.0  #: mission waypoints must lie in [0, area]²
    flavour: fl.Flavour = fl.ARDUPILOT  #: the autopilot it claims to be
    clock: str = vclock.LOCKSTEP  #: lockstep or realtime (services/uavsim/clock.py)
    speed_factor: float = 1.0  #: realtime: simulated s per wall s


class Endpoint:
    """The vehicle's MAVLink side: links, message handlers, modes, periodic telemetry."""

    def __init__(self, vehicle: Vehicle, links: dict[str, Any], setup: VehicleSetup,
                 tlog: mav.Tlog | None = None):
        sysid, altitude_m, home = setup.sysid, setup.altitude_m, setup.home
        offboard_loss_s, area_size_m, flavour = (setup.offboard_loss_s, setup.area_size_m,
                                                 setup.flavour)
        clock, speed_factor = setup.clock, setup.speed_factor
        self.setup = setup
        self.vehicle = vehicle
        self.flavour = flavour
        self.realtime = (vclock.RealtimeClock(speed_factor, int(vehicle.dyn.dt_s * 1000))
                         if clock == vclock.REALTIME else None)
        self.target: Any = None  # real time: the newest setpoint, flown every ΔT
        self.schedule = Schedule(time.monotonic())
        self.links = links
        for conn in links.values():
            if isinstance(getattr(conn, "port", None), socket.socket):
                arrivals.enable(conn.port)
        self.tlog = tlog
        self.send = {name: mav.Sender(conn, tlog) for name, conn in links.items()}
        self.sysid = sysid
        self.origin = home
        self.params: dict[str, Param] = {
            name: Param(default, low, high, doc) for name, (default, low, high, doc)
            in PARAMS.items()}
        self.params["MAV_SYS_ID"].value = float(sysid)
        self.params["COM_OF_LOSS_T"].value = float(offboard_loss_s)
        self.params["SIM_ALT_M"].value = float(altitude_m)
        self.params["SIM_KP"].value = float(vehicle.kp)
        self.params["BAT_CAP_NS"].value = float(vehicle.capacity_ns)
        self.mode = fl.HOLD
        self.armed = False
        self.airborne = False
        self.failsafe = False
        self.failsafe_since = 0.0
        self.last_setpoint = 0.0
        self.stream_since = 0.0
        self.stream_stats = StreamStats()  # the setpoint stream as this vehicle saw it
        self.ignored_setpoints = 0
        self.rejected_seen = 0
        self.last_reject_note = 0.0
        self.peers: set[tuple[str, int, int]] = set()
        #: who may steer: the link in control ("offboard" until a ground station takes over
        #: with a mode command) and the peer (address, sysid, compid) streaming on it
        self.control_link = "offboard"
        self.controller: tuple[Any, int, int] | None = None
        self.controller_heard = 0.0
        self.addr: Any = None  # the address of the datagram being handled
        self.rx_time: float | None = None  # when it arrived (monotonic s), if the kernel said
        #: the last setpoint checked and accepted ((link, peer, payload), target): its repeats
        #: (the ≥ 10 Hz stream) are not decoded and checked again; a parameter change clears it
        self.repeat: tuple[Any, Any] | None = None
        self.fault = ""  # a storage fault to report (STATUSTEXT) from the loop
        self.commands = Commands(self)
        self.home_local = (float(vehicle.state[0]), float(vehicle.state[1]))
        self.area_size_m = area_size_m
        self.mission = MissionServer(self.send, home, area_size_m, on_change=self.mission_changed,
                                     on_reject=self.reject,
                                     empty_upload_clears=flavour is fl.ARDUPILOT)

    # -- helpers ----------------------------------------------------------------------------------
    def p(self, name: str) -> float:
        return self.params[name].value

    @property
    def altitude_m(self) -> float:
        return self.p("SIM_ALT_M") if self.airborne else 0.0

    def broadcast(self, name: str, *args: Any) -> None:
        """Send on every link; the tlog gets the frame once."""
        for k, send in enumerate(self.send.values()):
            send.message(getattr(send.mav, f"{name}_encode")(*args), log=k == 0)

    def base_mode(self) -> int:
        base = m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | m.MAV_MODE_FLAG_STABILIZE_ENABLED
        if self.mode == fl.OFFBOARD:
            base |= m.MAV_MODE_FLAG_GUIDED_ENABLED
        if self.armed:
            base |= m.MAV_MODE_FLAG_SAFETY_ARMED
        return int(base)

    def mode_name(self, mode: str | None = None) -> str:
        return self.flavour.name_of(self.flavour.custom_mode(mode or self.mode))

    def set_mode(self, mode: str, why: str) -> None:
        if mode != self.mode:
            self.mode = mode
            if mode == fl.HOLD:
                self.target = None
            log.info("mode", extra=fields(mode=self.mode_name(), why=why))
            self.statustext(f"{self.mode_name()}: {why}")
            self.heartbeat()

    # -- outgoing -----------------------------------------------------------------------------
    def heartbeat(self) -> None:
        state = m.MAV_STATE_ACTIVE if self.armed else m.MAV_STATE_STANDBY
        self.broadcast("heartbeat", m.MAV_TYPE_QUADROTOR, self.flavour.autopilot,
                       self.base_mode(), self.flavour.custom_mode(self.mode), state)

    def statustext(self, text: str, severity: int = m.MAV_SEVERITY_INFO) -> None:
        self.broadcast("statustext", severity, text.encode()[:50])

    def param_value(self, link: str | None, name: str) -> None:
        names = list(self.params)
        args = (name.encode(), self.params[name].value, m.MAV_PARAM_TYPE_REAL32, len(names),
                names.index(name))
        if link is None:
            self.broadcast("param_value", *args)
        else:
            self.send[link]("param_value", *args)

    def set_param(self, name: str, value: float) -> None:
        """Change a parameter internally (read-only ones too) and announce it on every link."""
        self.params[name].value = float(value)
        self.param_value(None, name)

    # -- incoming -----------------------------------------------------------------------------
    def reject(self, link: str, err: rejections.CodecError, what: str = "mavlink") -> None:
        """Count and log (rate-limited) a rejected MAVLink input under ``mavlink/<link>``."""
        rejections.rejected(what, err, log, key=f"mavlink/{link}")

    def bad_frame(self, link: str, msg: Any) -> rejections.CodecError:
        """The rejection for a BAD_DATA frame (an unsigned one is also counted as such)."""
        why = str(getattr(msg, "reason", ""))
        reason = mavlink_codec.mavlink_frame_reason(why)
        if reason is rejections.Reason.UNSIGNED:
            self.count_unsigned(link)
        return rejections.invalid(f"bad frame on {link}: {why}", reason)

    def receive(self, link: str) -> None:
        """Read every waiting datagram of ``link`` and handle its frames (never raises).

        A datagram is parsed on its own (a truncated frame never swallows the
        next datagram's bytes); at most one framing problem is counted per
        datagram. Only a peer that sent a usable frame becomes a client that
        telemetry goes to.
        """
        conn = self.links[link]
        port = getattr(conn, "port", None)
        if not isinstance(port, socket.socket) or not getattr(conn, "udp_server", False):
            while (msg := conn.recv_msg()) is not None:  # not a udpin link: pymavlink reads
                self.handle(link, msg)
            return
        for _ in range(MAX_DATAGRAMS_PER_POLL):  # then telemetry and the failsafe get a turn
            try:
                data, addr, self.rx_time = arrivals.recv(port)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as err:  # e.g. ICMP port unreachable reported on the socket
                log.debug("recv failed", extra=fields(link=link, error=str(err)))
                return
            try:
                self.addr = addr
                if self.datagram(link, conn, data):
                    self.add_client(conn, addr)
            except Exception:  # a bug must not take the vehicle down: count it, go on
                log.exception("frame handling failed")
                self.reject(link, rejections.invalid("frame handling failed (internal error)"))
            finally:
                self.rx_time = None

    def datagram(self, link: str, conn: Any, data: bytes) -> bool:
        """Parse and handle one datagram; True if it held at least one usable frame."""
        if len(data) > mavlink_codec.MAX_MAVLINK_DATAGRAM:
            self.reject(link, rejections.invalid(
                f"datagram of {len(data)} bytes (at most {mavlink_codec.MAX_MAVLINK_DATAGRAM})",
                rejections.Reason.TOO_LARGE))
            return False
        parser = conn.mav
        parser.buf, parser.buf_index = bytearray(), 0
        parser.expected_length = mav.mavlink.HEADER_LEN_V1 + 2
        framing: rejections.CodecError | None = None
        usable = False
        msgs = parser.parse_buffer(data) or []
        if parser.buf_len() > 0:
            framing = rejections.invalid(f"truncated frame: {parser.buf_len()} bytes left over",
                                         rejections.Reason.MALFORMED)
            parser.buf, parser.buf_index = bytearray(), 0
        for msg in msgs:
            kind = msg.get_type()
            if kind == "BAD_DATA":
                bad = self.bad_frame(link, msg)
                framing = framing or bad
                continue
            if kind.startswith("UNKNOWN_"):
                if framing is None:
                    framing = rejections.invalid(f"message id {kind[8:]} is not in the dialect",
                                                 rejections.Reason.UNKNOWN_MESSAGE)
                continue
            if msg.get_msgbuf()[0] == mav.mavlink.PROTOCOL_MARKER_V1 and kind != "HEARTBEAT":
                if framing is None:  # a MAVLink 1 HEARTBEAT is how a GCS finds us, then v2
                    framing = rejections.invalid(f"MAVLink 1 {kind}: this vehicle speaks MAVLink 2",
                                                 rejections.Reason.MAVLINK1)
                continue
            usable = self.handle(link, msg) or usable
        if framing is not None:
            self.reject(link, framing)
        return usable

    @staticmethod
    def add_client(conn: Any, addr: tuple[str, int]) -> None:
        """Send telemetry to ``addr`` from now on (bounded: the least recently heard goes)."""
        now = time.time()
        conn.timeout = CLIENT_TIMEOUT_S
        conn.clients.add(addr)
        conn.clients_last_alive[addr] = now
        while len(conn.clients) > MAX_CLIENTS:
            oldest = min(conn.clients, key=lambda a: conn.clients_last_alive.get(a, 0.0))
            conn.clients.discard(oldest)
            conn.clients_last_alive.pop(oldest, None)

    def handle(self, link: str, msg: Any) -> bool:
        """Act on one decoded frame; False (after counting it) if it was rejected."""
        kind = msg.get_type()
        if kind == "BAD_DATA":
            self.reject(link, self.bad_frame(link, msg))
            return False
        if self.tlog is not None:
            self.tlog.message(msg)
        if kind == "HEARTBEAT":
            self.on_heartbeat(link, msg)
            return True
        if kind in GCS_CHATTER:
            return True
        if kind not in HANDLED:
            self.reject(link, rejections.invalid(f"{kind} is not a message the vehicle accepts",
                                                 rejections.Reason.WRONG_TYPE))
            return False
        target = getattr(msg, "target_system", None)
        comp = getattr(msg, "target_component", None)
        if (target not in (None, 0, self.sysid)
                or comp not in (None, 0, mav.MAV_COMP_ID_AUTOPILOT1)):
            self.reject(link, rejections.invalid(
                f"{kind} for system {target} component {comp} (this is {self.sysid}:1)",
                rejections.Reason.WRONG_TARGET))
            return False
        # when the datagram arrived (the kernel's stamp), not when this process got to it
        now = self.rx_time if self.rx_time is not None else time.monotonic()
        handled = self.mission.handle(link, msg, now)
        if handled is not None:
            return handled
        return self.dispatch(link, msg, now)

    def on_heartbeat(self, link: str, msg: Any) -> None:
        """A new peer is logged and answered at once: it waits for our heartbeat to start."""
        peer = (link, msg.get_srcSystem(), msg.get_srcComponent())
        if peer in self.peers:
            return
        if len(self.peers) >= 4 * MAX_CLIENTS:
            self.peers.clear()  # bounded: only used to answer a new peer at once
        self.peers.add(peer)
        log.info("peer", extra=fields(link=link, sysid=peer[1], compid=peer[2],
                                      mav_type=msg.type))
        self.heartbeat()

    def dispatch(self, link: str, msg: Any, now: float) -> bool:
        """A frame addressed to this vehicle and not the mission protocol's, by its type."""
        kind = msg.get_type()
        if kind == "SET_POSITION_TARGET_LOCAL_NED":
            return self.on_setpoint(link, msg, now)
        elif kind == "PARAM_REQUEST_LIST":
            for name in self.params:
                self.param_value(link, name)
        elif kind == "PARAM_REQUEST_READ":
            self.on_param_request_read(link, msg)
        elif kind == "PARAM_SET":
            return params.param_set(self, link, msg)
        elif kind == "COMMAND_LONG":
            return self.commands.on_command(link, msg)
        elif kind == "COMMAND_INT":
            return self.on_command_int(link, msg)
        elif kind == "SET_MODE":
            self.commands.on_set_mode(link, msg)
        return True

    def on_param_request_read(self, link: str, msg: Any) -> None:
        """PARAM_VALUE for the parameter named (index < 0) or at the index; unknown: nothing."""
        names = list(self.params)
        pid = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
        name = pid.rstrip("\x00") if msg.param_index < 0 else (
            names[msg.param_index] if msg.param_index < len(names) else "")
        if name in self.params:
            self.param_value(link, name)

    def on_command_int(self, link: str, msg: Any) -> bool:
        """COMMAND_INT: checked, then acknowledged UNSUPPORTED (DENIED if a field is bad)."""
        result = m.MAV_RESULT_UNSUPPORTED
        try:
            mavlink_codec.check_finite_fields(
                msg, ("param1", "param2", "param3", "param4", "z"), "COMMAND_INT")
        except rejections.CodecError as err:
            self.reject(link, err)
            result = m.MAV_RESULT_DENIED
        self.send[link]("command_ack", msg.command, result, 0, 0,
                        msg.get_srcSystem(), msg.get_srcComponent())
        return result != m.MAV_RESULT_DENIED

    def may_control(self, link: str, msg: Any, now: float) -> bool:
        """Control only from the link and peer in control; False after counting a refusal.

        A mode command (DO_SET_MODE, SET_MODE) from the ground-station link is its
        explicit take-over: the ground station is then in control until it
        commands offboard mode (the companion's setpoints are refused meanwhile).
        On the link in control, the first peer streams; another peer is refused
        until the first has been silent for COM_OF_LOSS_T (one controller at a time).
        """
        kind = msg.get_type()
        peer = (self.addr, msg.get_srcSystem(), msg.get_srcComponent())
        mode_cmd = kind == "SET_MODE" or (kind == "COMMAND_LONG"
                                          and int(msg.command) == m.MAV_CMD_DO_SET_MODE)
        if link != self.control_link:
            if link == "gcs" and mode_cmd:
                log.warning("ground station takes control", extra=fields(peer=str(peer)))
                self.statustext("ground station in control", m.MAV_SEVERITY_WARNING)
                self.control_link, self.controller, self.controller_heard = link, peer, now
                return True
            return self.refuse(link, f"{kind} from the {link} link: the {self.control_link} "
                                     f"link is in control")
        silent = now - self.controller_heard > self.p("COM_OF_LOSS_T")
        if self.controller is None or self.controller == peer or silent:
            if self.controller != peer and self.controller is not None:
                log.info("controller changed", extra=fields(link=link, peer=str(peer)))
            self.controller, self.controller_heard = peer, now
            if link == "gcs" and mode_cmd and self.commands.hands_back(msg):
                self.control_link, self.controller = "offboard", None
                log.info("ground station hands control back to the offboard link")
            return True
        return self.refuse(link, f"{kind} from a second peer {peer[1]}:{peer[2]} while "
                                 f"{self.controller[1]}:{self.controller[2]} is in control")

    def refuse(self, link: str, why: str) -> bool:
        self.reject(link, rejections.invalid(why, rejections.Reason.WRONG_TARGET), "control")
        self.set_param("CTL_REFUSED", self.p("CTL_REFUSED") + 1)
        return False

    def count_unsigned(self, link: str) -> None:
        """An unsigned or wrongly signed frame on a signed link: SIG_REJECTED, a STATUSTEXT.

        The caller counts the rejection itself (reason ``unsigned``).
        """
        total = sum(mav.rejected_frames(conn) for conn in self.links.values())
        if total != self.rejected_seen:
            self.rejected_seen = total
            self.params["SIG_REJECTED"].value = float(total)
            now = time.monotonic()
            if now - self.last_reject_note > 2.0:
                self.last_reject_note = now
                self.statustext(f"signing: {total} frames rejected", m.MAV_SEVERITY_WARNING)

    def on_setpoint(self, link: str, msg: Any, now: float) -> bool:
        """A setpoint that is not finite, far outside the area or due too far ahead is refused:
        the vehicle keeps its last target (or holds) and the stream is not kept alive."""
        peer = (self.addr, msg.get_srcSystem(), msg.get_srcComponent())
        key = (link, peer, bytes(msg.get_payload()))
        if (self.repeat is not None and self.repeat[0] == key and link == self.control_link
                and peer == self.controller):
            target = self.repeat[1]  # the stream's repeat of a setpoint already checked
            self.controller_heard = now
        else:
            target = self.check_setpoint(link, msg, now)
            if target is None:
                return False
            self.repeat = (key, target)
        if now - self.last_setpoint > self.p("COM_OF_LOSS_T"):
            self.stream_since = now  # a new stream starts
        self.stream_stats.setpoint(now, self.mode == fl.OFFBOARD or self.failsafe)
        self.last_setpoint = now
        if not (self.mode == fl.OFFBOARD and self.armed and self.airborne):
            self.ignored_setpoints += 1
            return True
        if self.realtime is not None:
            self.target = target  # flown on the vehicle's own clock (fly_realtime)
        elif self.vehicle.apply(target, int(msg.time_boot_ms)):
            self.after_step()
        return True

    def check_setpoint(self, link: str, msg: Any, now: float) -> Any:
        """The setpoint's target, or None after counting why it was refused (too far ahead,
        not valid, not from the link and peer in control)."""
        lead = (None if self.realtime is not None  # real time: the client's stamp is not a clock
                else int(msg.time_boot_ms) - self.vehicle.time_ms)
        if lead is not None and lead > self.p("COM_SP_LEAD_S") * 1000:  # never moves the clock
            self.reject(link, rejections.invalid(
                f"setpoint due {lead / 1000:.6g} s after the vehicle's clock (more than one step,"
                f" COM_SP_LEAD_S = {self.p('COM_SP_LEAD_S'):g} s)", rejections.Reason.OUT_OF_RANGE),
                "setpoint")
            return None
        try:
            target = mavlink_codec.setpoint_from_mavlink(normalised(msg), self.area_size_m, lead)
        except rejections.CodecError as err:
            self.reject(link, err, "setpoint")
            return None
        if not self.may_control(link, msg, now):  # checked once the setpoint itself is valid
            return None
        return target

    def fly_realtime(self, now: float) -> None:
        """Real-time clock: one Eq. (1) step per ΔT towards the newest setpoint (offboard)."""
        assert self.realtime is not None
        for due_ms in self.realtime.due_steps(now):
            if (self.target is not None and self.mode == fl.OFFBOARD and self.armed
                    and self.airborne):
                self.vehicle.apply(self.target, due_ms)
                self.after_step()
            else:
                self.vehicle.time_ms = due_ms  # the clock runs whether or not it flies

    def after_step(self) -> None:
        telemetry.telemetry(self)
        x = self.vehicle.state
        log.debug("step", extra=fields(time_ms=self.vehicle.time_ms, east_m=float(x[0]),
                                       north_m=float(x[1])))
        reached = self.mission.progress(float(x[0]), float(x[1]), self.p("MIS_ACC_RAD"))
        for seq in reached:
            self.broadcast("mission_item_reached", seq)
        if reached:
            self.mission.send_current()

    def mission_changed(self) -> None:
        self.set_param("MIS_ID", float(self.mission.version))
        waypoints = sum(it.is_waypoint() for it in self.mission.items)
        self.statustext(f"mission {self.mission.version}: {waypoints} waypoints")
        self.mission.send_current()

    # -- commands (services/uavsim/commands.py) -------------------------------------------------
    def stream_live(self, now: float) -> bool:
        return bool(self.last_setpoint) and now - self.last_setpoint <= self.p("COM_OF_LOSS_T")

    def end_failsafe(self, now: float) -> None:
        """The offboard-loss failsafe is over (the stream is back, or a mode was commanded)."""
        if self.failsafe:
            self.failsafe = False
            self.stream_stats.failsafe_s += now - self.failsafe_since

    # -- loop -----------------------------------------------------------------------------------
    def run(self, stop: threading.Event,
            on_tick: Callable[[float], None] | None = None) -> None:
        """Serve the links until ``stop``; ``on_tick(now)`` after every pass of the loop."""
        self.statustext("dualpilot uavsim ready")
        fds = {conn.fd: name for name, conn in self.links.items()}
        while not stop.is_set():
            now = time.monotonic()
            if self.realtime is not None:
                self.fly_realtime(now)
            for msg_id in self.schedule.due(now):
                telemetry.stream(self, msg_id)
            self.mission.poll(now)
            if self.fault:
                self.statustext(self.fault[:50], m.MAV_SEVERITY_ERROR)
                self.fault = ""
            timeout = min(self.schedule.wait_s(now), 0.05)
            if self.realtime is not None:
                timeout = min(timeout, self.realtime.wall_until_next(now))
            ready, _, _ = select.select(list(fds), [], [], max(0.0, timeout))
            for fd in ready:
                self.receive(fds[fd])
            # after the reads: a vehicle kept off the CPU finds its queued setpoints first
            check_offboard(self, time.monotonic())
            if on_tick is not None:
                on_tick(time.monotonic())

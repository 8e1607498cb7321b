"""uavsim: a simulated vehicle that speaks MAVLink like an autopilot and flies Eq. (1).

Links (pymavlink, MAVLink 2, system ``--sysid``, component 1), like PX4 SITL:
offboard (``--mavlink-url``, default ``udpin:0.0.0.0:14540``), where the
supervisor streams SET_POSITION_TARGET_LOCAL_NED, optionally signed; ground
station (``--gcs-url``, default ``udpin:0.0.0.0:14550``) for MAVProxy or
QGroundControl. Both get HEARTBEAT and telemetry and answer parameters
(:data:`PARAMS`), COMMAND_LONG and the mission protocol; ``--tlog`` records
them in MAVProxy's ``.tlog`` format. The local frame (m east/north) has its
origin at ``--home``, the area's south-west corner; the vehicle flies at
``SIM_ALT_M`` (m). Each setpoint, stamped with the simulated time it is due,
is one ΔT step of Eq. (1), with the dynamics of the readings profile
``--profile`` (its speed limit per axis or as a norm, ``--speed-limit``).

That is the lockstep clock (``--clock lockstep``, our missions); ``--clock
realtime`` flies on the vehicle's own clock instead (services/uavsim/clock.py).
Modules: commands.py (COMMAND_LONG), failsafe.py, intervals.py (stream
rates), setpoint.py (type masks), mission.py, vehicle.py (physics).
"""

from __future__ import annotations

import logging
import math
import os
import select
import socket
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from dualpilot.readings import PROFILES, get_profile
from services.common import bus, codec, fleet, mav
from services.common import cli as common_cli
from services.common.log import fields

from . import arrivals
from . import clock as vclock
from . import flavour as fl
from .commands import Commands
from .failsafe import check_offboard
from .intervals import Schedule
from .mission import MissionServer
from .setpoint import normalised
from .storage import open_tlog
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
#: wall s between writes of --stream-stats
STATS_EVERY_S = 5.0
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


@dataclass
class Param:
    """A vehicle parameter: value, allowed range (None: read-only) and what it sets."""

    value: float
    low: float | None = None
    high: float | None = None
    doc: str = ""


#: name → (default, low, high, meaning); low/high None = read-only. Defaults set by flags win.
PARAMS: dict[str, tuple[float, float | None, float | None, str]] = {
    "MAV_SYS_ID": (1.0, None, None, "system id (--sysid)"),
    "COM_OF_LOSS_T": (1.0, 0.1, 60.0, "s without a setpoint before the failsafe hold (PX4)"),
    "COM_OF_RSM_T": (0.5, 0.0, 10.0, "s of live setpoint stream before it resumes control"),
    "MPC_XY_VEL_MAX": (15.0, 0.1, 15.0, "speed limit per axis, or of |v| with --speed-limit "
                                        "norm, m/s (paper: 15)"),
    "SIM_U_MAX_N": (7.5, 0.1, 7.5, "force limit per axis, N (paper: 7.5)"),
    "SIM_KP": (0.5, 0.0, 1.0, "position gain of the tracking controller"),
    "SIM_ALT_M": (50.0, 1.0, 500.0, "flight altitude above home, m"),
    "BAT_CAP_NS": (1000.0, 1.0, 1e6, "battery capacity as impulse Σ‖u‖ΔT, N·s"),
    "MIS_ACC_RAD": (15.0, 1.0, 200.0, "a mission waypoint counts as reached within this, m"),
    "MIS_ID": (0.0, None, None, "mission version, +1 on every upload or clear"),
    "SIG_REJECTED": (0.0, None, None, "unsigned or wrongly signed frames ignored (offboard)"),
    "COM_SP_LEAD_S": (7.0, 1.0, 600.0, "a setpoint due later than this after the vehicle's "
                                       "clock is refused (one step: 5 dT planning + dT, +0.5)"),
    "CTL_REFUSED": (0.0, None, None, "control messages refused: not from the link and peer "
                                     "in control"),
    "SIM_FAILSAFES": (0.0, None, None, "offboard-loss failsafes so far (services/uavsim/"
                                       "failsafe.py)"),
}
#: Messages a keyed ground-station link refuses unsigned (control, mission upload, parameters).
SIGNED_ONLY = frozenset({"SET_POSITION_TARGET_LOCAL_NED", "COMMAND_LONG", "COMMAND_INT",
                         "SET_MODE", "PARAM_SET", "MISSION_COUNT", "MISSION_ITEM_INT",
                         "MISSION_ITEM", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT"})


class Endpoint:
    """The vehicle's MAVLink side: links, message handlers, modes, periodic telemetry."""

    def __init__(self, vehicle: Vehicle, links: dict[str, Any], sysid: int, altitude_m: float,
                 home: tuple[float, float], offboard_loss_s: float, area_size_m: float = 1000.0,
                 tlog: mav.Tlog | None = None, flavour: fl.Flavour = fl.ARDUPILOT,
                 clock: str = vclock.LOCKSTEP, speed_factor: float = 1.0):
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

    def telemetry(self, only: int | None = None) -> None:
        """LOCAL_POSITION_NED, GLOBAL_POSITION_INT and ATTITUDE (or ``only`` that one)."""
        x = self.vehicle.state
        alt = self.altitude_m
        n, e, d, vn, ve, vd = codec.state_to_ned(x, alt)
        lat, lon = mav.to_geodetic(float(x[0]), float(x[1]), self.origin)
        t_ms = self.vehicle.time_ms
        hdg = int(math.degrees(math.atan2(ve, vn)) % 360 * 100) if (vn or ve) else 65535
        roll, pitch, yaw = self.vehicle.attitude()
        if only in (None, m.MAVLINK_MSG_ID_LOCAL_POSITION_NED):
            self.broadcast("local_position_ned", t_ms, n, e, d, vn, ve, vd)
        if only in (None, m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT):
            self.broadcast("global_position_int", t_ms, int(lat * 1e7), int(lon * 1e7),
                           int(alt * 1000), int(alt * 1000), int(vn * 100), int(ve * 100),
                           int(vd * 100), hdg)
        if only in (None, m.MAVLINK_MSG_ID_ATTITUDE):
            self.broadcast("attitude", t_ms, roll, pitch, yaw, 0.0, 0.0, 0.0)

    def slow_telemetry(self, only: int | None = None) -> None:
        """SYS_STATUS, GPS_RAW_INT, EXTENDED_SYS_STATE, MISSION_CURRENT (or ``only`` one)."""
        v = self.vehicle
        if only in (None, m.MAVLINK_MSG_ID_SYS_STATUS):
            sensors = (m.MAV_SYS_STATUS_SENSOR_3D_GYRO | m.MAV_SYS_STATUS_SENSOR_3D_ACCEL
                       | m.MAV_SYS_STATUS_SENSOR_3D_MAG | m.MAV_SYS_STATUS_SENSOR_GPS
                       | m.MAV_SYS_STATUS_SENSOR_BATTERY | m.MAV_SYS_STATUS_PREARM_CHECK)
            # the pre-arm check passes while there is charge left (arming's only condition)
            healthy = sensors if v.battery_fraction > 0 else (
                sensors & ~m.MAV_SYS_STATUS_PREARM_CHECK)
            self.broadcast("sys_status", sensors, sensors, healthy, 100,
                           int(v.voltage_v * 1000), -1, int(round(v.battery_fraction * 100)), 0,
                           min(int(self.p("SIG_REJECTED")), 65535), 0, 0, 0, 0)
        if only in (None, m.MAVLINK_MSG_ID_GPS_RAW_INT):
            x = v.state
            lat, lon = mav.to_geodetic(float(x[0]), float(x[1]), self.origin)
            speed = math.hypot(float(x[2]), float(x[3]))
            cog = (int(math.degrees(math.atan2(float(x[2]), float(x[3]))) % 360 * 100)
                   if speed else 0)
            self.broadcast("gps_raw_int", v.time_ms * 1000, m.GPS_FIX_TYPE_3D_FIX,
                           int(lat * 1e7), int(lon * 1e7), int(self.altitude_m * 1000), 80, 120,
                           int(speed * 100), cog, 14)
        if only in (None, m.MAVLINK_MSG_ID_EXTENDED_SYS_STATE):
            landed = (m.MAV_LANDED_STATE_IN_AIR if self.airborne
                      else m.MAV_LANDED_STATE_ON_GROUND)
            self.broadcast("extended_sys_state", m.MAV_VTOL_STATE_UNDEFINED, landed)
        if only in (None, m.MAVLINK_MSG_ID_MISSION_CURRENT):
            self.mission.send_current()

    def stream(self, msg_id: int) -> None:
        """Send one scheduled telemetry message (services/uavsim/intervals.py) on every link."""
        if msg_id == m.MAVLINK_MSG_ID_HEARTBEAT:
            self.heartbeat()
        elif msg_id in (m.MAVLINK_MSG_ID_HOME_POSITION, m.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN):
            self.home_position(only=msg_id)
        elif msg_id in (m.MAVLINK_MSG_ID_LOCAL_POSITION_NED, m.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                        m.MAVLINK_MSG_ID_ATTITUDE):
            self.telemetry(only=msg_id)
        else:
            self.slow_telemetry(only=msg_id)

    def home_position(self, link: str | None = None, only: int | None = None) -> None:
        lat, lon = mav.to_geodetic(*self.home_local, self.origin)
        args = (int(lat * 1e7), int(lon * 1e7), 0, self.home_local[1], self.home_local[0], 0.0,
                [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, self.vehicle.time_ms * 1000)
        origin = (int(self.origin[0] * 1e7), int(self.origin[1] * 1e7), 0,
                  self.vehicle.time_ms * 1000)
        if link is None:
            if only in (None, m.MAVLINK_MSG_ID_HOME_POSITION):
                self.broadcast("home_position", *args)
            if only in (None, m.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN):
                self.broadcast("gps_global_origin", *origin)
        else:
            self.send[link]("home_position", *args)
            self.send[link]("gps_global_origin", *origin)

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
    def reject(self, link: str, err: codec.CodecError, what: str = "mavlink") -> None:
        """Count and log (rate-limited) a rejected MAVLink input under ``mavlink/<link>``."""
        codec.rejected(what, err, log, key=f"mavlink/{link}")

    def bad_frame(self, link: str, msg: Any) -> codec.CodecError:
        """The rejection for a BAD_DATA frame (an unsigned one is also counted as such)."""
        why = str(getattr(msg, "reason", ""))
        reason = codec.mavlink_frame_reason(why)
        if reason is codec.Reason.UNSIGNED:
            self.count_unsigned(link)
        return codec.invalid(f"bad frame on {link}: {why}", reason)

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
                self.reject(link, codec.invalid("frame handling failed (internal error)"))
            finally:
                self.rx_time = None

    def datagram(self, link: str, conn: Any, data: bytes) -> bool:
        """Parse and handle one datagram; True if it held at least one usable frame."""
        if len(data) > codec.MAX_MAVLINK_DATAGRAM:
            self.reject(link, codec.invalid(
                f"datagram of {len(data)} bytes (at most {codec.MAX_MAVLINK_DATAGRAM})",
                codec.Reason.TOO_LARGE))
            return False
        parser = conn.mav
        parser.buf, parser.buf_index = bytearray(), 0
        parser.expected_length = mav.mavlink.HEADER_LEN_V1 + 2
        framing: codec.CodecError | None = None
        usable = False
        msgs = parser.parse_buffer(data) or []
        if parser.buf_len() > 0:
            framing = codec.invalid(f"truncated frame: {parser.buf_len()} bytes left over",
                                    codec.Reason.MALFORMED)
            parser.buf, parser.buf_index = bytearray(), 0
        for msg in msgs:
            kind = msg.get_type()
            if kind == "BAD_DATA":
                bad = self.bad_frame(link, msg)
                framing = framing or bad
                continue
            if kind.startswith("UNKNOWN_"):
                if framing is None:
                    framing = codec.invalid(f"message id {kind[8:]} is not in the dialect",
                                            codec.Reason.UNKNOWN_MESSAGE)
                continue
            if msg.get_msgbuf()[0] == mav.mavlink.PROTOCOL_MARKER_V1 and kind != "HEARTBEAT":
                if framing is None:  # a MAVLink 1 HEARTBEAT is how a GCS finds us, then v2
                    framing = codec.invalid(f"MAVLink 1 {kind}: this vehicle speaks MAVLink 2",
                                            codec.Reason.MAVLINK1)
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
            peer = (link, msg.get_srcSystem(), msg.get_srcComponent())
            if peer not in self.peers:
                if len(self.peers) >= 4 * MAX_CLIENTS:
                    self.peers.clear()  # bounded: only used to answer a new peer at once
                self.peers.add(peer)
                log.info("peer", extra=fields(link=link, sysid=peer[1], compid=peer[2],
                                              mav_type=msg.type))
                self.heartbeat()  # answer at once: the peer waits for us before it starts
            return True
        if kind in GCS_CHATTER:
            return True
        if kind not in HANDLED:
            self.reject(link, codec.invalid(f"{kind} is not a message the vehicle accepts",
                                            codec.Reason.WRONG_TYPE))
            return False
        target = getattr(msg, "target_system", None)
        comp = getattr(msg, "target_component", None)
        if (target not in (None, 0, self.sysid)
                or comp not in (None, 0, mav.MAV_COMP_ID_AUTOPILOT1)):
            self.reject(link, codec.invalid(
                f"{kind} for system {target} component {comp} (this is {self.sysid}:1)",
                codec.Reason.WRONG_TARGET))
            return False
        # when the datagram arrived (the kernel's stamp), not when this process got to it
        now = self.rx_time if self.rx_time is not None else time.monotonic()
        handled = self.mission.handle(link, msg, now)
        if handled is not None:
            return handled
        if kind == "SET_POSITION_TARGET_LOCAL_NED":
            return self.on_setpoint(link, msg, now)
        elif kind == "PARAM_REQUEST_LIST":
            for name in self.params:
                self.param_value(link, name)
        elif kind == "PARAM_REQUEST_READ":
            names = list(self.params)
            pid = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
            name = pid.rstrip("\x00") if msg.param_index < 0 else (
                names[msg.param_index] if msg.param_index < len(names) else "")
            if name in self.params:
                self.param_value(link, name)
        elif kind == "PARAM_SET":
            return self.on_param_set(link, msg)
        elif kind == "COMMAND_LONG":
            return self.commands.on_command(link, msg)
        elif kind == "COMMAND_INT":
            result = m.MAV_RESULT_UNSUPPORTED
            try:
                codec.check_finite_fields(msg, ("param1", "param2", "param3", "param4", "z"),
                                          "COMMAND_INT")
            except codec.CodecError as err:
                self.reject(link, err)
                result = m.MAV_RESULT_DENIED
            self.send[link]("command_ack", msg.command, result, 0, 0,
                            msg.get_srcSystem(), msg.get_srcComponent())
            return result != m.MAV_RESULT_DENIED
        elif kind == "SET_MODE":
            self.commands.on_set_mode(link, msg)
        return True

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
        self.reject(link, codec.invalid(why, codec.Reason.WRONG_TARGET), "control")
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

    def on_param_set(self, link: str, msg: Any) -> bool:
        pid = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode(
            "ascii", "replace")
        name = pid.rstrip("\x00")
        param = self.params.get(name)
        if param is None:  # unknown: no PARAM_VALUE, as PX4 (the GCS times out)
            self.reject(link, codec.invalid(f"PARAM_SET of unknown parameter {name[:16]!r}"),
                        "PARAM_SET")
            return False
        value = float(msg.param_value)
        err: codec.CodecError | None = None
        if not math.isfinite(value):
            err = codec.invalid(f"PARAM_SET {name} = {value}", codec.Reason.NOT_FINITE)
        elif param.low is None or param.high is None:
            err = codec.invalid(f"PARAM_SET {name}: read-only")
        elif not param.low <= value <= param.high:
            err = codec.invalid(f"PARAM_SET {name} = {value:g} outside [{param.low:g}, "
                                f"{param.high:g}]", codec.Reason.OUT_OF_RANGE)
        if err is not None:
            self.reject(link, err, "PARAM_SET")
            self.statustext(f"{name}: refused {value:g}", m.MAV_SEVERITY_WARNING)
            self.param_value(link, name)  # the unchanged value tells the GCS it was refused
            return False
        param.value = value
        if name == "MPC_XY_VEL_MAX":
            self.vehicle.set_limits(v_max_mps=value)
        elif name == "SIM_U_MAX_N":
            self.vehicle.set_limits(u_max_n=value)
        elif name == "SIM_KP":
            self.vehicle.kp = value
        elif name == "BAT_CAP_NS":
            self.vehicle.capacity_ns = value
        log.info("param set", extra=fields(name=name, value=value))
        self.param_value(None, name)
        return True

    def on_setpoint(self, link: str, msg: Any, now: float) -> bool:
        """A setpoint that is not finite, far outside the area or due too far ahead is refused:
        the vehicle keeps its last target (or holds) and the stream is not kept alive."""
        lead = (None if self.realtime is not None  # real time: the client's stamp is not a clock
                else int(msg.time_boot_ms) - self.vehicle.time_ms)
        if lead is not None and lead > self.p("COM_SP_LEAD_S") * 1000:  # never moves the clock
            self.reject(link, codec.invalid(
                f"setpoint due {lead / 1000:.6g} s after the vehicle's clock (more than one step,"
                f" COM_SP_LEAD_S = {self.p('COM_SP_LEAD_S'):g} s)", codec.Reason.OUT_OF_RANGE),
                "setpoint")
            return False
        try:
            target = codec.setpoint_from_mavlink(normalised(msg), self.area_size_m, lead)
        except codec.CodecError as err:
            self.reject(link, err, "setpoint")
            return False
        if not self.may_control(link, msg, now):  # checked once the setpoint itself is valid
            return False
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
        self.telemetry()
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
                self.stream(msg_id)
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


class StatsFile:
    """Writes the endpoint's stream statistics (services/uavsim/stream_stats.py) to a file every
    :data:`STATS_EVERY_S` and at exit; a write error is logged once, never fatal."""

    def __init__(self, path: str, endpoint: Endpoint):
        self.path = path
        self.endpoint = endpoint
        self.next_s = 0.0
        self.failed = False

    def tick(self, now: float) -> None:
        if now >= self.next_s:
            self.next_s = now + STATS_EVERY_S
            self.write()

    def write(self) -> None:
        ep = self.endpoint
        try:
            clock = vclock.REALTIME if ep.realtime else vclock.LOCKSTEP
            ep.stream_stats.write(self.path, clock=clock, sysid=ep.sysid,
                                  failsafe_now=ep.failsafe)
        except OSError as err:
            if not self.failed:
                self.failed = True
                codec.rejected("stream-stats", codec.invalid(f"not written: {err}"), log,
                               key="storage/stream-stats", reason="write_error")


def parse_pair(text: str, what: str) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in text.split(","))
    except ValueError as err:
        raise ValueError(f"{what} must be 'a,b', got {text!r}") from err
    if not (math.isfinite(a) and math.isfinite(b)):
        raise ValueError(f"{what} must be finite")
    return a, b


def main(argv: list[str] | None = None) -> int:
    env = common_cli.env
    p = common_cli.parser("uavsim", "Simulated vehicle: MAVLink endpoint flying Eq. (1).",
                          mavlink_default="udpin:0.0.0.0:14540")
    p.add_argument("--gcs-url", default=env("GCS_URL", "udpin:0.0.0.0:14550"),
                   help="ground-station link, empty to disable [GCS_URL]")
    p.add_argument("--sysid", type=int, default=env("MAV_SYSID", "1"), help="[MAV_SYSID]")
    p.add_argument("--start", default=env("UAV_START", "50,50"),
                   help="start position 'east,north' in m [UAV_START]")
    p.add_argument("--altitude-m", type=float, default=env("UAV_ALTITUDE_M", "50"),
                   help="fixed flight altitude (Sec. IV is 2-D) [UAV_ALTITUDE_M]")
    p.add_argument("--home", default=env("UAV_HOME", "35.1450,33.4110"),
                   help="'lat,lon' of the local frame's origin (the area's south-west corner) "
                        "[UAV_HOME]")
    p.add_argument("--area-size-m", type=float, default=env("AREA_SIZE_M", "1000"),
                   help="mission waypoints must lie in [0, area]² [AREA_SIZE_M]")
    p.add_argument("--kp", type=float, default=env("UAV_KP", "0.5"),
                   help="position gain of the controller [UAV_KP]")
    p.add_argument("--offboard-loss-s", type=float, default=env("COM_OF_LOSS_T", "1.0"),
                   help="hold after this long without setpoints (PX4 COM_OF_LOSS_T) "
                        "[COM_OF_LOSS_T]")
    p.add_argument("--signing-key-file", default=env("MAVLINK_SIGNING_KEY_FILE", ""),
                   help="sign the offboard link: 32 raw bytes, or a passphrase (sha256, as "
                        "MAVProxy) [MAVLINK_SIGNING_KEY_FILE]")
    p.add_argument("--signing-passphrase", default=env("MAVLINK_SIGNING_PASSPHRASE", ""),
                   help="sign the offboard link (sha256 of the passphrase) "
                        "[MAVLINK_SIGNING_PASSPHRASE]")
    p.add_argument("--tlog", default=env("TLOG_PATH", ""),
                   help="record the vehicle's MAVLink traffic here (.tlog); {uav} is the "
                        "vehicle id [TLOG_PATH]")
    p.add_argument("--stream-stats", default=env("STREAM_STATS_PATH", ""),
                   help="write what the vehicle saw of its setpoint stream here (JSON: gaps, "
                        "failsafes; every 5 s and at exit); {uav} is the vehicle id "
                        "[STREAM_STATS_PATH]")
    fleet.add_argument(p, "several vehicles in this process, instance k (from 0) on the "
                          "links' ports + k with system id --sysid + k, as PX4 SITL's "
                          "multi-vehicle instances")
    p.add_argument("--autopilot", choices=sorted(fl.FLAVOURS),
                   default=env("UAV_AUTOPILOT", fl.ARDUPILOT.name),
                   help="the autopilot the vehicle claims to be: HEARTBEAT autopilot and mode "
                        "numbers (ardupilot: GUIDED/LOITER; px4: OFFBOARD/AUTO.LOITER) "
                        "[UAV_AUTOPILOT]")
    p.add_argument("--clock", choices=vclock.CLOCKS, default=env("UAV_CLOCK", vclock.LOCKSTEP),
                   help="lockstep: each new setpoint stamp is one step of Eq. (1) (the stack); "
                        "realtime: the vehicle flies on its own clock at --speed-factor, as "
                        "PX4 SITL (MAVSDK and other offboard clients) [UAV_CLOCK]")
    p.add_argument("--profile", default=env("READINGS_PROFILE", "today"), choices=list(PROFILES),
                   help="the reading of the paper whose dynamics the vehicle flies (Eq. (1), "
                        "its force and speed limits; dualpilot profiles) [READINGS_PROFILE]")
    p.add_argument("--speed-limit", default=env("SPEED_LIMIT", ""),
                   help="override: axis (|v_i| <= v_max) or norm (|v| <= v_max) [SPEED_LIMIT]")
    p.add_argument("--zenoh", choices=("auto", "on", "off"), default=env("UAV_ZENOH", "auto"),
                   help="hold a liveliness token on Zenoh; auto: only when ZENOH_CONNECT or "
                        "--zenoh-connect is given (the vehicle needs no router) [UAV_ZENOH]")
    raw_argv = sys.argv[1:] if argv is None else argv
    args = p.parse_args(argv)
    use_zenoh = args.zenoh == "on" or (args.zenoh == "auto" and (
        "ZENOH_CONNECT" in os.environ
        or any(a.startswith("--zenoh-connect") for a in raw_argv)))
    try:
        settings = common_cli.settings("uavsim", args)
        start = parse_pair(args.start, "--start")
        home = parse_pair(args.home, "--home")
        if not (abs(home[0]) < 85 and abs(home[1]) <= 180):
            raise ValueError("--home must be a latitude in (-85, 85) and a longitude")
        if not 1 <= args.sysid <= 255:
            raise ValueError("--sysid must be in 1..255")
        if not (0 <= args.kp <= 1 and 0.1 <= args.offboard_loss_s <= 60):
            raise ValueError("need 0 <= --kp <= 1 and 0.1 <= --offboard-loss-s <= 60")
        if not 0 < args.area_size_m <= 1e5:
            raise ValueError("--area-size-m must be in (0, 1e5]")
        key = mav.resolve_key(args.signing_passphrase, args.signing_key_file)
        dynamics = get_profile(args.profile).with_settings(
            {"speed_limit": args.speed_limit} if args.speed_limit else {}).dynamics
        uavs = fleet.uav_ids(args.uav_ids, settings.uav_id)
        if args.sysid + len(uavs) - 1 > 255:
            raise ValueError(f"--sysid {args.sysid} + {len(uavs)} vehicles passes 255")
        for flag, path in (("--tlog", args.tlog), ("--stream-stats", args.stream_stats)):
            if path and len(uavs) > 1 and "{uav}" not in path:
                raise ValueError(f"{flag} must contain {{uav}} to serve several vehicles")
        for url in (settings.mavlink_url, args.gcs_url):
            if url:
                fleet.instance_url(url, len(uavs) - 1)  # each vehicle's port exists
        speed = settings.speed_factor
        if args.clock == vclock.REALTIME and not speed > 0:
            raise ValueError("--clock realtime needs --speed-factor > 0 (1 is real time)")
    except (ValueError, OSError) as err:
        p.error(str(err))

    def body(ctx: bus.Context) -> None:
        k = uavs.index(ctx.settings.uav_id)  # this vehicle's instance: ports and sysid + k
        uav = ctx.settings.uav_id
        sysid = args.sysid + k
        tlog_path = fleet.per_vehicle(args.tlog, uav)
        stats_path = fleet.per_vehicle(args.stream_stats, uav)
        offboard_url = fleet.instance_url(settings.mavlink_url, k)
        gcs_url = fleet.instance_url(args.gcs_url, k) if args.gcs_url else ""
        tlog = open_tlog(tlog_path) if tlog_path else None
        links = {"offboard": mav.connect(offboard_url, sysid, mav.MAV_COMP_ID_AUTOPILOT1,
                                         key=key)}
        if gcs_url:
            links["gcs"] = mav.connect(gcs_url, sysid, mav.MAV_COMP_ID_AUTOPILOT1)
            if key is not None:  # signed too: unsigned control, uploads and PARAM_SET refused
                signed_only = {getattr(m, f"MAVLINK_MSG_ID_{k}") for k in SIGNED_ONLY}
                links["gcs"].setup_signing(
                    key, sign_outgoing=True,
                    allow_unsigned_callback=lambda _mav, msg_id: msg_id not in signed_only)
        vehicle = Vehicle.at(*start, dyn=dynamics)
        vehicle.kp = args.kp
        log.info("serving MAVLink", extra=fields(
            uav=uav, sysid=sysid, offboard=offboard_url, gcs=gcs_url, signed=key is not None,
            autopilot=args.autopilot, clock=args.clock, speed_factor=speed,
            speed_limit=vehicle.dyn.speed_limit,
            zenoh=use_zenoh, east_m=start[0], north_m=start[1], tlog=tlog_path))
        endpoint = Endpoint(vehicle, links, sysid, args.altitude_m, home,
                            args.offboard_loss_s, args.area_size_m, tlog,
                            fl.FLAVOURS[args.autopilot], args.clock, speed)
        if tlog is not None:
            tlog.on_fault = lambda text: setattr(endpoint, "fault", text)
        elif tlog_path:
            endpoint.fault = "tlog not created: flying without it"
        stats = StatsFile(stats_path, endpoint) if stats_path else None
        if ctx.session is not None:
            ctx.announce()
        try:
            endpoint.run(ctx.stop, on_tick=stats.tick if stats is not None else None)
        finally:
            if stats is not None:
                stats.write()
            for conn in links.values():
                conn.close()
            if tlog is not None:
                tlog.close()
                log.info("tlog closed", extra=fields(path=tlog_path, frames=tlog.frames))

    def serve(ctx: bus.Context) -> None:
        fleet.for_each(ctx, uavs, body)

    return bus.run_service(settings, serve, zenoh_session=use_zenoh)


if __name__ == "__main__":
    bus.leave(main())

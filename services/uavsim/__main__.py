"""uavsim: a simulated vehicle that speaks MAVLink like an autopilot and flies Eq. (1).

Links (pymavlink, MAVLink 2, system ``--sysid``, component 1):

* offboard (``--mavlink-url``, default ``udpin:0.0.0.0:14540``): the
  supervisor, the vehicle's offboard companion, streams
  SET_POSITION_TARGET_LOCAL_NED (frame LOCAL_NED, type_mask 3520 or 3576);
  optionally signed (``--signing-passphrase``: unsigned frames are rejected);
* ground station (``--gcs-url``, default ``udpin:0.0.0.0:14550``): MAVProxy or
  QGroundControl connect here (send first, e.g. ``mavproxy.py
  --master=udpout:127.0.0.1:14550``).

Both links get HEARTBEAT at 1 Hz (MAV_TYPE_QUADROTOR, component 1),
LOCAL_POSITION_NED and GLOBAL_POSITION_INT at 10 Hz and after every step,
and answers to PARAM_REQUEST_LIST/READ/SET, COMMAND_LONG (COMMAND_ACK) and the
mission protocol (an empty mission: operator waypoints reach System 1 over
Zenoh), so a GCS connects cleanly.

Time is lockstep (services/common/clock.py): each new setpoint, stamped with
the simulated time it is due (``time_boot_ms``), is one ΔT step of Eq. (1)
under the controller of services/uavsim/vehicle.py; repeats of it are the
keep-alive stream. Without setpoints for ``--offboard-loss-s`` of wall time
the vehicle reports HOLD (custom_mode 1) until the next new setpoint.
uavsim publishes nothing on Zenoh: it only holds a liveliness token.
"""

from __future__ import annotations

import logging
import math
import select
import sys
import threading
import time
from typing import Any

from services.common import bus, codec, mav
from services.common import cli as common_cli
from services.common.log import fields

from .vehicle import Vehicle, to_geodetic

log = logging.getLogger("services.uavsim")
m = mav.mavlink

MODE_OFFBOARD = 0
MODE_HOLD = 1
TELEMETRY_PERIOD_S = 0.1


class Endpoint:
    """The vehicle's MAVLink side: links, message handlers, periodic telemetry."""

    def __init__(self, vehicle: Vehicle, links: dict[str, Any], sysid: int, altitude_m: float,
                 home: tuple[float, float], offboard_loss_s: float):
        self.vehicle = vehicle
        self.links = links
        self.send = {name: mav.Sender(conn) for name, conn in links.items()}
        self.sysid = sysid
        self.altitude_m = altitude_m
        self.home = home
        self.offboard_loss_s = offboard_loss_s
        self.mode = MODE_HOLD
        self.last_setpoint = 0.0
        self.peers: set[tuple[str, int, int]] = set()
        self.boot = time.monotonic()
        self.params: dict[str, float] = {
            "MAV_SYS_ID": float(sysid),
            "COM_OF_LOSS_T": float(offboard_loss_s),
            "SIM_KP": float(vehicle.kp),
            "SIM_ALT_M": float(altitude_m),
        }

    # -- outgoing -----------------------------------------------------------------------------
    def heartbeat(self) -> None:
        base = (m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | m.MAV_MODE_FLAG_GUIDED_ENABLED
                | m.MAV_MODE_FLAG_SAFETY_ARMED)
        for send in self.send.values():
            send("heartbeat", m.MAV_TYPE_QUADROTOR, m.MAV_AUTOPILOT_GENERIC, base, self.mode,
                 m.MAV_STATE_ACTIVE)

    def telemetry(self) -> None:
        x = self.vehicle.state
        n, e, d, vn, ve, vd = codec.state_to_ned(x, self.altitude_m)
        lat, lon = to_geodetic(float(x[0]), float(x[1]), self.home)
        t_ms = self.vehicle.time_ms
        hdg = int(math.degrees(math.atan2(ve, vn)) % 360 * 100) if (vn or ve) else 65535
        for send in self.send.values():
            send("local_position_ned", t_ms, n, e, d, vn, ve, vd)
            send("global_position_int", t_ms, int(lat * 1e7), int(lon * 1e7),
                 int(self.altitude_m * 1000), int(self.altitude_m * 1000),
                 int(vn * 100), int(ve * 100), int(vd * 100), hdg)

    def statustext(self, text: str, severity: int = m.MAV_SEVERITY_INFO) -> None:
        for send in self.send.values():
            send("statustext", severity, text.encode()[:50])

    def param_value(self, link: str, name: str) -> None:
        names = list(self.params)
        self.send[link]("param_value", name.encode(), self.params[name],
                        m.MAV_PARAM_TYPE_REAL32, len(names), names.index(name))

    # -- incoming -----------------------------------------------------------------------------
    def handle(self, link: str, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "BAD_DATA":
            codec.rejected("mavlink", codec.invalid(f"bad or unsigned frame on {link}"), log)
            return
        if kind == "HEARTBEAT":
            peer = (link, msg.get_srcSystem(), msg.get_srcComponent())
            if peer not in self.peers:
                self.peers.add(peer)
                log.info("peer", extra=fields(link=link, sysid=peer[1], compid=peer[2],
                                              mav_type=msg.type))
                self.heartbeat()  # answer at once: the peer waits for us before it starts
            return
        target = getattr(msg, "target_system", None)
        if target not in (None, 0, self.sysid):
            return
        if kind == "SET_POSITION_TARGET_LOCAL_NED":
            self.on_setpoint(msg)
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
            pid = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
            name = pid.rstrip("\x00")
            if name in self.params and math.isfinite(msg.param_value):
                self.params[name] = float(msg.param_value)
                self.param_value(link, name)
        elif kind == "COMMAND_LONG":
            self.on_command(link, msg)
        elif kind == "MISSION_REQUEST_LIST":
            self.send[link]("mission_count", msg.get_srcSystem(), msg.get_srcComponent(), 0,
                            msg.mission_type)
        elif kind in ("MISSION_COUNT", "MISSION_CLEAR_ALL"):
            count = getattr(msg, "count", 0)
            result = m.MAV_MISSION_ACCEPTED if count == 0 else m.MAV_MISSION_DENIED
            self.send[link]("mission_ack", msg.get_srcSystem(), msg.get_srcComponent(), result,
                            msg.mission_type)
            if count:
                self.statustext("waypoints go to System 1 over Zenoh", m.MAV_SEVERITY_WARNING)

    def on_setpoint(self, msg: Any) -> None:
        try:
            target = codec.setpoint_from_mavlink(msg)
        except codec.CodecError as err:
            codec.rejected("setpoint", err, log)
            return
        self.last_setpoint = time.monotonic()
        if self.mode != MODE_OFFBOARD:
            self.mode = MODE_OFFBOARD
            log.info("offboard", extra=fields(time_ms=msg.time_boot_ms))
        if self.vehicle.apply(target, int(msg.time_boot_ms)):
            self.telemetry()
            x = self.vehicle.state
            log.debug("step", extra=fields(time_ms=self.vehicle.time_ms, east_m=float(x[0]),
                                           north_m=float(x[1])))

    def on_command(self, link: str, msg: Any) -> None:
        cmd = msg.command
        result = m.MAV_RESULT_UNSUPPORTED
        if cmd in (m.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, m.MAV_CMD_REQUEST_MESSAGE):
            result = m.MAV_RESULT_ACCEPTED
        elif cmd == m.MAV_CMD_SET_MESSAGE_INTERVAL:
            result = m.MAV_RESULT_ACCEPTED  # telemetry rates are fixed; accepted for the GCS
        self.send[link]("command_ack", cmd, result, 0, 0, msg.get_srcSystem(),
                        msg.get_srcComponent())
        wants_version = cmd == m.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES or (
            cmd == m.MAV_CMD_REQUEST_MESSAGE
            and int(msg.param1) == m.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        if wants_version:
            caps = (m.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                    | m.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED)
            self.send[link]("autopilot_version", caps, 1, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8,
                            0, 0, self.sysid)

    # -- loop -----------------------------------------------------------------------------------
    def run(self, stop: threading.Event) -> None:
        next_hb = next_tel = time.monotonic()
        self.statustext("dualpilot uavsim ready")
        fds = {conn.fd: name for name, conn in self.links.items()}
        while not stop.is_set():
            now = time.monotonic()
            if now >= next_hb:
                self.heartbeat()
                next_hb = now + 1.0
            if now >= next_tel:
                self.telemetry()
                next_tel = now + TELEMETRY_PERIOD_S
            if (self.mode == MODE_OFFBOARD and self.last_setpoint
                    and now - self.last_setpoint > self.offboard_loss_s):
                self.mode = MODE_HOLD
                log.warning("offboard setpoints lost: holding", extra=fields(
                    silence_s=round(now - self.last_setpoint, 3)))
            timeout = max(0.0, min(next_hb, next_tel, now + 0.2) - time.monotonic())
            ready, _, _ = select.select(list(fds), [], [], timeout)
            for fd in ready:
                name = fds[fd]
                conn = self.links[name]
                while (msg := conn.recv_msg()) is not None:
                    self.handle(name, msg)


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
                   help="'lat,lon' of the local origin, for GLOBAL_POSITION_INT [UAV_HOME]")
    p.add_argument("--kp", type=float, default=env("UAV_KP", "0.5"),
                   help="position gain of the controller [UAV_KP]")
    p.add_argument("--offboard-loss-s", type=float, default=env("COM_OF_LOSS_T", "1.0"),
                   help="hold after this long without setpoints (PX4 COM_OF_LOSS_T) "
                        "[COM_OF_LOSS_T]")
    p.add_argument("--signing-passphrase", default=env("MAVLINK_SIGNING_PASSPHRASE", ""),
                   help="sign the offboard link (sha256 of the passphrase) "
                        "[MAVLINK_SIGNING_PASSPHRASE]")
    args = p.parse_args(argv)
    try:
        settings = common_cli.settings("uavsim", args)
        start = parse_pair(args.start, "--start")
        home = parse_pair(args.home, "--home")
        if not 1 <= args.sysid <= 255:
            raise ValueError("--sysid must be in 1..255")
        if not (0 <= args.kp <= 1 and args.offboard_loss_s > 0):
            raise ValueError("need 0 <= --kp <= 1 and --offboard-loss-s > 0")
        vehicle = Vehicle.at(*start)
        vehicle.kp = args.kp
    except ValueError as err:
        p.error(str(err))

    def body(ctx: bus.Context) -> None:
        links = {"offboard": mav.connect(settings.mavlink_url, args.sysid,
                                         mav.MAV_COMP_ID_AUTOPILOT1, args.signing_passphrase)}
        if args.gcs_url:
            links["gcs"] = mav.connect(args.gcs_url, args.sysid, mav.MAV_COMP_ID_AUTOPILOT1)
        log.info("mavlink links open", extra=fields(
            offboard=settings.mavlink_url, gcs=args.gcs_url, signed=bool(args.signing_passphrase),
            east_m=start[0], north_m=start[1]))
        endpoint = Endpoint(vehicle, links, args.sysid, args.altitude_m, home,
                            args.offboard_loss_s)
        ctx.announce()
        try:
            endpoint.run(ctx.stop)
        finally:
            for conn in links.values():
                conn.close()

    return bus.run_service(settings, body)


if __name__ == "__main__":
    sys.exit(main())

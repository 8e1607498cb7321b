"""uavsim: a simulated vehicle that speaks MAVLink like an autopilot and flies Eq. (1).

Two links (pymavlink, MAVLink 2, system ``--sysid``, component 1): the
offboard link (``--mavlink-url``), where a companion (the supervisor, MAVSDK)
streams SET_POSITION_TARGET_LOCAL_NED, optionally signed, and the ground-station
link (``--gcs-url``) for MAVProxy or QGroundControl. Both get HEARTBEAT and
telemetry and answer parameters, commands and the mission protocol;
``--tlog`` records them in MAVProxy's ``.tlog`` format. Without the flags the
vehicle does what its autopilot's SITL does (services/uavsim/flavour.py):
``--autopilot px4`` *sends* to 127.0.0.1:14540 (MAVSDK's examples listen
there) and 127.0.0.1:14550 (QGroundControl listens there) and boots at PX4
SITL's home; ``--autopilot ardupilot`` serves TCP 5762 (offboard) and 5760
(ground station), ArduPilot SITL's SERIAL1 and SERIAL0. The local frame (m
east/north) has its origin at ``--home``.

``--clock realtime`` (the default: a vehicle on its own, as SITL) flies
Eq. (1) on the vehicle's own clock, one ΔT every ΔT / ``--speed-factor``
wall seconds; ``--clock lockstep`` (the stack: ``make run``, compose, every
mission) makes each setpoint, stamped with the simulated time it is due,
one ΔT step of Eq. (1) (services/uavsim/clock.py), with the dynamics of the
readings profile ``--profile`` (its speed limit per axis or as a norm,
``--speed-limit``). The parts: endpoint.py (links), commander.py (modes and
arming), failsafe.py, navigator.py, missionrun.py, geofence.py, commands.py,
params.py, telemetry.py, mission.py, control.py, vehicle.py (physics).
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
from dataclasses import dataclass
from typing import Any

from dualpilot.readings import PROFILES, get_profile
from services.common import bus, fleet, mav, rejections
from services.common import cli as common_cli
from services.common.log import fields

from . import clock as vclock
from . import flavour as fl
from .autopilot import VehicleSetup
from .endpoint import SIGNED_ONLY, Endpoint
from .storage import open_tlog
from .vehicle import Vehicle

log = logging.getLogger("services.uavsim")
m = mav.mavlink
#: wall s between writes of --stream-stats
STATS_EVERY_S = 5.0


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
            ep.ap.stream_stats.write(self.path, clock=clock, sysid=ep.sysid,
                                     failsafe_now=ep.ap.in_offboard_failsafe)
        except OSError as err:
            if not self.failed:
                self.failed = True
                rejections.rejected("stream-stats", rejections.invalid(f"not written: {err}"), log,
                                    key="storage/stream-stats", reason="write_error")


def parse_numbers(text: str, what: str, counts: tuple[int, ...] = (2,)) -> tuple[float, ...]:
    """Comma-separated finite numbers, as many as one of ``counts``; ValueError otherwise."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError as err:
        raise ValueError(f"{what} must be {len(counts) and counts[0]} comma-separated numbers, "
                         f"got {text!r}") from err
    if len(values) not in counts:
        raise ValueError(f"{what} must have {' or '.join(map(str, counts))} numbers, "
                         f"got {text!r}")
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"{what} must be finite")
    return values


def parse_pair(text: str, what: str) -> tuple[float, float]:
    a, b = parse_numbers(text, what)
    return a, b


def main(argv: list[str] | None = None) -> int:
    p = _parser()
    raw_argv = sys.argv[1:] if argv is None else argv
    args = p.parse_args(argv)
    try:
        opts = _options(args, raw_argv)
    except (ValueError, OSError) as err:
        p.error(str(err))

    def serve(ctx: bus.Context) -> None:
        fleet.for_each(ctx, opts.uavs, lambda c: _fly(c, opts))

    return bus.run_service(opts.settings, serve, zenoh_session=opts.use_zenoh)


def _parser() -> argparse.ArgumentParser:
    """The vehicle's flags, each with its environment variable."""
    env = common_cli.env
    p = common_cli.parser("uavsim", "Simulated vehicle: MAVLink endpoint flying Eq. (1).")
    _link_flags(p)
    p.add_argument("--sysid", type=int, default=env("MAV_SYSID", "1"), help="[MAV_SYSID]")
    p.add_argument("--start", default=os.environ.get("UAV_START"),
                   help="start position 'east,north' in m of the origin; default: px4 0,0 (at "
                        "home, as PX4 SITL), ardupilot 50,50 [UAV_START]")
    p.add_argument("--altitude-m", type=float, default=env("UAV_ALTITUDE_M", "50"),
                   help="fixed flight altitude (Sec. IV is 2-D) [UAV_ALTITUDE_M]")
    p.add_argument("--home", default=os.environ.get("UAV_HOME"),
                   help="'lat,lon[,alt]' (deg, deg, m above mean sea level) of the local "
                        "frame's origin, the planning area's south-west corner; default: px4 "
                        "PX4 SITL's home 47.397742,8.545594,488, ardupilot 35.1450,33.4110,0 "
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
    p.add_argument("--clock", choices=vclock.CLOCKS, default=env("UAV_CLOCK", vclock.REALTIME),
                   help="realtime: the vehicle flies on its own clock at --speed-factor, as a "
                        "SITL (MAVSDK, ground stations, missions); lockstep: each new setpoint "
                        "stamp is one step of Eq. (1) (the stack sets it) [UAV_CLOCK]")
    p.add_argument("--profile", default=env("READINGS_PROFILE", "today"), choices=list(PROFILES),
                   help="the reading of the paper whose dynamics the vehicle flies (Eq. (1), "
                        "its force and speed limits; dualpilot profiles) [READINGS_PROFILE]")
    p.add_argument("--speed-limit", default=env("SPEED_LIMIT", ""),
                   help="override: axis (|v_i| <= v_max) or norm (|v| <= v_max) [SPEED_LIMIT]")
    p.add_argument("--zenoh", choices=("auto", "on", "off"), default=env("UAV_ZENOH", "auto"),
                   help="hold a liveliness token on Zenoh; auto: only when ZENOH_CONNECT or "
                        "--zenoh-connect is given (the vehicle needs no router) [UAV_ZENOH]")
    return p


def _link_flags(p: argparse.ArgumentParser) -> None:
    """The autopilot and its links: without them, the autopilot's SITL defaults."""
    env = common_cli.env
    p.add_argument("--autopilot", choices=sorted(fl.FLAVOURS),
                   default=env("UAV_AUTOPILOT", fl.ARDUPILOT.name),
                   help="the autopilot the vehicle claims to be and behaves like: HEARTBEAT "
                        "autopilot, mode numbers, and its SITL's links and home "
                        "[UAV_AUTOPILOT]")
    p.add_argument("--mavlink-url", default=os.environ.get("MAVLINK_URL"),
                   help="the offboard link; default: the autopilot's SITL (px4: "
                        f"{fl.PX4.sitl.offboard_url}, ardupilot: {fl.ARDUPILOT.sitl.offboard_url})"
                        " [MAVLINK_URL]")
    p.add_argument("--gcs-url", default=os.environ.get("GCS_URL"),
                   help="the ground-station link, empty to disable; default: the autopilot's "
                        f"SITL (px4: {fl.PX4.sitl.gcs_url}, ardupilot: "
                        f"{fl.ARDUPILOT.sitl.gcs_url}) [GCS_URL]")


@dataclass(frozen=True)
class VehicleOptions:
    """The checked flags: what every vehicle of this process flies with."""

    args: argparse.Namespace
    settings: common_cli.Settings
    start: tuple[float, float]  #: m east, north
    home: tuple[float, float]  #: deg lat, lon of the local frame's origin
    home_amsl_m: float  #: the origin's altitude above mean sea level
    key: bytes | None  #: the offboard link's signing key
    dynamics: Any  #: Eq. (1) of the profile
    uavs: tuple[str, ...]
    speed: float  #: the clock's speed factor
    use_zenoh: bool


def _options(args: argparse.Namespace, raw_argv: list[str]) -> VehicleOptions:
    """Check the flags together; ValueError names the first that is wrong."""
    use_zenoh = args.zenoh == "on" or (args.zenoh == "auto" and (
        "ZENOH_CONNECT" in os.environ
        or any(a.startswith("--zenoh-connect") for a in raw_argv)))
    sitl = fl.FLAVOURS[args.autopilot].sitl
    args.mavlink_url = sitl.offboard_url if args.mavlink_url is None else args.mavlink_url
    args.gcs_url = sitl.gcs_url if args.gcs_url is None else args.gcs_url
    if not args.mavlink_url:
        raise ValueError("--mavlink-url must not be empty (the offboard link)")
    settings = common_cli.settings("uavsim", args)
    start = parse_pair(args.start, "--start") if args.start is not None else sitl.start
    lat, lon, *alt = (parse_numbers(args.home, "--home", (2, 3)) if args.home is not None
                      else sitl.home)
    if not (abs(lat) < 85 and abs(lon) <= 180 and -500 <= (alt or [0.0])[0] <= 9000):
        raise ValueError("--home must be a latitude in (-85, 85), a longitude and an altitude "
                         "in [-500, 9000] m")
    home = (lat, lon)
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
    return VehicleOptions(args, settings, start, home, (alt or [0.0])[0], key, dynamics, uavs,
                          speed, use_zenoh)


def _links(opts: VehicleOptions, k: int, sysid: int) -> dict[str, Any]:
    """Instance k's MAVLink links: offboard (signed with the key) and, if asked, the GCS's."""
    args, key = opts.args, opts.key
    links = {"offboard": mav.connect(fleet.instance_url(opts.settings.mavlink_url, k), sysid,
                                     mav.MAV_COMP_ID_AUTOPILOT1, key=key)}
    if args.gcs_url:
        links["gcs"] = mav.connect(fleet.instance_url(args.gcs_url, k), sysid,
                                   mav.MAV_COMP_ID_AUTOPILOT1)
        if key is not None:  # signed too: unsigned control, uploads and PARAM_SET refused
            signed_only = {getattr(m, f"MAVLINK_MSG_ID_{k}") for k in SIGNED_ONLY}
            links["gcs"].setup_signing(
                key, sign_outgoing=True,
                allow_unsigned_callback=lambda _mav, msg_id: msg_id not in signed_only)
    return links


def _fly(ctx: bus.Context, opts: VehicleOptions) -> None:
    """One vehicle (instance k of the process): its links, endpoint and records, until stop."""
    args, start = opts.args, opts.start
    k = opts.uavs.index(ctx.settings.uav_id)  # this vehicle's instance: ports and sysid + k
    uav = ctx.settings.uav_id
    sysid = args.sysid + k
    tlog_path = fleet.per_vehicle(args.tlog, uav)
    stats_path = fleet.per_vehicle(args.stream_stats, uav)
    tlog = open_tlog(tlog_path) if tlog_path else None
    links = _links(opts, k, sysid)
    vehicle = Vehicle.at(*start, dyn=opts.dynamics)
    vehicle.kp = args.kp
    log.info("serving MAVLink", extra=fields(
        uav=uav, sysid=sysid, offboard=fleet.instance_url(opts.settings.mavlink_url, k),
        gcs=fleet.instance_url(args.gcs_url, k) if args.gcs_url else "",
        signed=opts.key is not None, autopilot=args.autopilot, clock=args.clock,
        speed_factor=opts.speed, speed_limit=vehicle.dyn.speed_limit,
        zenoh=opts.use_zenoh, east_m=start[0], north_m=start[1], home=opts.home,
        home_amsl_m=opts.home_amsl_m, tlog=tlog_path))
    setup = VehicleSetup(sysid, args.altitude_m, opts.home, args.offboard_loss_s,
                         args.area_size_m, fl.FLAVOURS[args.autopilot], args.clock, opts.speed,
                         opts.home_amsl_m)
    endpoint = Endpoint(vehicle, links, setup, tlog)
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


if __name__ == "__main__":
    bus.leave(main())

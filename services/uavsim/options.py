"""uavsim's flags and their checks: :func:`parser` and :func:`check` give :class:`VehicleOptions`.

Every flag is a setting of the simulated vehicle (its links, identity, frame,
clock, failsafe and records), each with its environment variable. What the
vehicle flies in a mission (Eq. (1), the area) is no flag: it comes with the
mission's configuration from its supervisor (services/uavsim/missionconfig.py).
"""

from __future__ import annotations

import argparse
import math
import os
from dataclasses import dataclass

from services.common import cli as common_cli
from services.common import fleet, mav

from . import clock as vclock
from . import flavour as fl


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


def parser() -> argparse.ArgumentParser:
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
    uavs: tuple[str, ...]
    speed: float  #: the clock's speed factor
    use_zenoh: bool


def check(args: argparse.Namespace, raw_argv: list[str]) -> VehicleOptions:
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
    key = mav.resolve_key(args.signing_passphrase, args.signing_key_file)
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
    return VehicleOptions(args, settings, start, home, (alt or [0.0])[0], key, uavs, speed,
                          use_zenoh)

"""The vehicles of one uavsim process, opened and served: links, endpoint, records, Zenoh.

:func:`serve` boots every vehicle of the process (``--uav-ids``: instance k on
the links' ports + k, system id + k) and runs them in one loop
(services/uavsim/host.py); each holds its liveliness token and takes its
mission configuration on Zenoh when the process has a session
(services/uavsim/missionconfig.py), writes its MAVLink traffic (``--tlog``) and
what it saw of its setpoint stream (``--stream-stats``).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Any

from services.common import bus, fleet, mav, rejections
from services.common.log import fields, tag_vehicle

from . import clock as vclock
from . import flavour as fl
from .autopilot import VehicleSetup
from .endpoint import SIGNED_ONLY, Endpoint
from .host import Host
from .missionconfig import MissionConfigs, mission_configs
from .options import VehicleOptions
from .sidechannel import SideChannel
from .storage import open_tlog
from .truth import flight_truths
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


@dataclass
class HostedVehicle:
    """One vehicle of the process, opened: its endpoint, links, flight log and stream file."""

    uav: str
    endpoint: Endpoint
    links: dict[str, Any]
    tlog: Any
    tlog_path: str
    stats: StatsFile | None
    configs: SideChannel | None = None  #: the mission configurations it takes (Zenoh)
    truths: SideChannel | None = None  #: its plant's ground truth (Zenoh)

    def tick(self, now: float) -> None:
        """Between two passes of the vehicle's loop: a new mission configuration, the
        stream statistics."""
        if self.configs is not None:
            self.configs.poll(now)
        if self.truths is not None:
            self.truths.poll(now)
        if self.stats is not None:
            self.stats.tick(now)

    def close(self) -> None:
        if self.configs is not None:
            self.configs.close()
        if self.truths is not None:
            self.truths.close()
        if self.stats is not None:
            self.stats.write()
        for conn in self.links.values():
            conn.close()
        if self.tlog is not None:
            self.tlog.close()
            log.info("tlog closed", extra=fields(path=self.tlog_path, frames=self.tlog.frames))


def open_vehicle(ctx: bus.Context, opts: VehicleOptions, boot: float) -> HostedVehicle:
    """Vehicle ``ctx.settings.uav_id`` (instance k of the process: ports and sysid + k), booted
    at ``boot`` (monotonic s): its links, endpoint and records, announced on Zenoh."""
    args, start = opts.args, opts.start
    uav = ctx.settings.uav_id
    k = opts.uavs.index(uav)
    sysid = args.sysid + k
    tlog_path = fleet.per_vehicle(args.tlog, uav)
    stats_path = fleet.per_vehicle(args.stream_stats, uav)
    tlog = open_tlog(tlog_path) if tlog_path else None
    links = _links(opts, k, sysid)
    vehicle = Vehicle.at(*start)  # the default dynamics until a mission configuration comes
    vehicle.kp = args.kp
    log.info("serving MAVLink", extra=fields(
        uav=uav, sysid=sysid, offboard=fleet.instance_url(opts.settings.mavlink_url, k),
        gcs=fleet.instance_url(args.gcs_url, k) if args.gcs_url else "",
        signed=opts.key is not None, autopilot=args.autopilot, clock=args.clock,
        speed_factor=opts.speed, speed_limit=vehicle.dyn.speed_limit,
        zenoh=opts.use_zenoh, east_m=start[0], north_m=start[1], home=opts.home,
        home_amsl_m=opts.home_amsl_m, tlog=tlog_path))
    setup = VehicleSetup(sysid, args.altitude_m, opts.home, args.offboard_loss_s,
                         flavour=fl.FLAVOURS[args.autopilot], clock=args.clock,
                         speed_factor=opts.speed, home_amsl_m=opts.home_amsl_m)
    endpoint = Endpoint(vehicle, links, setup, tlog, boot)
    if tlog is not None:
        tlog.on_fault = lambda text: setattr(endpoint, "fault", text)
    elif tlog_path:
        endpoint.fault = "tlog not created: flying without it"
    stats = StatsFile(stats_path, endpoint) if stats_path else None
    configs = truths = None
    if ctx.session is not None:
        configs = mission_configs(ctx.session, MissionConfigs(
            uav, endpoint, bus.Liveliness(ctx.session, uav)))
        truths = flight_truths(ctx.session, uav, vehicle)
        ctx.announce()
    return HostedVehicle(uav, endpoint, links, tlog, tlog_path, stats, configs, truths)


def serve(ctx: bus.Context, opts: VehicleOptions) -> None:
    """Every vehicle of the process, booted together and served by one loop until stop."""
    subs = fleet.contexts(ctx, opts.uavs)
    boot = time.monotonic()
    host = Host()
    opened: list[HostedVehicle] = []
    try:
        for sub in subs:
            tag_vehicle(sub.settings.uav_id)
            v = open_vehicle(sub, opts, boot)
            opened.append(v)
            host.add(v.uav, v.endpoint, v.tick)
        if len(subs) > 1:
            log.info("serving vehicles", extra=fields(uavs=",".join(opts.uavs)))
        host.run(ctx.stop)
    finally:
        for v in opened:
            tag_vehicle(v.uav)
            v.close()
        fleet.release(ctx, subs)

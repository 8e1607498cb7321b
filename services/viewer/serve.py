"""The viewer's loops: the live one (every vehicle's messages, checked, on Foxglove and the web
page) and the replay of recorded missions; :class:`Viewer` dispatches one message.

The Zenoh callbacks only enqueue; :func:`body` decodes and logs, drawing only
each vehicle's newest fire state and forecast of a pass (:func:`batch`).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

from dualpilot.spec import MissionSpec
from services.common import bus, keys, rejections
from services.common.convert import fire as fire_convert
from services.common.convert import supervisor as supervisor_convert
from services.common.convert import vehicle as vehicle_convert
from services.common.log import fields
from services.msgs import fire_pb2, supervisor_pb2, vehicle_pb2

from . import replay
from .live import LiveVehicle, log_time_ns
from .picture import Picture
from .replay import Timeline
from .web import WebServer

log = logging.getLogger("services.viewer")

DEFAULT_LISTEN = "tcp/127.0.0.1:8765"
#: between two vehicles' areas side by side in ``world`` (m)
AREA_GAP_M = 100.0
#: items taken from the inbox in one pass
BATCH = 500
_LISTEN = re.compile(r"^tcp/(?P<host>[^:/]+|\[[^\]]+\]):(?P<port>\d{1,5})$")
#: what is drawn only at its newest within one pass
LATEST_ONLY = ("ews/fires", "ews/forecast")


def parse_listen(text: str) -> tuple[str, int]:
    """``tcp/HOST:PORT`` → (host, port); raises ValueError."""
    m = _LISTEN.match(text.strip())
    if m is None or not 0 <= int(m.group("port")) <= 65535:
        raise ValueError(f"--listen must look like tcp/127.0.0.1:8765, got {text!r}")
    return m.group("host").strip("[]"), int(m.group("port"))


#: key (below dualpilot/<uav>/) → the key function (for the subscription)
KINDS: dict[str, Callable[[str], str]] = {
    "supervisor/decision": keys.decision, "supervisor/plans": keys.step_plans,
    "vehicle/state": keys.vehicle_state, "mission/event": keys.mission_event,
    "ews/fires": keys.fires, "ews/forecast": keys.forecast,
}


class Viewer:
    """Every vehicle seen so far, and the dispatch of one received message to its handler."""

    def __init__(self, context: Any, picture: Picture | None = None):
        self.context = context
        self.picture = picture
        self.vehicles: dict[str, LiveVehicle] = {}

    def vehicle(self, uav: str, area_m: float) -> LiveVehicle:
        v = self.vehicles.get(uav)
        if v is None:
            k = len(self.vehicles)
            offset = (k * (area_m + AREA_GAP_M), 0.0)
            scene = self.picture.scene(uav, offset) if self.picture is not None else None
            v = LiveVehicle(uav, self.context, offset, scene)
            self.vehicles[uav] = v
            log.info("vehicle seen", extra=fields(uav=uav, vehicles=len(self.vehicles)))
        return v

    def handle(self, item: bus.Received, draw: bool = True) -> None:
        """Decode ``item`` (counted and logged when rejected) and draw it (a fire state or
        forecast only when ``draw``: an older frame of one pass is checked, not drawn)."""
        try:
            uav = keys.vehicle_of(item.key)
        except ValueError as err:
            rejections.rejected("input", rejections.invalid(str(err)), log, key=item.key)
            return
        kind = item.key.removeprefix(f"{keys.ns(uav)}/")
        if kind == "supervisor/decision":
            got = bus.accept(item, supervisor_pb2.Decision,
                             lambda m: (supervisor_convert.decision_from_msg(m),
                                        int(m.commanded_system),
                                        log_time_ns(m.header)), key=item.key, logger=log)
            if got is not None:
                self._for(uav).decision(*got)
        elif kind == "supervisor/plans":
            sp = bus.accept(item, supervisor_pb2.StepPlans,
                            lambda m: (supervisor_convert.step_plans_from_msg(m),
                                       log_time_ns(m.header)),
                            key=item.key, logger=log)
            if sp is not None:
                plans, t_ns = sp
                self.vehicle(uav, plans.spec.area_size_m).step_plans(plans, t_ns)
        elif kind == "vehicle/state":
            st = bus.accept(item, vehicle_pb2.VehicleState,
                            lambda m: (vehicle_convert.state_from_msg(m),
                                       int(m.step), log_time_ns(m.header)),
                            key=item.key, logger=log)
            if st is not None:
                self._for(uav).state(*st)
        elif kind == "mission/event":
            ev = bus.accept(item, supervisor_pb2.MissionEvent,
                            supervisor_convert.check_mission_event, key=item.key, logger=log)
            if ev is not None:
                self._for(uav).event(ev, log_time_ns(ev.header))
        elif kind == "ews/fires":
            fs = bus.accept(item, fire_pb2.FireState,
                            lambda m: (fire_convert.snapshot_from_msg(m), log_time_ns(m.header)),
                            key=item.key, logger=log)
            if fs is not None and draw:
                self._for(uav).fires(*fs)
        elif kind == "ews/forecast":
            fc = bus.accept(item, fire_pb2.FireForecast,
                            lambda m: (fire_convert.occupancy_from_msg(m), log_time_ns(m.header)),
                            key=item.key, logger=log)
            if fc is not None and fc[0] is not None and draw:
                self._for(uav).forecast(fc[0], fc[1])

    def _for(self, uav: str) -> LiveVehicle:
        known = self.vehicles.get(uav)
        return known if known is not None else self.vehicle(uav, MissionSpec().area_size_m)


def batch(inbox: bus.Inbox, first: bus.Received) -> list[tuple[bus.Received, bool]]:
    """``first`` and what else waits in ``inbox`` (at most :data:`BATCH`), each with whether to
    draw it: of each vehicle's fire states and forecasts only the newest is drawn."""
    items = [first]
    while len(items) < BATCH:
        nxt = inbox.get(timeout=0)
        if nxt is None:
            break
        items.append(nxt)
    newest: dict[str, int] = {}
    for i, it in enumerate(items):
        if any(it.key.endswith("/" + k) for k in LATEST_ONLY):
            newest[it.key] = i
    keep = set(newest.values())
    return [(it, i in keep or it.key not in newest) for i, it in enumerate(items)]


def body(ctx: bus.Context, host: str, port: int, web: WebServer | None) -> None:
    import foxglove

    assert ctx.session is not None
    context = foxglove.Context()
    server = foxglove.start_server(name="dualpilot", host=host, port=port, context=context)
    log.info("serving the live view", extra=fields(url=f"ws://{host}:{server.port}",
                                                   port=server.port))
    picture = Picture()
    if web is not None:
        web.frames = picture.frame
        web.start()
    viewer = Viewer(context, picture if web is not None else None)
    inbox = bus.Inbox()
    subs = [ctx.session.declare_subscriber(keys.every_vehicle(fn), inbox.on_sample)
            for fn in KINDS.values()]
    ctx.announce()
    skipped = 0
    try:
        while not ctx.stop.is_set():
            first = inbox.get(timeout=0.2)
            if first is None:
                continue
            for item, draw in batch(inbox, first):
                skipped += not draw
                try:
                    viewer.handle(item, draw)
                except Exception:  # a bug in drawing one message must not stop the view
                    log.exception("could not draw a message", extra=fields(key=item.key))
    finally:
        for sub in subs:
            sub.undeclare()
        server.stop()
        if web is not None:
            web.stop()
        log.info("live view stopped", extra=fields(frames_skipped=skipped))


def replay_body(ctx: bus.Context, timeline: Timeline, web: WebServer) -> None:
    """Serve the page of recorded missions (no Zenoh) until stopped."""
    web.step_frames, web.replay_steps = timeline.at, len(timeline.frames)
    web.title = f"dualpilot replay: {', '.join(Path(f).name for f in timeline.files)}"
    log.info("replaying", extra=fields(files=list(timeline.files), frames=len(timeline.frames)))
    web.start()
    try:
        ctx.stop.wait()
    finally:
        web.stop()


def load_replay(paths: list[Path]) -> Timeline:
    """The recordings' timeline; ValueError naming the file for anything unreadable."""
    from mcap.exceptions import McapError

    missing = [str(f) for f in paths if not f.is_file()]
    if missing:
        raise ValueError(f"no such recording: {', '.join(missing)}")
    try:
        return replay.load(paths)
    except (McapError, OSError, KeyError, IndexError) as err:
        raise ValueError(f"cannot replay {', '.join(map(str, paths))}: not a mission.mcap "
                         f"of dualpilot's channels ({type(err).__name__}: {err})") from err


def web_server(args: Any) -> WebServer | None:
    """The web page's server the flags ask for (not started), None with ``--no-web``."""
    if args.no_web:
        return None
    host, port = parse_listen(args.web_listen)
    if args.web_port is not None:
        if not 0 <= args.web_port <= 65535:
            raise ValueError(f"--web-port must be in 0..65535, got {args.web_port}")
        port = args.web_port
    if port == 0:
        from services.launch.processes import free_port

        port = free_port("tcp")
    origins = [o.strip() for o in args.web_origin.split(",") if o.strip()]
    return WebServer(host, port, "dualpilot operations picture", None, allow_origins=origins)

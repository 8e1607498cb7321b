"""The stack around one supervisor mission, in this process: no Zenoh session, no socket, no sleep.

What the supervisor's session (services/supervisor/session.py) talks to, each
piece the real component where one can run here, behind a fake transport:

- :class:`Tokens`: a Zenoh session's liveliness as :class:`services.common.bus.Liveliness`
  reads it; the test puts and deletes the services' tokens.
- :class:`InProcessStack`: the session's transport (``StackTransport``): a fire
  command is answered by the EWS's own handler (services/ews), a plan request
  by the planner service's own handler (services/common/planning.py; a forecast
  named by reference is taken from the EWS's answers, services/ews/answers.py), the
  mission configuration handed to the simulated vehicle is decoded and answered
  as uavsim does (services/uavsim/missionconfig.py), each through its wire form;
  what the supervisor publishes is kept, decoded.
- :class:`FakeWall`: the wall clock, moved only by the waits made on it (and by
  the test).
- :class:`SimAutopilot` behind :class:`SimConnection`: the vehicle at the other
  end of a real :class:`~services.supervisor.link.VehicleLink`, answering each
  MAVLink message at once as a PX4 autopilot in lockstep would (a setpoint due
  at t ms is the state at t ms: the stack's lockstep contract,
  tests/e2e/test_lockstep.py); for a mission of another plant than Eq. (1),
  :class:`PlantAutopilot`, which flies as uavsim's vehicle does (its plant,
  services/uavsim/plantsim.py) and answers its ground truth as uavsim does
  (services/uavsim/truth.py).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import zenoh
from google.protobuf.message import Message

from dualpilot.mission.config import MissionConfig
from dualpilot.model.dynamics import Array, hover_state
from dualpilot.plan import Planner
from dualpilot.planners import build_planner
from dualpilot.spec import MissionSpec
from services.common import bus, keys, mav, mavlink_codec, mavmodes, rejections, wire
from services.common.clock import SimClock
from services.common.convert import config as config_convert
from services.common.convert import fire as fire_convert
from services.common.convert import plan as plan_convert
from services.common.convert import vehicle as vehicle_convert
from services.common.planning import PlannerService
from services.ews.answers import AnsweredForecasts, answer
from services.ews.fireprocess import Ews
from services.msgs import common_pb2, config_pb2, fire_pb2, supervisor_pb2
from services.supervisor.link import LinkParams, VehicleLink
from services.supervisor.pool import NoReply, Reply
from services.supervisor.ports import StackBus, StackParams
from services.supervisor.record import RunRecord
from services.supervisor.session import StackSession
from services.uavsim.missionconfig import fly_plant
from services.uavsim.truth import answer as truth_answer
from services.uavsim.vehicle import Vehicle

m = mav.mavlink
UAV = "u1"
HOME = (35.1450, 33.4110)  # the vehicle's geodetic origin (lat, lon degrees)
BOOT_MS = 5000  # the vehicle's clock when the mission starts (ms since boot)


class _Publisher:
    """A publisher nobody subscribes to (the EWS's own, services/ews)."""

    class Matching:
        matching = False

    matching_status = Matching()

    def put(self, *args: Any, **kw: Any) -> None:
        pass


class EwsSession:
    """Enough of a Zenoh session for the EWS's publishers."""

    def declare_publisher(self, key: str) -> _Publisher:
        return _Publisher()


def in_process_ews(stop: threading.Event, uav: str = UAV) -> Ews:
    """The EWS's fire process with its default parameters (a reset carries the mission's)."""
    return Ews(EwsSession(), uav, 80.0, stop)  # type: ignore[arg-type]


@dataclass(frozen=True)
class _Sample:
    key_expr: str
    kind: zenoh.SampleKind


class Tokens:
    """The liveliness tokens of one vehicle's services, put and deleted by the test."""

    def __init__(self, uav: str = UAV):
        self.uav = uav
        self.handler: Callable[[Any], None] | None = None

    # what bus.Liveliness asks of its session
    def liveliness(self) -> Tokens:
        return self

    def declare_subscriber(self, key: str, handler: Callable[[Any], None],
                           history: bool = False) -> Tokens:
        self.handler = handler
        return self

    def tracker(self) -> bus.Liveliness:
        """A liveliness tracker fed by these tokens."""
        return bus.Liveliness(self, self.uav)  # type: ignore[arg-type]

    def _say(self, service: str, zid: str, kind: zenoh.SampleKind) -> None:
        assert self.handler is not None, "no tracker yet"
        self.handler(_Sample(keys.holder(self.uav, service, zid), kind))
        self.handler(_Sample(keys.alive(self.uav, service), kind))

    def up(self, *services: str) -> None:
        for service in services:
            self._say(service, f"{service}-zid", zenoh.SampleKind.PUT)

    def claim(self, service: str, zid: str) -> None:
        """``service``'s token, held by the session ``zid``."""
        self._say(service, zid, zenoh.SampleKind.PUT)

    def down(self, *services: str) -> None:
        for service in services:
            self._say(service, f"{service}-zid", zenoh.SampleKind.DELETE)


def planner_services(uav: str = UAV) -> dict[int, PlannerService]:
    """Both planner services, each making its mission's planner as the processes do
    (services/system1, services/system2: the configuration's method, risk-aware with risk)."""

    def maker(system: int) -> Callable[[MissionSpec, MissionConfig], Planner]:
        return lambda spec, config: build_planner(system, spec, config.methods()[system],
                                                  risk=config.risk)

    return {k: PlannerService(k, maker(k), uav) for k in (1, 2)}


class _Replicas:
    """The planner pool's transport: each system's one replica, its service's own handler."""

    def __init__(self, stack: InProcessStack, live: bus.Liveliness | None):
        self.stack = stack
        self.live = live

    def replicas(self, system: int) -> list[str] | None:
        return None if self.live is None else self.live.replicas(f"system{system}")

    def ask(self, system: int, replica: str, msg: Message, timeout_s: float) -> Reply:
        if system in self.stack.silent_planners:
            raise NoReply(f"no reply on plan/system{system}/{replica}")
        out = self.stack.services[system].handle(msg.SerializeToString(),
                                                 wire.encoding_name(msg))
        if isinstance(out, common_pb2.Error):
            raise bus.QueryError(out.code, out.message)
        return Reply(replica or f"system{system}-zid", out.SerializeToString(),
                     wire.encoding_name(out))

    def health(self, system: int, timeout_s: float) -> None:
        if system in self.stack.silent_planners:
            raise TimeoutError(f"no status from system{system}")


@dataclass
class InProcessStack:
    """The session's transport to the EWS and the planners, and what it publishes."""

    ews: Ews
    services: dict[int, PlannerService]
    uav: str = UAV
    ews_down: bool = False  # fire commands go unanswered (TimeoutError)
    silent_planners: set[int] = field(default_factory=set)
    fire_commands: list[str] = field(default_factory=list)  # the kinds asked, in order
    published: list[tuple[str, Message]] = field(default_factory=list)
    #: the mission configurations the simulated vehicle took, in order
    vehicle_configs: list[MissionConfig] = field(default_factory=list)
    #: called with (key, message) after each publication
    on_publish: list[Callable[[str, Message], None]] = field(default_factory=list)
    #: the forecasts the EWS answered (``ews/forecasts``: the planners' by reference)
    answers: AnsweredForecasts = field(default_factory=AnsweredForecasts)
    #: forecasts the planners took by reference, and the failed attempts
    fetched: list[str] = field(default_factory=list)
    #: the simulated vehicle that takes the mission configuration and answers its plant's
    #: ground truth as uavsim does (services/uavsim/missionconfig.py, truth.py); None: the
    #: configuration is only echoed
    plant_autopilot: PlantAutopilot | None = None

    def __post_init__(self) -> None:
        for service in self.services.values():  # the planners' EWS nearby is this one
            service.resolved.source = self

    def fetch(self, mission_id: str, ref: plan_convert.ForecastRef,
              timeout_s: float) -> fire_pb2.FireForecast:
        """A planner's forecast by reference, as ``ews/forecasts`` answers it."""
        if self.ews_down:
            self.fetched.append("late")
            raise TimeoutError(f"no reply on ews/forecasts within {timeout_s:.3g} s")
        cmd = fire_convert.fire_forecast_query_msg(mission_id, ref.step, ref.substeps_done,
                                                   ref.substeps_per_step,
                                                   wire.Stamper("planner", self.uav), 0.0,
                                                   digest=ref.digest)
        out = answer(self.answers, cmd.SerializeToString(), wire.encoding_name(cmd),
                     self.ews.stamper)
        if isinstance(out, common_pb2.Error):
            self.fetched.append("unavailable")
            raise bus.QueryError(out.code, out.message)
        self.fetched.append("ok")
        return wire.parse(out[0], fire_pb2.FireUpdate, out[1]).forecast

    def query(self, key: str, msg: Message, timeout_s: float, stop: threading.Event,
              trusted: bus.Trusted) -> tuple[bytes, str]:
        if key == keys.sim_mission(self.uav):  # uavsim takes the mission's configuration
            config = config_convert.config_from_msg(wire.parse(
                msg.SerializeToString(), config_pb2.MissionConfig, wire.encoding_name(msg)))
            self.vehicle_configs.append(config)
            if self.plant_autopilot is not None:
                self.plant_autopilot.configure(config)
            back = config_convert.config_to_msg(config, config_pb2.MissionConfig())
            return back.SerializeToString(), wire.encoding_name(back)
        if key == keys.sim_flight(self.uav) and self.plant_autopilot is not None:
            return self.plant_autopilot.truth(msg)
        assert key == keys.fire_command(self.uav), key
        cmd = fire_convert.fire_command_from_msg(
            wire.parse(msg.SerializeToString(), fire_pb2.FireCommand, wire.encoding_name(msg)))
        self.fire_commands.append(cmd.kind)
        if self.ews_down:
            raise TimeoutError(f"no reply on {key} within {timeout_s:.3g} s")
        update = self.ews.handle(cmd)
        if cmd.kind == "forecast":  # kept for the planners, as services/ews/service.py does
            self.answers.put(cmd.mission_id, update)
        return update.SerializeToString(), wire.encoding_name(update)

    def publisher(self, key: str) -> Callable[[Message], None]:
        return lambda msg: self.put(key, msg)

    def put(self, key: str, msg: Message) -> None:
        copy = type(msg).FromString(msg.SerializeToString())  # as a subscriber decodes it
        self.published.append((key, copy))
        if key == keys.waypoints(self.uav):  # what the planner services subscribe to
            for service in self.services.values():
                service.set_operator_waypoints(vehicle_convert.waypoints_from_msg(copy))
        for hook in list(self.on_publish):
            hook(key, copy)

    def planners(self, uav: str, stop: threading.Event,
                 live: bus.Liveliness | None) -> _Replicas:
        return _Replicas(self, live)

    # -- reading what was published ---------------------------------------------------------------
    def on(self, key: str) -> list[Any]:
        """The messages published on ``key``, in order."""
        return [msg for k, msg in self.published if k == key]

    def events(self) -> list[supervisor_pb2.MissionEvent]:
        return self.on(keys.mission_event(self.uav))

    def event_kinds(self) -> list[str]:
        """Each MissionEvent's kind, as its name says it (STARTED, STEP, …)."""
        return [supervisor_pb2.MissionEventKind.Name(ev.kind).removeprefix(
            "MISSION_EVENT_KIND_") for ev in self.events()]


class FakeWall:
    """The wall clock (monotonic s): it moves by the waits made on it, and when the test says."""

    def __init__(self, start_s: float = 1000.0):
        self.now_s = start_s
        self.waited_s = 0.0
        #: called with the new time after each wait (what happens meanwhile)
        self.on_wait: list[Callable[[float], None]] = []

    def now(self) -> float:
        return self.now_s

    def wait(self, seconds: float, stop: threading.Event) -> bool:
        self.now_s += seconds
        self.waited_s += seconds
        for hook in list(self.on_wait):
            hook(self.now_s)
        return stop.is_set()


def _custom_mode(main: float, sub: float) -> int:
    return mavmodes.px4_mode(int(main), int(sub))


class SimAutopilot:
    """A PX4 vehicle in lockstep, answering each MAVLink message of its companion at once.

    It heartbeats with each answer; a setpoint flies it (offboard and armed) to the target
    at the setpoint's due time, and it says so with LOCAL_POSITION_NED at that time; it
    switches to offboard only once a setpoint has come (PX4's rule), arms on request,
    answers ``MIS_ID`` and the mission protocol with its mission, and the origin request
    with :data:`HOME`. ``present`` False: it answers nothing (gone).
    """

    def __init__(self, state: Array, time_ms: int = BOOT_MS, altitude_m: float = 50.0):
        self.state = np.asarray(state, dtype=float).copy()
        self.time_ms = time_ms
        self.altitude_m = altitude_m
        self.mode = mavmodes.PX4_MODES.hold
        self.armed = False
        self.present = True
        self.text = ""  # the STATUSTEXT sent before the next heartbeat
        self.mission_id = 0.0
        self.items: list[Any] = []
        self.setpoints: list[tuple[list[float], int]] = []  # (target, due ms) received
        self.commands: list[int] = []  # COMMAND_LONG ids received
        self.refuse: dict[int, int] = {}  # command → the MAV_RESULT it is answered with
        self.lock = threading.Lock()
        self.deliver: Callable[[Any], None] = lambda msg: None  # to the link's handlers

    # -- what it sends ----------------------------------------------------------------------------
    def heartbeat(self) -> None:
        if self.text:
            self.deliver(m.MAVLink_statustext_message(m.MAV_SEVERITY_INFO, self.text.encode()))
            self.text = ""
        base = m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (
            m.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
        self.deliver(m.MAVLink_heartbeat_message(m.MAV_TYPE_QUADROTOR, m.MAV_AUTOPILOT_PX4,
                                                 base, self.mode, m.MAV_STATE_ACTIVE, 3))

    def position(self) -> None:
        n, e, d, vn, ve, vd = mavlink_codec.state_to_ned(self.state, self.altitude_m)
        self.deliver(m.MAVLink_local_position_ned_message(self.time_ms, n, e, d, vn, ve, vd))
        self.deliver(m.MAVLink_global_position_int_message(
            self.time_ms, round(HOME[0] * 1e7), round(HOME[1] * 1e7), 0, 0, 0, 0, 0, 0))

    def switch(self, mode: int, text: str = "") -> None:
        """The vehicle changes mode by itself (a failsafe, a ground station's command)."""
        with self.lock:
            self.mode, self.text = mode, text
            self.heartbeat()

    def upload(self, waypoints: Iterable[tuple[float, float]], mission_id: float) -> None:
        """A ground station uploads a mission of waypoints (east, north m)."""
        items = []
        for seq, (east, north) in enumerate(waypoints):
            lat, lon = mav.to_geodetic(east, north, HOME)
            items.append(m.MAVLink_mission_item_int_message(
                0, 0, seq, m.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, m.MAV_CMD_NAV_WAYPOINT, 0, 1,
                0, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), 50.0, 0))
        with self.lock:
            self.items, self.mission_id = items, float(mission_id)

    # -- what it receives -------------------------------------------------------------------------
    def receive(self, name: str, *args: Any) -> None:
        with self.lock:
            if not self.present:
                return
            handler = getattr(self, f"_on_{name}", None)
            if handler is not None:
                handler(*args)
            self.heartbeat()  # its heartbeat and telemetry go with every answer
            self.position()

    def _on_set_position_target_local_ned(self, due_ms: int, _sys: int, _comp: int, _frame: int,
                                          _mask: int, n: float, e: float, _d: float,
                                          vn: float, ve: float, *_rest: float) -> None:
        self.setpoints.append(([e, n, ve, vn], int(due_ms)))
        if self.armed and self.mode == mavmodes.PX4_MODES.offboard and due_ms >= self.time_ms:
            self.state = mavlink_codec.state_from_ned(n, e, vn, ve)
            self.time_ms = int(due_ms)

    def _on_command_long(self, _sys: int, _comp: int, cmd: int, _conf: int,
                         *p: float) -> None:
        self.commands.append(int(cmd))
        result = self.refuse.get(int(cmd), m.MAV_RESULT_ACCEPTED)
        if result == m.MAV_RESULT_ACCEPTED:
            if cmd == m.MAV_CMD_DO_SET_MODE:
                wanted = _custom_mode(p[1], p[2])
                if wanted == mavmodes.PX4_MODES.offboard and not self.setpoints:
                    result = m.MAV_RESULT_TEMPORARILY_REJECTED  # PX4: the stream first
                else:
                    self.mode = wanted
            elif cmd == m.MAV_CMD_COMPONENT_ARM_DISARM:
                self.armed = p[0] == 1.0
            elif cmd == m.MAV_CMD_REQUEST_MESSAGE:
                self.deliver(m.MAVLink_gps_global_origin_message(
                    round(HOME[0] * 1e7), round(HOME[1] * 1e7), 0, 0))
        self.deliver(m.MAVLink_command_ack_message(int(cmd), result, 0, 0, 0, 0))

    def _on_param_request_read(self, _sys: int, _comp: int, name: bytes, _index: int) -> None:
        if name == b"MIS_ID":
            self.deliver(m.MAVLink_param_value_message(
                b"MIS_ID", self.mission_id, m.MAV_PARAM_TYPE_REAL32, 1, 0))

    def _on_mission_request_list(self, _sys: int, _comp: int, mission_type: int) -> None:
        self.deliver(m.MAVLink_mission_count_message(0, 0, len(self.items), mission_type))

    def _on_mission_request_int(self, _sys: int, _comp: int, seq: int,
                                mission_type: int) -> None:
        self.deliver(self.items[seq])


class PlantAutopilot(SimAutopilot):
    """A :class:`SimAutopilot` that flies as uavsim's vehicle does (services/uavsim/vehicle.py):
    Eq. (1) towards each setpoint, or the mission's plant once the mission configuration
    says so (services/uavsim/missionconfig.py: :func:`fly_plant`), its ground truth
    answered as services/uavsim/truth.py answers it."""

    def __init__(self, vehicle: Vehicle, time_ms: int = BOOT_MS, altitude_m: float = 50.0):
        super().__init__(vehicle.state, time_ms, altitude_m)
        self.vehicle = vehicle
        vehicle.time_ms = time_ms
        self.stamper = wire.Stamper("uavsim", UAV)

    def configure(self, config: MissionConfig) -> None:
        with self.lock:
            fly_plant(self.vehicle, config, own_clock=False)
            self.vehicle.dyn = config.spec().dynamics
            self.state = self.vehicle.state.copy()

    def truth(self, msg: Message) -> tuple[bytes, str]:
        """The reply to a ground-truth request (QueryError: an error reply)."""
        with self.lock:
            try:
                out = truth_answer(self.vehicle, self.stamper, msg.SerializeToString(),
                                   wire.encoding_name(msg))
            except rejections.CodecError as err:
                raise bus.QueryError(err.code, str(err)) from err
        return out.SerializeToString(), wire.encoding_name(out)

    def _on_set_position_target_local_ned(self, due_ms: int, _sys: int, _comp: int, _frame: int,
                                          _mask: int, n: float, e: float, _d: float,
                                          vn: float, ve: float, *_rest: float) -> None:
        self.setpoints.append(([e, n, ve, vn], int(due_ms)))
        if self.armed and self.mode == mavmodes.PX4_MODES.offboard and due_ms >= self.time_ms:
            self.vehicle.apply(mavlink_codec.state_from_ned(n, e, vn, ve), int(due_ms))
            self.state = self.vehicle.state.copy()
            self.time_ms = self.vehicle.time_ms = int(due_ms)


class SimConnection:
    """The link's connection to a :class:`SimAutopilot` (``link.connection``)."""

    def __init__(self, autopilot: SimAutopilot, wall: FakeWall, target_system: int = 1):
        self.autopilot = autopilot
        self.wall = wall
        self.conn: Any = None
        self.target = (target_system, mav.MAV_COMP_ID_AUTOPILOT1)
        self.udp = False
        self.tag: str | None = None
        self.handlers: dict[str, Callable[[Any], None]] = {}
        self.sent: list[str] = []  # the names of the messages sent, in order
        autopilot.deliver = self.dispatch

    @property
    def listened(self) -> float:  # the reader never misses a frame here
        return self.wall.now()

    def send(self, name: str, *args: Any) -> None:
        self.sent.append(name)
        self.autopilot.receive(name, *args)

    def on(self, kinds: Iterable[str], handler: Callable[[Any], None]) -> None:
        for kind in kinds:
            self.handlers[kind] = handler

    def dispatch(self, msg: Any) -> None:
        handler = self.handlers.get(msg.get_type())
        if handler is not None:
            handler(msg)

    def listening(self, now: float) -> None:
        pass

    def read(self) -> None:
        pass

    def serve(self, stop: threading.Event) -> None:
        stop.wait()

    def heartbeat(self) -> None:
        self.send("heartbeat", m.MAV_TYPE_ONBOARD_CONTROLLER, m.MAV_AUTOPILOT_INVALID, 0, 0,
                  m.MAV_STATE_ACTIVE)

    def destinations(self) -> list[tuple[str, int]]:
        return []

    def close(self) -> None:
        pass


def sim_link(autopilot: SimAutopilot, wall: FakeWall) -> VehicleLink:
    """A real vehicle link (its components, no thread started) to ``autopilot``, heard (its
    first heartbeat, ``MIS_ID`` and mission, the origin) as the link's poll would have."""
    params = LinkParams("sim", rate_hz=20.0, stream="thread", command_timeout_s=0.2)
    link = VehicleLink(params, SimConnection(autopilot, wall), clock=wall.now)
    link.connection.heartbeat()  # speak first: the vehicle answers
    serve_link(link, wall)
    return link


def serve_link(link: VehicleLink, wall: FakeWall) -> None:
    """What the link loop and the mission watcher do in a second: the polls, a download."""
    link.poll(float("inf"))  # due at any time: the next call polls again
    link.mission.check()


@dataclass
class Rig:
    """One mission's session and everything around it, in this process."""

    config: MissionConfig
    stack: InProcessStack
    tokens: Tokens
    wall: FakeWall
    autopilot: SimAutopilot
    link: VehicleLink
    bus: StackBus
    record: RunRecord
    session: StackSession

    @property
    def run_dir(self) -> Path:
        assert self.record.dir is not None
        return self.record.dir


def rig(config: MissionConfig, run_dir: Path | None, params: StackParams = StackParams(),
        stack: InProcessStack | None = None, autopilot: SimAutopilot | None = None,
        waypoints: Array | None = None) -> Rig:
    """The session of ``config``'s mission, its services alive and its vehicle at the spec's
    start (hovering), the records in ``run_dir``."""
    stop = threading.Event()
    stack = stack or InProcessStack(in_process_ews(stop), planner_services())
    tokens = Tokens()
    live = tokens.tracker()
    tokens.up("ews", "uavsim", "system1", "system2")
    wall = FakeWall()
    spec = config.spec()
    if autopilot is None and config.reading().plant.plant != "ideal" and spec.dim == 2:
        autopilot = PlantAutopilot(Vehicle.at(float(spec.start[0]), float(spec.start[1]),
                                              dyn=spec.dynamics))
    autopilot = autopilot or SimAutopilot(hover_state(np.array(spec.start), spec.dynamics))
    if isinstance(autopilot, PlantAutopilot):
        stack.plant_autopilot = autopilot
    link = sim_link(autopilot, wall)
    b = StackBus(stack, UAV, config.mission_id or "m1", wire.Stamper("supervisor", UAV),
                 SimClock(0.0), stop, params, live, dt_s=spec.dynamics.dt_s, wall=wall)
    record = RunRecord(run_dir, b.mission_id)
    session = StackSession(b, link, config, record, waypoints)
    return Rig(config, stack, tokens, wall, autopilot, link, b, record, session)

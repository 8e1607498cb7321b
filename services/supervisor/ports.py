"""The mission step's ports over the stack: fires from the EWS, plans from the planner
services (Zenoh queries), the vehicle over MAVLink.

Each adapter turns a port call into messages and back, checking every reply
before it acts (services/common/protobuf_codec.py). Time is the lockstep SimClock
(services/common/clock.py): the fires' sub-steps and the vehicle's ΔT
advance it.
"""

from __future__ import annotations

import hashlib
import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np
import zenoh

from dualpilot.mission.ports import KeepOut, PlanRequest
from dualpilot.model.dynamics import Array
from dualpilot.model.fire import FireParams, FireSnapshot
from dualpilot.model.geometry import Rect
from dualpilot.model.stale_fire import StaleFireParams, credible_margin_m
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.spec import MissionSpec
from services.common import bus, keys, protobuf_codec, rejections, wire
from services.common.clock import SimClock
from services.common.log import fields, vehicle_thread
from services.msgs import common_pb2, fire_pb2, plan_pb2

from .link import VehicleLink

log = logging.getLogger(__name__)


class Aborted(RuntimeError):
    """The stack could not finish the mission (a service or the vehicle stopped answering)."""


@dataclass(frozen=True)
class StackParams:
    """How the supervisor talks to the stack."""

    #: how long a plan request waits (wall s), System 1 and System 2; None: tied to the
    #: control period ΔT by ``plan_deadline_periods`` (the paper's modelled planning times
    #: stay a modelling choice of the step, never a wait)
    plan_deadline_s: tuple[float, float] | None = None
    #: the deadlines in control periods ΔT: 2 ΔT for System 1, 5 ΔT (the paper's 5 s) for System 2
    plan_deadline_periods: tuple[float, float] = (2.0, 5.0)
    #: a planner that misses this many deadlines in a row is unavailable until it answers a
    #: health query (its ``status/<service>`` queryable)
    deadline_misses: int = 2
    health_every_s: float = 2.0    # wall s between health queries of an unavailable planner
    health_timeout_s: float = 0.5
    #: uavsim's token gone and no heartbeat for this long (s, after the link's 3 s): the
    #: mission ends ("vehicle_lost", an ``end`` line) instead of waiting ``pause_limit_s``
    vehicle_gone_s: float = 5.0
    fire_timeout_s: float = 30.0
    vehicle_timeout_s: float = 10.0
    altitude_m: float = 50.0
    offboard_timeout_s: float = 30.0  # taking the vehicle (heartbeat, position, mode, arm)
    mission_wait_s: float = 5.0       # downloading the vehicle's mission before step 0
    prepare_timeout_s: float = 60.0   # a planner's warm-up (not a flight plan: no deadline)
    pause_limit_s: float = 300.0      # abort when paused for longer
    #: fire data at least this old (simulated s) is stale (dualpilot/model/stale_fire.py)
    stale: StaleFireParams = StaleFireParams()
    #: flush the step record (steps.jsonl) at most this long after a line (s); 0: every line
    record_flush_s: float = 0.0


@dataclass
class Bus:
    """What every adapter shares: the session, the vehicle id, the clock, the stop event."""

    session: zenoh.Session
    uav: str
    mission_id: str
    stamper: wire.Stamper
    clock: SimClock
    stop: threading.Event
    stack: StackParams
    live: bus.Liveliness | None = None
    dt_s: float = 1.0  # the control period ΔT (s)

    def deadline_s(self, system: int) -> float:
        """The plan deadline of ``system`` (wall s): the explicit one, or periods × ΔT."""
        st = self.stack
        if st.plan_deadline_s is not None:
            return st.plan_deadline_s[system - 1]
        return st.plan_deadline_periods[system - 1] * self.dt_s

    def alive(self, service: str) -> bool:
        """The service's liveliness token is up (always True without a tracker)."""
        return self.live is None or not self.live.missing({service})

    def trusted(self, service: str) -> str | None:
        """Whose replies count for ``service``: the token holder's Zenoh id ("" nobody yet);
        None (anyone) without a tracker."""
        return None if self.live is None else self.live.holder(service)

    def clock_msg(self, out: common_pb2.Clock) -> None:
        """``out`` as the anchor that maps the current τ_t to the wall clock."""
        a = self.clock.anchor
        out.speed_factor = a.speed_factor
        out.sim_time_s = self.clock.now_s
        out.anchor_wall_ns = (int(a.wall_at(self.clock.now_s) * 1e9) if a.speed_factor
                              else a.wall_ns)


class StackFires:
    """The fire port over the EWS's ``ews/command`` queryable.

    Sub-steps the EWS does not confirm (gone, or no answer) are owed: the fire
    data then ages (:meth:`age_s`) and the planners get it grown by
    :meth:`margin_m` until an EWS is back, reset and replayed to the same fire
    world (:meth:`snapshot` catches up first).
    """

    def __init__(self, b: Bus, spec: MissionSpec, fire_params: FireParams = FireParams(),
                 on_caught_up: Callable[[int, int], None] | None = None):
        self.b = b
        self.spec = spec
        self.params = fire_params
        self.on_caught_up = on_caught_up
        #: (step, sub-steps, keep-out) of every FireAdvance the fire world should have had
        self.history: list[tuple[int, int, KeepOut | None]] = []
        self.owed = 0
        self.msg: fire_pb2.FireState | None = None
        self.current = FireSnapshot(regions=(), hulls=())

    # -- messages ---------------------------------------------------------------------------------
    def _command(self, cmd: fire_pb2.FireCommand) -> fire_pb2.FireUpdate:
        cmd.mission_id = self.b.mission_id
        self.b.stamper.stamp(cmd.header, self.b.clock.now_s)
        key = keys.fire_command(self.b.uav)
        try:
            payload, enc = bus.request(self.b.session, key, cmd, self.b.stack.fire_timeout_s,
                                       self.b.stop, trusted=self.b.trusted("ews"))
            update = wire.parse(payload, fire_pb2.FireUpdate, enc)
        except rejections.CodecError as err:
            rejections.rejected("FireUpdate", err, log, key=key)
            raise Aborted(f"EWS: {err}") from err
        except (TimeoutError, bus.QueryError) as err:
            raise Aborted(f"EWS: {err}") from err
        if not update.states:
            raise Aborted("EWS replied without a fire state")
        return update

    def _take(self, msg: fire_pb2.FireState) -> FireSnapshot:
        try:
            snap = protobuf_codec.snapshot_from_msg(msg)
        except rejections.CodecError as err:
            rejections.rejected("FireState", err, log)
            raise Aborted(f"EWS sent an invalid fire state: {err}") from err
        self.msg, self.current = msg, snap
        return snap

    def reset(self) -> FireSnapshot:
        """Start the mission's fire process; returns its first state. Raises Aborted."""
        cmd = fire_pb2.FireCommand()
        cmd.reset.seed, cmd.reset.area_size_m = self.spec.seed, self.spec.area_size_m
        # the EWS runs the same readings
        protobuf_codec.fire_readings_to_msg(self.params, cmd.reset)
        first = self._command(cmd).states[0]
        self.params = replace(self.params, substep_s=first.substep_s)
        return self._take(first)

    def replay(self) -> None:
        """Reset the EWS and replay every recorded advance (unpaced): the fire world the
        mission had, whatever the EWS lost. Raises Aborted when the EWS does not answer."""
        cmd = fire_pb2.FireCommand()
        cmd.reset.seed, cmd.reset.area_size_m = self.spec.seed, self.spec.area_size_m
        # the EWS runs the same readings
        protobuf_codec.fire_readings_to_msg(self.params, cmd.reset)
        last = self._command(cmd).states[-1]
        for t, n, keep in self.history:
            if n:
                cmd = fire_pb2.FireCommand()
                cmd.advance.step, cmd.advance.substeps = t, n
                _keep_out_to_msg(keep, cmd.advance)
                last = self._command(cmd).states[-1]
        self._take(last)
        self.owed = 0

    # -- the port ---------------------------------------------------------------------------------
    def snapshot(self) -> FireSnapshot:
        self._catch_up()
        return self.current

    def age_s(self) -> float:
        """Simulated s the fire process should have advanced beyond the last FireState."""
        return self.owed * self.params.substep_s

    def stale(self) -> bool:
        return self.age_s() >= self.b.stack.stale.stale_after_s

    def margin_m(self) -> float:
        if not self.stale():
            return 0.0
        return credible_margin_m(self.age_s(), self.params, self.b.stack.stale)

    def advance(self, t: int, n: int, keep_out: KeepOut | None) -> list[tuple[Rect, ...]]:
        """Propagate ``n`` sub-steps from τ_t (now); each sub-step's regions, [] when owed."""
        self.history.append((t, n, keep_out))
        if self.owed or not self.b.alive("ews"):
            self.owed += n
            self._pace(n)
            return []
        cmd = fire_pb2.FireCommand()
        cmd.advance.step, cmd.advance.substeps = t, n
        _keep_out_to_msg(keep_out, cmd.advance)
        self.b.clock_msg(cmd.advance.clock)  # sub-step k is due at τ_t + k·T_f
        try:
            update = self._command(cmd)
        except Aborted as err:
            if self.b.stop.is_set():
                raise
            log.warning("EWS did not advance the fires: data ageing", extra=fields(
                step=t, substeps=n, error=str(err)))
            self.owed += n
            self._pace(n)
            return []
        self.b.clock.advance(n * self.params.substep_s)
        out = []
        last = len(update.states) - 1
        for k, msg in enumerate(update.states):
            try:  # the intermediate sub-steps only matter through their regions
                out.append(self._take(msg).regions if k == last
                           else protobuf_codec.regions_from_msg(msg))
            except rejections.CodecError as err:
                rejections.rejected("FireState", err, log)
                raise Aborted(f"EWS sent an invalid fire state: {err}") from err
        return out

    def _pace(self, n: int) -> None:
        """The planning interval's n sub-steps pass on the clock without the EWS."""
        self.b.clock.advance(n * self.params.substep_s)
        self.b.clock.sleep_until_now(self.b.stop)

    def _catch_up(self) -> None:
        """With sub-steps owed and the EWS alive: replay (the step then judges the result)."""
        if not self.owed or not self.b.alive("ews"):
            return
        owed = self.owed
        try:
            self.replay()
        except Aborted as err:
            if self.b.stop.is_set():
                raise
            log.warning("EWS not caught up yet", extra=fields(error=str(err)))
            return
        log.info("fire data fresh again: EWS caught up", extra=fields(owed_substeps=owed))
        if self.on_caught_up is not None:
            self.on_caught_up(owed, len(self.current.regions))


def _keep_out_to_msg(keep: KeepOut | None, out: fire_pb2.FireAdvance) -> None:
    if keep is not None:
        out.keep_out.east_m, out.keep_out.north_m = (float(v) for v in keep[0])
        out.keep_out_m = float(keep[1])


class StackPlanners:
    """The planner port over ``plan/system<k>/<zid>`` queries, one replica of a pool at a time.

    A planner is asked only while its liveliness token is up. Each system may
    run as several replicas (each holder of its token is one); every replica
    is prepared for the mission, and each request goes to the mission's
    replica — the first of them by rendezvous hashing of (mission id, replica
    id), so the vehicles of a fleet spread over the pool and a mission keeps
    its replica (and that replica's warm start) while it lives. A request whose
    replica vanished (its query ends early without a reply: Zenoh finalises
    the queries of a closed session) is asked again of the next replica within
    what is left of the same deadline (``failovers``); a replica that let a
    request time out goes to the end of the order. A reply is checked before it
    is used: it must come from the replica asked, answer this step's request,
    arrive within the request's deadline and decode as a valid plan; anything
    else is a failed plan, never flown. A planner that was not prepared for
    this mission (it was restarted) is prepared again and asked once more.
    """

    def __init__(self, b: Bus, spec: MissionSpec, systems: list[int],
                 methods: dict[int, str] | None = None):
        self.b = b
        self.spec = spec
        self.systems = systems
        self.methods = methods or {}  # system → planner method named in the prepare request
        self.waypoints = protobuf_codec.Waypoints(b.mission_id, 0, None)
        self.last_info: dict[int, dict[str, object]] = {}
        self.request_wall = self.service_time = self.compute = 0.0
        self.requests = 0
        self.misses = {1: 0, 2: 0}  # deadlines missed in a row
        self.deadline_misses = 0  # all of them (the named fault plan_deadline)
        self._pool: ThreadPoolExecutor | None = None  # background requests (launch/collect)
        self.demoted: dict[int, float] = {}  # system → monotonic time of its last health query
        self.failovers = 0  # requests asked again of another replica (theirs vanished)
        self.suspect: dict[int, set[str]] = {1: set(), 2: set()}  # replicas that timed out
        self._lock = threading.Lock()  # the background request's thread counts too

    def replicas(self, system: int) -> list[str]:
        """The replicas of ``system`` in this mission's order ([] without a liveliness tracker:
        then the shared key is asked, trusting the first holder)."""
        if self.b.live is None:
            return []
        zids = self.b.live.replicas(f"system{system}")
        order = sorted(zids, key=lambda z: hashlib.blake2b(
            f"{self.b.mission_id}/{z}".encode(), digest_size=8).digest())
        suspect = self.suspect[system]
        return [z for z in order if z not in suspect] + [z for z in order if z in suspect]
    def begin_step(self) -> None:
        self.request_wall = self.service_time = self.compute = 0.0
        self.requests = 0
        self.last_info = {}

    def available(self, system: int) -> bool:
        if not self.b.alive(f"system{system}"):
            return False
        return system not in self.demoted or self._healthy(system)

    def _healthy(self, system: int) -> bool:
        """An unavailable planner's health query (at most every ``health_every_s``)."""
        now = time.monotonic()
        if now - self.demoted[system] < self.b.stack.health_every_s:
            return False
        self.demoted[system] = now
        name = f"system{system}"
        try:
            bus.query_status(self.b.session, self.b.uav, name, self.b.stack.health_timeout_s,
                             trusted=self._trusted(system), stop=self.b.stop)
        except (TimeoutError, ValueError) as err:
            log.info("planner still unavailable", extra=fields(system=system, error=str(err)))
            return False
        log.info("planner available again: it answered its health query",
                 extra=fields(system=system))
        del self.demoted[system]
        self.misses[system] = 0
        return True

    def _trusted(self, system: int) -> bus.Trusted:
        """Any replica of ``system`` (None: anyone, without a liveliness tracker)."""
        return None if self.b.live is None else frozenset(self.replicas(system))

    def _count_miss(self, system: int, plan: Plan) -> None:
        if plan.status is not PlanStatus.TIMEOUT:
            self.misses[system] = 0
            return
        self.misses[system] += 1
        self.deadline_misses += 1
        if self.misses[system] >= self.b.stack.deadline_misses and system not in self.demoted:
            self.demoted[system] = time.monotonic()
            log.warning("planner unavailable: missed its deadline", extra=fields(
                system=system, misses=self.misses[system],
                deadline_s=self.b.deadline_s(system)))

    def _message(self, system: int, req: PlanRequest | None) -> plan_pb2.PlanRequest:
        core = protobuf_codec.PlanRequest(
            seq=0, mission_id=self.b.mission_id, step=0 if req is None else req.t,
            system=system, objective=req.objective if req is not None else _OBJ,
            state=req.state if req is not None else np.zeros(4),
            prev_control=req.prev_control if req is not None else np.zeros(2),
            obstacles=req.obstacles if req is not None else (),
            deadline_s=self.b.deadline_s(system),
            waypoints_revision=self.waypoints.revision, prepare=req is None,
            spec=self.spec if req is None else None,
            method=self.methods.get(system, "") if req is None else "")
        return protobuf_codec.plan_request_msg(core, self.b.stamper, self.b.clock.now_s)

    def prepare(self, systems: list[int]) -> None:
        """Warm-up: every replica of each planner builds this mission's planner from the spec.

        Raises Aborted when no replica of a system could (one that could not is logged)."""
        for system in systems:
            msg = self._message(system, None)
            timeout = max(self.b.deadline_s(system), self.b.stack.prepare_timeout_s)
            targets = self.replicas(system) or [""]
            errors = []
            for zid in targets:
                key = (keys.plan_replica(self.b.uav, system, zid) if zid
                       else keys.plan(self.b.uav, system))
                try:
                    payload, enc = bus.request(
                        self.b.session, key, msg, timeout, self.b.stop,
                        trusted=zid or self.b.trusted(f"system{system}"),
                        count_key=keys.plan(self.b.uav, system))
                    wire.parse(payload, plan_pb2.Plan, enc)
                except (TimeoutError, bus.QueryError, rejections.CodecError) as err:
                    errors.append(f"{zid or 'system'}: {err}")
            if len(errors) == len(targets):
                raise Aborted(f"system{system} could not prepare the mission: "
                              f"{'; '.join(errors)}")
            for why in errors:
                log.warning("a planner replica could not prepare the mission",
                            extra=fields(system=system, error=why))

    def set_waypoints(self, points: Array | None, publish: bool) -> None:
        """A new revision of the operator waypoints, published on their key."""
        self.waypoints = protobuf_codec.Waypoints(self.b.mission_id, self.waypoints.revision + 1,
                                                  points)
        if publish:
            self.publish_waypoints()

    def publish_waypoints(self) -> None:
        pub = self.b.session.declare_publisher(keys.waypoints(self.b.uav))
        bus.put(pub, "", protobuf_codec.waypoints_msg(self.waypoints, self.b.stamper))
        pub.undeclare()

    def launch(self, request: PlanRequest) -> object:
        """Ask in the background (the concurrent supervisor's System 2): the query leaves now,
        on a thread of its own; :meth:`collect` takes its checked reply."""
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="deliberate",
                                            initializer=vehicle_thread(lambda: None))
        return self._pool.submit(self._ask, request, False)

    def collect(self, ticket: object) -> Plan:
        """The launched request's plan (a failed plan when it was late or not this step's)."""
        assert isinstance(ticket, Future)
        plan: Plan = ticket.result()
        if plan.status is PlanStatus.TIMEOUT:
            self.deadline_misses += 1
        return plan

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)

    def plan(self, request: PlanRequest) -> Plan:
        plan = self._ask(request)
        if plan.info.get("unprepared"):
            try:  # a restarted service: prepare it (and re-send the waypoints), ask once more
                self.prepare([request.system])
                if self.waypoints.revision:
                    self.publish_waypoints()
            except Aborted as err:
                log.warning("planner could not be prepared again", extra=fields(error=str(err)))
            else:
                plan = self._ask(request)
        self._count_miss(request.system, plan)
        self.compute += plan.compute_time_s
        if request.system == 1:
            self.last_info[1] = dict(plan.info)
        return plan

    def _ask(self, request: PlanRequest, account: bool = True) -> Plan:
        """One checked request, failed over between replicas; ``account``: add it to this
        step's latency counters (a background request runs on its own thread and is not part
        of the step's)."""
        system, t = request.system, request.t
        deadline = self.b.deadline_s(system)
        msg = self._message(system, request)
        t0 = time.perf_counter()
        base = keys.plan(self.b.uav, system)
        if account:
            self.requests += 1
        plan: Plan | None = None
        for zid in self.replicas(system) or [""]:
            remaining = deadline - (time.perf_counter() - t0)
            if remaining <= 0:
                break
            plan = self._ask_one(system, t, msg, zid, remaining, t0, account)
            ended_early = time.perf_counter() - t0 < deadline - 0.01
            if plan.info.get("no_reply") and zid and ended_early and not self.b.stop.is_set():
                with self._lock:
                    self.failovers += 1
                log.warning("plan request failed over: the replica vanished", extra=fields(
                    system=system, step=t, replica=zid,
                    left_s=round(deadline - (time.perf_counter() - t0), 4)))
                plan = None
                continue
            if plan.status is PlanStatus.TIMEOUT and zid:
                self.suspect[system].add(zid)  # asked last from now on
            elif zid:
                self.suspect[system].discard(zid)
            break
        if plan is None:
            plan = Plan.failed(system, PlanStatus.TIMEOUT, time.perf_counter() - t0,
                               f"no replica of system{system} answered on {base} within "
                               f"{deadline:g} s")
        if account:
            self.request_wall += time.perf_counter() - t0
        if self.b.stop.is_set():
            raise Aborted("stopped")
        return plan

    def _ask_one(self, system: int, t: int, msg: plan_pb2.PlanRequest, zid: str,
                 timeout_s: float, t0: float, account: bool) -> Plan:
        """Ask replica ``zid`` ("" the shared key) once; a failed plan says why."""
        deadline = self.b.deadline_s(system)
        base = keys.plan(self.b.uav, system)
        key = keys.plan_replica(self.b.uav, system, zid) if zid else base
        trusted = zid or self.b.trusted(f"system{system}")
        log.debug("plan request sent", extra=fields(system=system, step=t, replica=zid or "any",
                                                    seq=msg.header.seq,
                                                    stamped_ns=msg.header.wall_time_ns))
        try:
            payload, enc = bus.request(self.b.session, key, msg, timeout_s, self.b.stop,
                                       trusted=trusted, count_key=base)
            reply = wire.parse(payload, plan_pb2.Plan, enc)
            log.debug("plan reply received", extra=fields(system=system, step=t,
                                                          replica=zid or "any",
                                                          seq=reply.request_seq))
            plan = protobuf_codec.plan_from_msg(reply, system)
            if account:
                self.service_time += reply.service_time_s
            age = time.perf_counter() - t0
            if reply.step != t or reply.request_seq != msg.header.seq:
                plan = Plan.failed(system, PlanStatus.ERROR, plan.compute_time_s,
                                   f"system{system} answered step {reply.step} request "
                                   f"{reply.request_seq}, not step {t} request {msg.header.seq}")
            elif age > deadline:  # a plan older than its deadline is never flown
                log.warning("late plan not flown", extra=fields(
                    system=system, step=t, age_s=round(age, 4), deadline_s=deadline))
                plan = Plan.failed(system, PlanStatus.TIMEOUT, plan.compute_time_s,
                                   f"plan {age:.3f} s old, past its {deadline:g} s deadline")
                plan.info["late_s"] = round(age, 4)
        except TimeoutError as err:
            plan = Plan.failed(system, PlanStatus.TIMEOUT, time.perf_counter() - t0, str(err))
            plan.info["no_reply"] = True
        except bus.QueryError as err:
            status = (PlanStatus.INVALID_INPUT if err.code == common_pb2.ERROR_CODE_INVALID
                      else PlanStatus.ERROR)
            plan = Plan.failed(system, status, time.perf_counter() - t0, f"system{system}: {err}")
            if err.code == common_pb2.ERROR_CODE_UNPREPARED:
                plan.info["unprepared"] = True
        except rejections.CodecError as err:
            rejections.rejected("Plan", err, log, key=base)
            plan = Plan.failed(system, PlanStatus.ERROR, time.perf_counter() - t0, str(err))
        return plan


_OBJ = Objective.MISSION_TIME


class StackVehicle:
    """The vehicle port over MAVLink: a setpoint due at a simulated time, then the state.

    ``ensure_offboard`` is called while the vehicle is not flying offboard: the
    session pauses the mission there (nothing advances: the clock is lockstep).
    """

    def __init__(self, b: Bus, link: VehicleLink, dt_s: float,
                 ensure_offboard: Callable[[], None]):
        self.b = b
        self.link = link
        self.dt_s = dt_s
        self.ensure_offboard = ensure_offboard
        self.base_ms = 0  # the vehicle's boot time (ms) at the mission's τ = 0
        self.due_ms = 0
        self.sent = 0.0  # perf_counter when the last setpoint left

    def command(self, target: Array, control: Array, after_s: float) -> None:
        self.due_ms = self.base_ms + round((self.b.clock.now_s + after_s) * 1000)
        self.sent = self.link.send_setpoint(np.asarray(target, dtype=float), self.due_ms)

    def observe(self) -> Array:
        """The state at or after the setpoint's due time; the flight lasts ΔT of sim time."""
        state = self.read_state(self.due_ms)
        self.b.clock.advance(self.dt_s)
        return state

    def read_state(self, min_ms: int) -> Array:
        """The vehicle's state at or after ``min_ms``; pauses while the vehicle is not flying
        offboard (lost, or holding), aborts after ``vehicle_timeout_s`` without it otherwise."""
        deadline = time.monotonic() + self.b.stack.vehicle_timeout_s
        while True:
            got = self.link.wait_state(min_ms, 0.25, self.b.stop)
            if got is not None:
                return got[1]
            if self.b.stop.is_set():
                raise Aborted("stopped")
            if not self.link.offboard():
                self.ensure_offboard()
                deadline = time.monotonic() + self.b.stack.vehicle_timeout_s
            elif time.monotonic() > deadline:
                raise Aborted(f"no vehicle state at or after {min_ms} ms")

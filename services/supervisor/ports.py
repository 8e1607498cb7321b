"""The mission step's ports over the stack: fires from the EWS, plans from the planner
services (Zenoh queries), the vehicle over MAVLink.

Each adapter turns a port call into messages and back, checking every reply
before it acts (services/common/convert/). Time is the lockstep SimClock
(services/common/clock.py): the fires' sub-steps and the vehicle's ΔT
advance it.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import zenoh
from google.protobuf.message import Message

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.ports import KeepOut, PlanRequest
from dualpilot.model.dynamics import Array
from dualpilot.model.field_forecast import forecast_step_substeps
from dualpilot.model.fire import FireParams, FireSnapshot
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.geometry import Rect
from dualpilot.model.stale_fire import StaleFireParams, credible_margin_m
from dualpilot.plan import Plan
from dualpilot.spec import MissionSpec
from services.common import bus, keys, rejections, wire
from services.common.clock import SimClock
from services.common.convert import fire as fire_convert
from services.common.convert import plan as plan_convert
from services.common.convert import vehicle as vehicle_convert
from services.common.log import fields, vehicle_thread
from services.msgs import fire_pb2, plan_pb2

from .link import VehicleLink
from .pool import PlannerPool

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
    #: how long a forecast query to the EWS waits (wall s); past it the step flies without
    #: the forecast (the forecast_stale fault)
    forecast_timeout_s: float = 10.0
    #: a paced (real-time) mission waits for a forecast at most this many control periods
    #: (wall s, as the plan deadlines; never longer than ``forecast_timeout_s``): the step keeps
    #: its beat and flies without a forecast that comes later (forecast_stale)
    forecast_deadline_periods: float = 0.5

    def forecast_wait_s(self, dt_s: float, speed_factor: float) -> float:
        """How long a forecast query waits (wall s): ``forecast_timeout_s`` in lockstep
        (speed factor 0), else ``forecast_deadline_periods`` × ΔT at most."""
        if speed_factor <= 0:
            return self.forecast_timeout_s
        return min(self.forecast_timeout_s, self.forecast_deadline_periods * dt_s)


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

    def query(self, key: str, msg: Message, timeout_s: float,
              trusted: bus.Trusted = None) -> tuple[bytes, str]:
        """The first trusted reply's (payload, encoding) to ``msg`` on ``key`` (bus.request:
        TimeoutError, QueryError); the one seam a unit test replaces."""
        return bus.request(self.session, key, msg, timeout_s, self.stop, trusted=trusted)

    def trusted(self, service: str) -> str | None:
        """Whose replies count for ``service``: the token holder's Zenoh id ("" nobody yet);
        None (anyone) without a tracker."""
        return None if self.live is None else self.live.holder(service)


class StackFires:
    """The fire port over the EWS's ``ews/command`` queryable.

    Sub-steps the EWS does not confirm (gone, or no answer) are owed: the fire
    data then ages (:meth:`age_s`) and the planners get it grown by
    :meth:`margin_m` until an EWS is back, reset and replayed to the same fire
    world (:meth:`snapshot` catches up first). A reset carries the mission's
    configuration: the EWS runs its reading's fire process.

    :meth:`forecast` asks the EWS for the occupancy forecast of exactly the fire
    state the step plans on (its revision: the sub-steps done), as the
    in-process port makes it. Without one (fire data owed, the EWS gone, late,
    refusing or answering with another revision, a reply that does not decode)
    the step flies without it, the paper's planners and threat rule: each such
    step is a ``forecast_stale`` fault (:meth:`take_faults`), and every answer's
    cost is kept for the step record (:meth:`take_costs`).
    """

    def __init__(self, b: Bus, spec: MissionSpec, config: MissionConfig,
                 on_caught_up: Callable[[int, int], None] | None = None):
        self.b = b
        self.spec = spec
        self.config = config
        self.params: FireParams = config.reading().fire
        self.on_caught_up = on_caught_up
        #: (step, sub-steps, keep-out) of every FireAdvance the fire world should have had
        self.history: list[tuple[int, int, KeepOut | None]] = []
        self.owed = 0
        self.msg: fire_pb2.FireState | None = None
        self.current = FireSnapshot(regions=(), hulls=())
        self.step = 0  # the mission step under way (begin_step)
        self._forecasts: dict[tuple[int, int], OccupancyForecast | None] = {}
        self._faults: list[str] = []
        self._costs: list[dict[str, object]] = []
        self._received: list[tuple[float, float, int]] = []  # (compute s, wall s, bytes)
        self._missing = 0  # steps that flew without the forecast they asked for
        self._missing_step = -1

    # -- messages ---------------------------------------------------------------------------------
    def _command(self, cmd: fire_pb2.FireCommand) -> fire_pb2.FireUpdate:
        key = keys.fire_command(self.b.uav)
        try:
            payload, enc = self.b.query(key, cmd, self.b.stack.fire_timeout_s,
                                        trusted=self.b.trusted("ews"))
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
            snap = fire_convert.snapshot_from_msg(msg)
        except rejections.CodecError as err:
            rejections.rejected("FireState", err, log)
            raise Aborted(f"EWS sent an invalid fire state: {err}") from err
        self.msg, self.current = msg, snap
        return snap

    def _reset_msg(self) -> fire_pb2.FireCommand:
        return fire_convert.fire_reset_msg(self.b.mission_id, self.spec.seed,
                                           self.spec.area_size_m, self.config, self.b.stamper,
                                           self.b.clock.now_s)

    def _advance_msg(self, t: int, n: int, keep_out: KeepOut | None,
                     paced: bool) -> fire_pb2.FireCommand:
        return fire_convert.fire_advance_msg(self.b.mission_id, t, n, keep_out,
                                             self.b.clock if paced else None, self.b.stamper)

    def _check_substep(self, state: fire_pb2.FireState) -> None:
        """The EWS must run the mission's T_f: its sub-steps are the mission's clock."""
        if not np.isclose(state.substep_s, self.params.substep_s, rtol=1e-12, atol=0.0):
            raise Aborted(f"the EWS runs T_f = {state.substep_s:g} s, the mission "
                          f"{self.params.substep_s:g} s")

    def reset(self) -> FireSnapshot:
        """Start the mission's fire process; returns its first state. Raises Aborted."""
        first = self._command(self._reset_msg()).states[0]
        self._check_substep(first)
        return self._take(first)

    def replay(self) -> None:
        """Reset the EWS and replay every recorded advance (unpaced): the fire world the
        mission had, whatever the EWS lost. Raises Aborted when the EWS does not answer."""
        last = self._command(self._reset_msg()).states[-1]
        self._check_substep(last)
        for t, n, keep in self.history:
            if n:
                last = self._command(self._advance_msg(t, n, keep, paced=False)).states[-1]
        self._take(last)
        self.owed = 0

    # -- the port ---------------------------------------------------------------------------------
    def begin_step(self, t: int) -> None:
        self.step = t

    def snapshot(self) -> FireSnapshot:
        self._catch_up()
        return self.current

    def revision(self) -> int:
        """The fire state's revision: its sub-steps since the mission began."""
        return int(self.msg.substeps_done) if self.msg is not None else 0

    def forecast(self, substeps_per_step: int) -> OccupancyForecast | None:
        """The EWS's forecast from :meth:`snapshot`'s state for time-steps of
        ``substeps_per_step`` sub-steps (kept until the fires advance); None when there is
        none to be had (a ``forecast_stale`` fault, one a step: fire data owed, the EWS gone, no
        answer or a refused one; a refused or missing answer is not asked again for the same
        revision and length)."""
        n = forecast_step_substeps(self.params, substeps_per_step)
        if self.owed or not self.b.alive("ews"):  # the state it would start from is gone by
            why = (f"fire data {self.age_s():g} s old" if self.owed else "the EWS is gone")
            self._no_forecast(why)
            return None
        key = (self.revision(), n)
        if key not in self._forecasts:
            self._forecasts = {k: v for k, v in self._forecasts.items() if k[0] == key[0]}
            self._forecasts[key] = self._ask_forecast(*key)
        elif self._forecasts[key] is None:
            self._no_forecast(f"the EWS gave no forecast of revision {key[0]}")
        return self._forecasts[key]

    def _ask_forecast(self, revision: int, n: int) -> OccupancyForecast | None:
        cmd = fire_convert.fire_forecast_query_msg(self.b.mission_id, self.step, revision, n,
                                                   self.b.stamper, self.b.clock.now_s)
        key = keys.fire_command(self.b.uav)
        t0 = time.perf_counter()
        speed = self.b.clock.speed_factor
        try:
            payload, enc = self.b.query(key, cmd, self.b.stack.forecast_wait_s(self.b.dt_s, speed),
                                        trusted=self.b.trusted("ews"))
            update = wire.parse(payload, fire_pb2.FireUpdate, enc)
            fc = self._checked_forecast(update, revision)
        except rejections.CodecError as err:
            rejections.rejected("FireForecast", err, log, key=key)
            self._no_forecast(f"refused: {err}")
            return None
        except TimeoutError as err:
            if self.b.stop.is_set():
                raise Aborted("stopped") from err
            self._no_forecast(f"late: {err}")
            return None
        except bus.QueryError as err:
            self._no_forecast(str(err))
            return None
        fc.memo[fire_convert.WIRE_GRID] = update.forecast.occupancy  # sent on as it came
        wall = time.perf_counter() - t0
        compute = update.forecast.compute_s
        self._received.append((compute, wall, len(payload)))
        # its age when the step plans on it: the simulated time the wait took (0 in lockstep,
        # where the clock stands still while the step waits)
        self._costs.append({"revision": revision, "substeps_per_step": n,
                            "compute_s": round(compute, 6), "wall_s": round(wall, 6),
                            "bytes": len(payload), "age_s": round(wall * speed, 6)})
        return fc

    def _checked_forecast(self, update: fire_pb2.FireUpdate,
                          revision: int) -> OccupancyForecast:
        """The reply's forecast, if it is the one asked for (CodecError otherwise)."""
        if not update.HasField("forecast"):
            raise rejections.invalid("the EWS replied without a forecast")
        got = update.forecast
        if got.substeps_done != revision or got.step != self.step:
            raise rejections.invalid(
                f"a forecast of step {got.step} from fire revision {got.substeps_done}, asked "
                f"for step {self.step} from {revision}", rejections.Reason.STALE)
        if not np.isclose(got.substep_s, self.params.substep_s, rtol=1e-12, atol=0.0):
            raise rejections.invalid(f"a forecast at T_f = {got.substep_s:g} s, the mission "
                                     f"runs {self.params.substep_s:g} s")
        fc = fire_convert.occupancy_from_msg(got)
        if fc is None:
            raise rejections.invalid("the EWS's forecast carries no occupancy grid")
        return fc

    def _no_forecast(self, why: str) -> None:
        """A forecast_stale fault, one a step however often the step asks."""
        if self._missing_step == self.step:
            return
        self._missing_step = self.step
        log.warning("no fire forecast for this step: flying without it", extra=fields(
            step=self.step, revision=self.revision(), reason=why))
        self._faults.append(why)
        self._missing += 1

    def forecast_summary(self) -> dict[str, object]:
        """The mission's forecasts: how many came and went missing, the medians of the EWS's
        compute time, the query's wall time (s) and the reply's size (bytes)."""
        if not self._received and not self._missing:
            return {}
        got = np.array(self._received, dtype=float).reshape(-1, 3)
        med = np.median(got, axis=0) if len(got) else np.full(3, np.nan)
        return {"received": len(got), "missing": self._missing,
                "median_compute_s": round(float(med[0]), 6),
                "median_wall_s": round(float(med[1]), 6), "median_bytes": float(med[2])}

    def take_faults(self) -> list[str]:
        """Why each forecast asked since the last call could not be had."""
        out, self._faults = self._faults, []
        return out

    def take_costs(self) -> list[dict[str, object]]:
        """Each forecast received since the last call: its revision, time-step length, the
        EWS's compute time, the query's wall time, its size (bytes) and age (s)."""
        out, self._costs = self._costs, []
        return out

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
        cmd = self._advance_msg(t, n, keep_out, paced=True)  # sub-step k due at τ_t + k·T_f
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
                           else fire_convert.regions_from_msg(msg))
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


class StackPlanners:
    """The planner port over the planner pool (services/supervisor/pool.py).

    A planner is asked only while its liveliness token is up and the pool has
    not demoted it. Each request goes to the mission's replica and comes back
    checked (the pool's rules). A planner that was not prepared for this mission
    (it was restarted) is prepared again and asked once more. Operator waypoints
    travel on their own key, with a revision the requests name.
    """

    def __init__(self, b: Bus, spec: MissionSpec, config: MissionConfig, pool: PlannerPool):
        self.b = b
        self.spec = spec
        self.config = config
        self.pool = pool
        self.waypoints = vehicle_convert.Waypoints(b.mission_id, 0, None)
        self.last_info: dict[int, dict[str, object]] = {}
        self.compute = 0.0  # this step's planners' compute time (s)
        self._background: ThreadPoolExecutor | None = None  # launch/collect

    def begin_step(self) -> None:
        self.compute = 0.0
        self.last_info = {}
        self.pool.begin_step()

    def available(self, system: int) -> bool:
        return self.b.alive(f"system{system}") and self.pool.available(system)

    def uses_forecast(self, system: int) -> bool:
        """Under ``risk`` both systems' planners are risk-aware (dualpilot.planners)."""
        return self.config.risk

    # -- messages ---------------------------------------------------------------------------------
    def _query_msg(self, request: PlanRequest) -> plan_pb2.PlanRequest:
        query = plan_convert.PlanQuery(request, self.b.mission_id, 0,
                                       self.b.deadline_s(request.system),
                                       self.waypoints.revision)
        return plan_convert.plan_query_msg(query, self.b.stamper, self.b.clock.now_s)

    def prepare(self, systems: list[int]) -> None:
        """Warm-up: every replica of each planner builds this mission's planner from the spec
        and the configuration. Raises Aborted when no replica of a system could."""
        for system in systems:
            prep = plan_convert.Prepare(self.b.mission_id, system, self.spec, self.config,
                                        deadline_s=self.b.deadline_s(system))
            msg = plan_convert.prepare_msg(prep, self.b.stamper, self.b.clock.now_s)
            try:
                self.pool.prepare(system, msg)
            except RuntimeError as err:
                raise Aborted(str(err)) from err

    def set_waypoints(self, points: Array | None, publish: bool) -> None:
        """A new revision of the operator waypoints, published on their key."""
        self.waypoints = vehicle_convert.Waypoints(self.b.mission_id,
                                                   self.waypoints.revision + 1, points)
        if publish:
            self.publish_waypoints()

    def publish_waypoints(self) -> None:
        pub = self.b.session.declare_publisher(keys.waypoints(self.b.uav))
        bus.put(pub, "", vehicle_convert.waypoints_msg(self.waypoints, self.b.stamper))
        pub.undeclare()

    # -- the port ---------------------------------------------------------------------------------
    def launch(self, request: PlanRequest) -> object:
        """Ask in the background (the concurrent supervisor's System 2): the query leaves now,
        on a thread of its own; :meth:`collect` takes its checked reply."""
        if self._background is None:
            self._background = ThreadPoolExecutor(max_workers=1, thread_name_prefix="deliberate",
                                                  initializer=vehicle_thread(lambda: None))
        return self._background.submit(self._ask, request, False)

    def collect(self, ticket: object) -> Plan:
        """The launched request's plan (a failed plan when it was late or not this step's)."""
        assert isinstance(ticket, Future)
        plan: Plan = ticket.result()
        self.pool.count_background(plan)
        return plan

    def close(self) -> None:
        if self._background is not None:
            self._background.shutdown(wait=False, cancel_futures=True)

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
        self.pool.count(request.system, plan)
        self.compute += plan.compute_time_s
        if request.system == 1:
            self.last_info[1] = dict(plan.info)
        return plan

    def _ask(self, request: PlanRequest, account: bool = True) -> Plan:
        plan = self.pool.ask(request.system, request.t, self._query_msg(request), account)
        if self.b.stop.is_set():
            raise Aborted("stopped")
        return plan


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

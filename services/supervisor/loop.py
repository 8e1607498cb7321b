"""The distributed mission loop: the mission step over Zenoh and MAVLink.

Same step semantics as the in-process loop (see its docstring), with the
fires in the EWS, the planners in their services and the vehicle behind
MAVLink. Step t, at simulated time τ_t (services/common/clock.py):

1. the fire state is the EWS's last FireState; the vehicle state x_t the last
   LOCAL_POSITION_NED (republished on ``vehicle/state``);
2. Ξ_t, P_t, A_t, Ψ_t, S_t from :meth:`Supervisor.decide` (published on
   ``supervisor/decision``); ``s1``/``s2`` force the system;
3. the chosen system is queried (``plan/system<k>``), then the other one if
   the plan is not OK (``cc`` only); planning takes T_s — the planners'
   reported compute times (``--timing measured``) or the paper's 155 ms / 5 s
   (``--timing paper``);
4. the plan's next state x_{t+1|t} leaves at once as SET_POSITION_TARGET_LOCAL_NED
   (type_mask 3520), due at τ_t + n·T_f + ΔT with n = ⌈T_s/T_f⌉; no OK plan:
   the braking state;
5. the EWS propagates the n sub-steps of the planning interval (a
   FireAdvance query); the mission fails if a region came within d_safe of
   the idle vehicle (its step towards the setpoint then does not count);
6. the vehicle flies one step of Eq. (1) and reports x_{t+1}: success on
   entering G, failure when the motion passes within d_safe of a region
   (exact segment distance) or at the step limit.

Before step 0 the supervisor takes the vehicle (services/supervisor/link.py:
setpoints, offboard mode, arm) and downloads its mission. Before every step
(and while it waits for the vehicle's state) it checks that the vehicle is
still flying offboard: a vehicle lost for 3 s, or put in hold by the operator
or the failsafe, pauses the mission (MissionEvent PAUSED; nothing advances:
the clock is lockstep) until it is back (RESUMED; a vehicle that was lost is
taken again). A new mission on the vehicle (uploaded from a ground station)
becomes System 1's operator waypoints at the next step: they go with every
PlanRequest (``mission.operator_waypoints``) and, once the planners are
prepared, on ``operator/waypoints``. A mission that was never uploaded
(``MIS_ID`` 0) keeps the ``--waypoints`` flag's.

Faults (README, Tests → Faults): a planner whose liveliness token is gone is
not asked (``s<k>:unavailable``); with none alive the step brakes and, once
at rest, the mission pauses until one is back. A plan reply older than its
deadline, or for another step, is never flown. FireAdvance sub-steps the EWS
does not confirm are owed; the data is then stale and the planners avoid the
last known hulls grown by the fastest credible spread
(dualpilot/stale_fire.py) until an EWS is reset and replayed. Every
step is appended to ``steps.jsonl`` as it happens (dualpilot.mission.records.StepLog);
a supervisor restarted with the same mission id and run directory resumes
from it (:meth:`StackMission._resume`).

Records (:class:`MissionResult` / :class:`StepRecord`) are the in-process
ones, so ``summary.json``, ``steps.csv`` and ``trace.json`` have the same
format and :func:`dualpilot.viz.mission.make_figures` draws them; ``latency.csv``
adds the tick → setpoint latency of every step. Which path System 1 used is
in the published Decision (``plan_source``, ``operator_rejected``,
``operator_waypoints``), in ``steps.csv`` (``source`` plus the columns
``operator_waypoints`` and ``operator_rejected``) and in ``trace.json``.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import zenoh

from dualpilot.mission.records import (
    STEP_LOG,
    StepLog,
    read_step_log,
    record_to_json,
    result_from_log,
)
from dualpilot.mission.step import (
    Controller,
    MissionConfig,
    MissionParams,
    MissionResult,
    StepRecord,
    Timing,
    attention_distance,
    brake_control,
    flight_outcome,
    nearest_region_distance,
    planning_order,
    planning_time,
)
from dualpilot.model.dynamics import Array, DynamicsParams, step
from dualpilot.model.fire import FireParams, FireSnapshot, substeps_for
from dualpilot.model.stale_fire import StaleFireParams, credible_margin_m
from dualpilot.plan import Objective, Plan, PlanStatus
from dualpilot.supervisor.decision import Decision, Supervisor, SupervisorParams
from services.common import bus, codec, keys
from services.common.clock import SimClock
from services.common.log import fields
from services.msgs import common_pb2, fire_pb2, plan_pb2, supervisor_pb2, vehicle_pb2

from .faults import grown_fire_msg
from .link import OffboardError, VehicleLink
from .runlog import Latency, OperatorRecord, write_operator_columns

log = logging.getLogger(__name__)

class Aborted(RuntimeError):
    """The stack could not finish the mission (a service or the vehicle stopped answering)."""


@dataclass(frozen=True)
class StackParams:
    """How the supervisor talks to the stack."""

    plan_deadline_s: tuple[float, float] = (30.0, 120.0)  # System 1, System 2 (wall s)
    fire_timeout_s: float = 30.0
    vehicle_timeout_s: float = 10.0
    altitude_m: float = 50.0
    offboard_timeout_s: float = 30.0  # taking the vehicle (heartbeat, position, mode, arm)
    mission_wait_s: float = 5.0       # downloading the vehicle's mission before step 0
    prepare_timeout_s: float = 60.0   # a planner's warm-up (not a flight plan: no deadline)
    pause_limit_s: float = 300.0      # abort when paused for longer
    #: fire data at least this old (simulated s) is stale (dualpilot/stale_fire.py)
    stale: StaleFireParams = StaleFireParams()
    #: flush the step record (steps.jsonl) at most this long after a line (s); 0: every line
    record_flush_s: float = 0.0


class StackMission:
    """One mission flown through the services; ``run()`` flies it, ``step()`` is one tick."""

    def __init__(
        self,
        session: zenoh.Session,
        link: VehicleLink,
        uav: str,
        mission_id: str,
        controller: Controller,
        seed: int,
        timing: Timing,
        clock: SimClock,
        stop: threading.Event,
        goal: codec.Rect = MissionConfig().goal,
        area_size_m: float = 1000.0,
        waypoints: Array | None = None,
        params: MissionParams = MissionParams(),
        dynamics: DynamicsParams = DynamicsParams(),
        supervisor_params: SupervisorParams = SupervisorParams(),
        stack: StackParams = StackParams(),
        live: bus.Liveliness | None = None,
        record_dir: Path | None = None,
    ):
        self.session = session
        self.live = live
        self.record_dir = record_dir
        self.step_log: StepLog | None = None
        #: (step, sub-steps) of every FireAdvance the fire world should have had, in order
        self.fire_history: list[tuple[int, int]] = []
        self.fire_owed = 0  # sub-steps the EWS did not confirm (the fire data's age / T_f)
        self.resumed_at: int | None = None
        self.holding = ""
        self.link = link
        self.uav = uav
        self.mission_id = mission_id
        self.controller = controller
        self.seed = seed
        self.timing = timing
        self.clock = clock
        self.stop = stop
        self.params = params
        self.dyn = dynamics
        self.stack = stack
        self.goal = goal
        self.area_size_m = area_size_m
        self.waypoints = waypoints
        self.stamper = codec.Stamper("supervisor", uav)
        # the supervisor's stream of SeedSequence(seed).spawn(2), as the in-process mission
        sup_rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[1])
        self.supervisor = Supervisor(sup_rng, supervisor_params)
        self.pubs = {
            name: session.declare_publisher(key) for name, key in (
                ("decision", keys.decision(uav)), ("state", keys.vehicle_state(uav)),
                ("event", keys.mission_event(uav)), ("clock", keys.clock(uav)),
                ("waypoints", keys.waypoints(uav)))
        }
        self.waypoints_rev = 0
        self.prepared = False
        self.operator: list[OperatorRecord] = []
        self.latency = Latency()
        self.request_wall = self.service_time = 0.0
        self.fire_params = FireParams()
        self.fire_msg: fire_pb2.FireState | None = None
        self.snapshot = FireSnapshot(regions=(), hulls=())
        self.state = np.zeros(4)
        self.base_ms = 0
        self.prev_control = np.zeros(dynamics.dim)
        self.result: MissionResult | None = None
        self.done = False

    # -- bus helpers ------------------------------------------------------------------------------
    def _now(self) -> float:
        return self.clock.now_s

    def _fire_command(self, cmd: fire_pb2.FireCommand) -> fire_pb2.FireUpdate:
        cmd.mission_id = self.mission_id
        self.stamper.stamp(cmd.header, self._now())
        key = keys.fire_command(self.uav)
        try:
            payload, enc = bus.request(self.session, key, cmd, self.stack.fire_timeout_s,
                                       self.stop)
            update = codec.parse(payload, fire_pb2.FireUpdate, enc)
        except codec.CodecError as err:
            codec.rejected("FireUpdate", err, log, key=key)
            raise Aborted(f"EWS: {err}") from err
        except (TimeoutError, bus.QueryError) as err:
            raise Aborted(f"EWS: {err}") from err
        if not update.states:
            raise Aborted("EWS replied without a fire state")
        return update

    def _take_fires(self, msg: fire_pb2.FireState) -> FireSnapshot:
        try:
            snap = codec.snapshot_from_msg(msg)
        except codec.CodecError as err:
            codec.rejected("FireState", err, log)
            raise Aborted(f"EWS sent an invalid fire state: {err}") from err
        self.fire_msg, self.snapshot = msg, snap
        return snap

    def _publish_state(self, t: int) -> None:
        m = vehicle_pb2.VehicleState()
        self.stamper.stamp(m.header, self._now())
        codec.state_to_msg(self.state, t, m, self.stack.altitude_m)
        bus.put(self.pubs["state"], "", m)

    def _alive(self, service: str) -> bool:
        """The service's liveliness token is up (always True without a tracker)."""
        return self.live is None or not self.live.missing({service})

    def _record(self, kind: str, **fields_: object) -> None:
        """Append a line to the step record (steps.jsonl), if there is one."""
        if self.step_log is not None and not self.step_log.fh.closed:
            try:
                self.step_log.write(kind, wall_time_s=round(time.time(), 3), **fields_)
            except (OSError, ValueError) as err:  # a full disk must not stop the vehicle
                log.error("step record not written", extra=fields(error=str(err)))

    def _event(self, kind: supervisor_pb2.MissionEventKind, **kw: object) -> None:
        if kind != supervisor_pb2.MISSION_EVENT_KIND_STEP:
            self._record("event", event=supervisor_pb2.MissionEventKind.Name(kind).rsplit(
                "_", 1)[-1].lower(), **{k: v for k, v in kw.items() if k != "position"})
        m = supervisor_pb2.MissionEvent(kind=kind, mission_id=self.mission_id,
                                        controller=self.controller.value, seed=self.seed)
        self.stamper.stamp(m.header, self._now())
        pos = kw.pop("position", None)
        for k, v in kw.items():
            setattr(m, k, v)
        if pos is not None:
            m.position.east_m, m.position.north_m = (float(v) for v in np.asarray(pos)[:2])
        bus.put(self.pubs["event"], "", m)

    def _read_state(self, min_ms: int) -> Array:
        """The vehicle's state at or after ``min_ms``; pauses while the vehicle is not flying
        offboard (lost, or holding), aborts after ``vehicle_timeout_s`` without it otherwise."""
        deadline = time.monotonic() + self.stack.vehicle_timeout_s
        while True:
            got = self.link.wait_state(min_ms, 0.25, self.stop)
            if got is not None:
                return got[1]
            if self.stop.is_set():
                raise Aborted("stopped")
            if not self.link.offboard():
                self._ensure_offboard()
                deadline = time.monotonic() + self.stack.vehicle_timeout_s
            elif time.monotonic() > deadline:
                raise Aborted(f"no vehicle state at or after {min_ms} ms")

    # -- the vehicle ------------------------------------------------------------------------------
    def _take_vehicle(self) -> None:
        try:
            self.link.start_offboard(self.stop, self.stack.offboard_timeout_s)
        except OffboardError as err:
            raise Aborted(f"vehicle: {err}") from err
        if self.stop.is_set():
            raise Aborted("stopped")
        log.info("vehicle under offboard control", extra=fields(status=self.link.status()))

    def _ensure_offboard(self) -> None:
        """Pause while the vehicle is not flying offboard; take it again when it comes back."""
        if self.link.offboard():
            return
        t0 = time.monotonic()
        lost = not self.link.alive()
        reason = ("vehicle lost: no heartbeat for 3 s" if lost
                  else f"vehicle not flying offboard ({self.link.status()})")
        log.warning("mission paused", extra=fields(reason=reason))
        self._event(supervisor_pb2.MISSION_EVENT_KIND_PAUSED, message=reason,
                    step=self.result.steps if self.result else 0)
        while not self.link.offboard():
            if self.stop.is_set():
                raise Aborted("stopped")
            if time.monotonic() - t0 > self.stack.pause_limit_s:
                raise Aborted(f"paused for more than {self.stack.pause_limit_s:g} s: {reason}")
            if not self.link.alive():
                lost = True
            elif lost:  # back after a loss: take it again (the steps it still needs)
                lost = False
                try:
                    self.link.start_offboard(self.stop, self.stack.offboard_timeout_s)
                except OffboardError as err:
                    log.warning("could not take the vehicle back", extra=fields(error=str(err)))
            self.stop.wait(0.05)
        paused = time.monotonic() - t0
        log.info("mission resumed", extra=fields(paused_s=round(paused, 3)))
        self._event(supervisor_pb2.MISSION_EVENT_KIND_RESUMED,
                    message=f"paused {paused:.1f} s", step=self.result.steps if self.result else 0)

    def _update_waypoints(self) -> None:
        """Take a newly downloaded mission as the operator waypoints (module docstring)."""
        rev, wps, mission_id = self.link.operator_waypoints()
        if rev == 0 or rev == self.waypoints_rev:
            return
        self.waypoints_rev = rev
        if not mission_id:
            return  # never uploaded: the --waypoints flag's stay
        if wps is not None and not all(0.0 <= v <= self.area_size_m for v in wps.ravel()):
            log.error("operator waypoints outside the area ignored", extra=fields(
                mission_id=mission_id, n=len(wps)))
            return
        same = (wps is None and self.waypoints is None) or (
            wps is not None and self.waypoints is not None and wps.shape == self.waypoints.shape
            and np.allclose(wps, self.waypoints))
        if same:
            return
        self.waypoints = wps
        n = 0 if wps is None else len(wps)
        log.info("operator waypoints from the vehicle", extra=fields(
            mission_id=mission_id, n=n, waypoints=";".join(
                f"{e:.1f},{north:.1f}" for e, north in (wps if wps is not None else []))))
        if self.prepared:  # System 1 applies them at its next plan (the requests carry them too)
            bus.put(self.pubs["waypoints"], "", codec.waypoints_msg(wps, self.stamper))
        self._event(supervisor_pb2.MISSION_EVENT_KIND_WAYPOINTS,
                    message=f"{n} operator waypoints (mission {mission_id:g})",
                    step=self.result.steps if self.result else 0)

    # -- start ------------------------------------------------------------------------------------
    def start(self) -> None:
        """Read the vehicle's state, reset the EWS and announce the mission."""
        self._take_vehicle()
        if not self.link.wait_mission(self.stack.mission_wait_s, self.stop):
            log.warning("the vehicle's mission was not downloaded before the start")
        self._update_waypoints()
        got = self.link.wait_state(0, self.stack.vehicle_timeout_s, self.stop)
        if got is None:
            raise Aborted("no LOCAL_POSITION_NED from the vehicle")
        prior = self._prior_record()
        if prior is not None:
            self._resume(prior, got)
            return
        self.base_ms, x0 = got
        self.state = x0  # at rest at boot: the in-process mission's hover_state(start)
        config = MissionConfig(start=(float(x0[0]), float(x0[1])), goal=self.goal,
                               area_size_m=self.area_size_m)
        self.result = MissionResult(controller=self.controller.value, seed=self.seed,
                                    timing=self.timing.value, config=config)
        reset = fire_pb2.FireCommand()
        reset.reset.seed = self.seed
        first = self._fire_command(reset).states[0]
        self.fire_params = replace(FireParams(), substep_s=first.substep_s)
        snap = self._take_fires(first)
        if nearest_region_distance(self.state[:2], snap.regions) < self.params.d_safe_m:
            raise Aborted("the start lies within d_safe of a fire")
        self._prepare({Controller.CC: [1, 2], Controller.S1: [1],
                       Controller.S2: [2]}[self.controller])
        self.prepared = True
        bus.settle_heap()  # everything the mission needs is imported and built
        self._open_record()
        self._publish_state(0)
        self._event(supervisor_pb2.MISSION_EVENT_KIND_STARTED, position=self.state,
                    message=f"timing={self.timing.value} speed_factor={self.clock.speed_factor}")
        log.info("mission started", extra=fields(
            mission=self.mission_id, controller=self.controller.value, seed=self.seed,
            timing=self.timing.value, start_east_m=float(x0[0]), start_north_m=float(x0[1])))

    # -- the step record and a restarted supervisor ----------------------------------------------
    def _open_record(self) -> None:
        """Start ``steps.jsonl`` in the run directory: the mission line first."""
        if self.record_dir is None or self.result is None:
            return
        path = self.record_dir / STEP_LOG
        fresh = self.resumed_at is None
        if fresh and path.exists():
            path.replace(path.with_suffix(f".{int(time.time())}.jsonl"))  # another mission's
        self.step_log = StepLog(path, flush_every_s=self.stack.record_flush_s)
        if fresh:
            c = self.result.config
            self._record("mission", mission_id=self.mission_id, controller=self.controller.value,
                         seed=self.seed, timing=self.timing.value, start=list(c.start),
                         goal=[c.goal.center_x, c.goal.center_y, c.goal.width, c.goal.height],
                         area_size_m=c.area_size_m, substep_s=self.fire_params.substep_s,
                         dt_s=self.dyn.dt_s, speed_factor=self.clock.speed_factor)

    def _prior_record(self) -> list[dict[str, object]] | None:
        """This mission's record left by a supervisor that stopped before its end, if any."""
        if self.record_dir is None or not (self.record_dir / STEP_LOG).is_file():
            return None
        try:
            entries = read_step_log(self.record_dir / STEP_LOG)
        except (OSError, UnicodeDecodeError) as err:
            log.warning("unreadable step record: a new mission", extra=fields(error=str(err)))
            return None
        head = next((e for e in entries if e.get("kind") == "mission"), None)
        if head is None or head.get("mission_id") != self.mission_id or any(
                e.get("kind") == "end" for e in entries):
            return None
        return entries

    def _resume(self, entries: list[dict[str, object]], got: tuple[int, Array]) -> None:
        """Pick the mission up where its record ends, from the vehicle's state now.

        The record gives the steps flown (rebuilt into :attr:`result`), the
        attention stream (each recorded decision is replayed, so the supervisor's
        random stream and Ψ continue as if it had never stopped), the fire
        history (the EWS is reset and replayed to the same fire world) and the
        simulated time; the vehicle (holding since the failsafe) gives x_t.
        """
        self.result = result_from_log(entries, self.dyn.dt_s)  # type: ignore[arg-type]
        head = next(e for e in entries if e.get("kind") == "mission")
        steps = [e for e in entries if e.get("kind") == "step"]
        for rec in self.result.records:
            self.supervisor.decide(rec.t, rec.d_t)
        if self.result.records:
            self.prev_control = np.asarray(self.result.records[-1].control, dtype=float)
        self.fire_history = [(int(e["t"]), int(e["fire_substeps"]))  # type: ignore[call-overload]
                             for e in steps]
        sim_s = float(steps[-1].get("sim_time_s", 0.0)) if steps else 0.0  # type: ignore[arg-type]
        self.clock.now_s = sim_s
        vehicle_ms, self.state = got
        self.base_ms = vehicle_ms - round(sim_s * 1000)
        self.fire_params = replace(FireParams(), substep_s=float(
            head.get("substep_s", FireParams().substep_s)))  # type: ignore[arg-type]
        self.resumed_at = self.result.steps
        self._replay_fires()
        self._prepare({Controller.CC: [1, 2], Controller.S1: [1],
                       Controller.S2: [2]}[self.controller])
        self.prepared = True
        bus.settle_heap()  # everything the mission needs is imported and built
        self._open_record()
        self._publish_state(self.result.steps)
        msg = (f"supervisor restarted: mission picked up at step {self.result.steps} from the "
               f"vehicle's state ({self.state[0]:.1f}, {self.state[1]:.1f})")
        log.info("mission resumed from its record", extra=fields(
            mission=self.mission_id, step=self.result.steps, fire_substeps=sum(
                n for _, n in self.fire_history)))
        self._event(supervisor_pb2.MISSION_EVENT_KIND_RESUMED, message=msg,
                    step=self.result.steps, position=self.state)

    # -- fires the supervisor cannot see ----------------------------------------------------------
    def _replay_fires(self) -> None:
        """Reset the EWS and replay every recorded advance (unpaced): the fire world the
        mission had, whatever the EWS lost. Raises Aborted when the EWS does not answer."""
        reset = fire_pb2.FireCommand()
        reset.reset.seed = self.seed
        last = self._fire_command(reset).states[-1]
        for t, n in self.fire_history:
            if n:
                cmd = fire_pb2.FireCommand()
                cmd.advance.step, cmd.advance.substeps = t, n
                last = self._fire_command(cmd).states[-1]
        self._take_fires(last)
        self.fire_owed = 0

    def _catch_up_fires(self) -> bool:
        """With sub-steps owed and the EWS alive: replay; True if the caught-up fires are
        within d_safe of the vehicle (the mission has failed)."""
        if not self.fire_owed or not self._alive("ews"):
            return False
        owed = self.fire_owed
        try:
            self._replay_fires()
        except Aborted as err:
            if self.stop.is_set():
                raise
            log.warning("EWS not caught up yet", extra=fields(error=str(err)))
            return False
        log.info("fire data fresh again: EWS caught up", extra=fields(owed_substeps=owed))
        self._record("fires_caught_up", owed_substeps=owed, fires_active=len(
            self.snapshot.regions))
        return nearest_region_distance(self.state[:2], self.snapshot.regions) < \
            self.params.d_safe_m

    def fire_age_s(self) -> float:
        """Simulated s the fire process should have advanced beyond the last FireState."""
        return self.fire_owed * self.fire_params.substep_s

    def fire_stale(self) -> bool:
        return self.fire_age_s() >= self.stack.stale.stale_after_s

    def fire_margin_m(self) -> float:
        """The margin the planners' hulls are grown by (0 while the data is fresh)."""
        if not self.fire_stale():
            return 0.0
        return credible_margin_m(self.fire_age_s(), self.fire_params, self.stack.stale)

    # -- planners that are gone ------------------------------------------------------------------
    def _systems(self) -> list[int]:
        return {Controller.CC: [1, 2], Controller.S1: [1], Controller.S2: [2]}[self.controller]

    def _hold_without_planners(self) -> None:
        """No planner of this controller alive and the vehicle at rest: pause (the vehicle holds,
        the lockstep clock and the fires wait) until one is back."""
        if self.live is None or any(self._alive(f"system{k}") for k in self._systems()):
            return
        if np.linalg.norm(self.state[self.dyn.dim:]) > 0.05:
            return  # still moving: this step brakes (no plan to fly)
        gone = ", ".join(f"system{k}" for k in self._systems())
        reason = f"holding: no planner alive ({gone}: liveliness token gone)"
        self.holding = reason
        t0 = time.monotonic()
        log.warning("mission paused", extra=fields(reason=reason))
        self._event(supervisor_pb2.MISSION_EVENT_KIND_PAUSED, message=reason,
                    step=self.result.steps if self.result else 0)
        while not any(self._alive(f"system{k}") for k in self._systems()):
            if self.stop.is_set():
                raise Aborted("stopped")
            if time.monotonic() - t0 > self.stack.pause_limit_s:
                raise Aborted(f"paused for more than {self.stack.pause_limit_s:g} s: {reason}")
            self.live.wait_any([f"system{k}" for k in self._systems()], 0.25, self.stop)
        back = [f"system{k}" for k in self._systems() if self._alive(f"system{k}")]
        try:  # a planner that came back has a fresh service: build this mission's planner
            self._prepare([int(b[-1]) for b in back])
        except Aborted as err:
            log.warning("planner back but not ready", extra=fields(error=str(err)))
        self.holding = ""
        paused = time.monotonic() - t0
        log.info("mission resumed", extra=fields(paused_s=round(paused, 3), back=",".join(back)))
        self._event(supervisor_pb2.MISSION_EVENT_KIND_RESUMED,
                    message=f"{', '.join(back)} back after {paused:.1f} s",
                    step=self.result.steps if self.result else 0)

    # -- one tick -------------------------------------------------------------------------------
    def _d_t(self, t: int, snapshot: FireSnapshot) -> float:
        return attention_distance(self.state[:2], snapshot, t, self.params)

    def _planning_time(self, plan: Plan) -> float:
        return planning_time(plan, self.timing, self.params)

    def _plan_request(self, system: int, t: int, objective: Objective,
                      prepare: bool = False) -> plan_pb2.PlanRequest:
        assert self.fire_msg is not None
        req = codec.PlanRequest(
            seq=0,
            mission=codec.MissionSpec(self.mission_id, self.seed, self.goal, self.area_size_m,
                                      self.waypoints),
            step=t, system=system, objective=objective, state=self.state,
            prev_control=self.prev_control, fires=self.snapshot,
            deadline_s=self.stack.plan_deadline_s[system - 1], prepare=prepare)
        fires = self.fire_msg
        margin = self.fire_margin_m()
        if margin > 0:  # stale: the last known fronts grown by the fastest credible spread
            fires = grown_fire_msg(fires, margin)
        return codec.plan_request_msg(req, fires, self.stamper, self._now())

    def _prepare(self, systems: list[int]) -> None:
        """Warm-up: each planner service builds this mission's planner before step 0."""
        for system in systems:
            msg = self._plan_request(system, 0, Objective.MISSION_TIME, prepare=True)
            try:
                payload, enc = bus.request(self.session, keys.plan(self.uav, system), msg,
                                           max(self.stack.plan_deadline_s[system - 1],
                                               self.stack.prepare_timeout_s), self.stop)
                codec.parse(payload, plan_pb2.Plan, enc)
            except (TimeoutError, bus.QueryError, codec.CodecError) as err:
                raise Aborted(f"system{system} could not prepare the mission: {err}") from err

    def _plan_with(self, system: int, t: int, decision: Decision) -> Plan:
        assert self.result is not None
        deadline = self.stack.plan_deadline_s[system - 1]
        msg = self._plan_request(system, t, decision.objective)
        t0 = time.perf_counter()
        key = keys.plan(self.uav, system)
        try:
            payload, enc = bus.request(self.session, key, msg, deadline, self.stop)
            reply = codec.parse(payload, plan_pb2.Plan, enc)
            plan = codec.plan_from_msg(reply, system)
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
        except bus.QueryError as err:
            status = (PlanStatus.INVALID_INPUT if err.code == common_pb2.ERROR_CODE_INVALID
                      else PlanStatus.ERROR)
            plan = Plan.failed(system, status, time.perf_counter() - t0, f"system{system}: {err}")
        except codec.CodecError as err:
            codec.rejected("Plan", err, log, key=key)
            plan = Plan.failed(system, PlanStatus.ERROR, time.perf_counter() - t0, str(err))
        self.request_wall += time.perf_counter() - t0
        if self.stop.is_set():
            raise Aborted("stopped")
        self.result.planning_time_s[f"s{system}"].append(plan.compute_time_s)
        return plan

    def _caught(self, update: fire_pb2.FireUpdate) -> bool:
        """Take each sub-step's state; True if a region came within d_safe of the idle vehicle."""
        last = len(update.states) - 1
        for k, msg in enumerate(update.states):
            try:  # the intermediate sub-steps only matter through their regions
                regions = (self._take_fires(msg).regions if k == last
                           else codec.regions_from_msg(msg))
            except codec.CodecError as err:
                codec.rejected("FireState", err, log)
                raise Aborted(f"EWS sent an invalid fire state: {err}") from err
            if nearest_region_distance(self.state[:2], regions) < self.params.d_safe_m:
                if k != last:
                    self._take_fires(msg)
                return True
        return False

    def _advance(self, t: int, n: int) -> bool:
        """Propagate ``n`` fire sub-steps from τ_t (now); True if the idle vehicle got caught.

        When the EWS is gone (no liveliness token, or no answer) the sub-steps
        are owed: the fire data ages (:meth:`fire_age_s`) until the EWS is back
        and :meth:`_catch_up_fires` replays them.
        """
        self.fire_history.append((t, n))
        if self.fire_owed or not self._alive("ews"):
            self.fire_owed += n
            self._pace(n)
            return False
        cmd = fire_pb2.FireCommand()
        cmd.advance.step, cmd.advance.substeps = t, n
        self._clock_msg(cmd.advance.clock)  # sub-step k is due at τ_t + k·T_f
        try:
            update = self._fire_command(cmd)
        except Aborted as err:
            if self.stop.is_set():
                raise
            log.warning("EWS did not advance the fires: data ageing", extra=fields(
                step=t, substeps=n, error=str(err)))
            self.fire_owed += n
            self._pace(n)
            return False
        self.clock.advance(n * self.fire_params.substep_s)
        return self._caught(update)

    def _pace(self, n: int) -> None:
        """The planning interval's n sub-steps pass on the clock without the EWS."""
        self.clock.advance(n * self.fire_params.substep_s)
        self.clock.sleep_until_now(self.stop)

    def _publish_step_start(self, decision: Decision, wanted: int, op: OperatorRecord,
                            fire: tuple[bool, float, float]) -> None:
        clock_msg = common_pb2.Clock()
        self._clock_msg(clock_msg)
        self.stamper.stamp(clock_msg.header, self._now())
        bus.put(self.pubs["clock"], "", clock_msg)
        msg = codec.decision_to_msg(decision, wanted, self.stamper, self._now())
        msg.plan_source, msg.operator_rejected = op.source, op.rejected
        msg.operator_waypoints, msg.operator_note = op.waypoints, op.note[:500]
        msg.fire_stale, msg.fire_age_s, msg.fire_margin_m = fire
        bus.put(self.pubs["decision"], "", msg)

    def _clock_msg(self, out: common_pb2.Clock) -> None:
        """``out`` as the anchor that maps the current τ_t to the wall clock."""
        a = self.clock.anchor
        out.speed_factor = a.speed_factor
        out.sim_time_s = self.clock.now_s
        out.anchor_wall_ns = int(a.wall_at(self.clock.now_s) * 1e9) if a.speed_factor else a.wall_ns

    def step(self) -> StepRecord | None:
        """Run one step; returns its record, or None when the mission is over."""
        if self.done:
            return None
        assert self.result is not None
        t = self.result.steps
        self._ensure_offboard()
        self._update_waypoints()
        self._hold_without_planners()
        if self._catch_up_fires() and self.result.records:
            return self._finish(False, "fire_while_stale", self.result.records[-1])
        tick = time.perf_counter()
        self.clock.start_step()
        stale, age, margin = self.fire_stale(), self.fire_age_s(), self.fire_margin_m()
        alive = [k for k in (1, 2) if self._alive(f"system{k}")]

        snapshot = self.snapshot
        d_t = self._d_t(t, snapshot)
        decision = self.supervisor.decide(t, d_t)
        order = planning_order(self.controller, decision.system, self.params)
        wanted = order[0]
        plan: Plan | None = None
        planning_time = compute = self.request_wall = self.service_time = 0.0
        statuses = []
        s1_info: dict[str, object] = {}
        for system in order:
            if system not in alive:  # its liveliness token is gone: not asked
                statuses.append(f"s{system}:unavailable")
                continue
            candidate = self._plan_with(system, t, decision)
            if system == 1:
                s1_info = dict(candidate.info)
            planning_time += self._planning_time(candidate)
            compute += candidate.compute_time_s
            statuses.append(f"s{system}:{candidate.status.value}")
            if candidate.ok:
                plan = candidate
                break
        n_sub = substeps_for(planning_time, self.fire_params)

        if plan is not None:
            control = np.asarray(plan.controls[0], dtype=float)
            target = np.asarray(plan.states[1, : 2 * self.dyn.dim], dtype=float)
            flown = plan.system
            planned = np.asarray(plan.states[:, : 2 * self.dyn.dim])
            info = dict(plan.info)
        else:
            control = brake_control(self.state, self.dyn)
            target = step(self.state, control, self.dyn)
            flown = 0
            planned = np.empty((0, 2 * self.dyn.dim))
            info = {}
        # The setpoint leaves as soon as the plan is known, stamped with the simulated time
        # it is due (after the planning interval and one ΔT of flight). The fire propagation
        # of the planning interval is the simulated world catching up, not the control path:
        # if it reaches the idle vehicle the mission has failed (Sec. IV), and the vehicle's
        # step towards this setpoint is not counted.
        due_ms = self.base_ms + round(
            (self.clock.now_s + n_sub * self.fire_params.substep_s + self.dyn.dt_s) * 1000)
        sent = self.link.send_setpoint(target, due_ms)
        self.latency.add(t, sent - tick, compute, len(statuses), self.request_wall,
                         self.service_time)
        rejected = s1_info.get("operator_rejected")
        op = OperatorRecord(t, 0 if self.waypoints is None else len(self.waypoints),
                            str(info.get("source", "")) if flown == 1 else "",
                            bool(rejected), str(rejected or ""))
        self.operator.append(op)
        self._publish_step_start(decision, wanted, op,  # observers: off the control path
                                 (stale, age, margin))
        caught = self._advance(t, n_sub)
        record = StepRecord(
            t=t, state=self.state.copy(), control=control, decision=decision, system=flown,
            plan_status=";".join(statuses), planning_time_s=planning_time, fire_substeps=n_sub,
            d_t=d_t, fires_active=len(snapshot.regions), planned_positions=planned,
            snapshot=snapshot, info=info,
        )
        self.result.records.append(record)
        why = {"fire_age_s": age, "fire_stale": stale, "fire_margin_m": round(margin, 3),
               "planners_alive": [f"system{k}" for k in alive], "ews_alive": self._alive("ews"),
               "commanded_system": wanted}
        if flown == 0:
            why["hold_reason"] = ("no planner alive" if not any(k in alive for k in order)
                                  else "no OK plan")
        if caught:
            self._record("step", **self._step_json(record), flown=False,
                         sim_time_s=self.clock.now_s, **why)
            return self._finish(False, "fire_while_planning", record)

        prev_pos = self.state[:2].copy()
        self.state = self._read_state(due_ms)
        self.clock.advance(self.dyn.dt_s)
        self.result.add_flight(control, self.prev_control, self.dyn.dt_s)
        self.prev_control = control
        self._publish_state(t + 1)
        self._record("step", **self._step_json(record), flown=True, sim_time_s=self.clock.now_s,
                     after=[float(v) for v in self.state], **why)
        self.clock.sleep_until_now(self.stop)  # the flight lasts ΔT of simulated time
        if self.params.fire_substeps_per_motion and self._advance(
                t, self.params.fire_substeps_per_motion):
            return self._finish(False, "fire_in_flight", record)
        regions = self.snapshot.regions
        outcome = flight_outcome(prev_pos, self.state[:2], regions, self.result.steps,
                                 self.result.config, self.params)
        if outcome is not None:
            return self._finish(outcome == "", outcome, record)
        note = (f"fire data stale: {age:g} s old, hulls grown by {margin:.1f} m" if stale else "")
        if flown == 0:
            note = "; ".join(filter(None, [note, f"braking: {why['hold_reason']}"]))
        self._event(supervisor_pb2.MISSION_EVENT_KIND_STEP, step=t, flown_system=flown,
                    position=self.state, fires_active=len(regions),
                    plan_status=record.plan_status, mission_time_s=self.result.mission_time_s,
                    message=note)
        return record

    @staticmethod
    def _step_json(record: StepRecord) -> dict[str, object]:
        return record_to_json(record)

    def _finish(self, success: bool, cause: str, record: StepRecord) -> StepRecord:
        assert self.result is not None
        self.done = True
        self.result.success = success
        self.result.failure_cause = cause
        self.result.final_state = self.state.copy()
        self._record("end", success=success, failure_cause=cause, steps=self.result.steps,
                     final_state=[float(v) for v in self.state])
        self._event(supervisor_pb2.MISSION_EVENT_KIND_STEP, step=record.t,
                    flown_system=record.system, position=self.state,
                    fires_active=len(self.snapshot.regions), plan_status=record.plan_status,
                    mission_time_s=self.result.mission_time_s)
        log.info("mission ended", extra=fields(success=success, cause=cause,
                                               steps=self.result.steps))
        return record

    def run(self) -> MissionResult:
        self.start()
        while self.step() is not None:
            pass
        assert self.result is not None
        return self.result

    def close_record(self) -> None:
        if self.step_log is not None:
            self.step_log.close()

    def announce_end(self, run_dir: str, aborted: str = "") -> None:
        r = self.result
        if aborted or r is None:
            self._event(supervisor_pb2.MISSION_EVENT_KIND_ABORTED, message=aborted[:1000],
                        success=False, failure_cause="aborted")
            return
        self._event(supervisor_pb2.MISSION_EVENT_KIND_ENDED, step=r.steps, success=r.success,
                    failure_cause=r.failure_cause, mission_time_s=r.mission_time_s,
                    position=self.state, message=run_dir)

    def write(self, out: Path, extra: dict[str, object]) -> list[Path]:
        """summary.json, steps.csv, trace.json (dualpilot.mission.records) and latency.csv."""
        from dualpilot.mission.records import write_all

        assert self.result is not None
        paths = write_all(self.result, out)
        write_operator_columns(self.operator, out)
        summary = json.loads((out / "summary.json").read_text())
        summary["stack"] = {
            "mission_id": self.mission_id, "transport": "zenoh + mavlink",
            "speed_factor": self.clock.speed_factor or "unpaced",
            "setpoint_overhead": self.latency.overhead_ms(),
            "setpoints_sent": self.link.sent, "rejected_messages": dict(codec.REJECTIONS),
            **extra,
        }
        (out / "summary.json").write_text(json.dumps(summary, indent=2, default=str) + "\n")
        paths.append(self.latency.write(out))
        return paths

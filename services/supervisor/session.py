"""The supervisor's mission session: the one mission step over the stack's ports.

What is about being a process lives here; the step itself is
:class:`dualpilot.mission.step.Mission`, the same object the in-process loop
runs, built from the same :class:`~dualpilot.mission.config.MissionConfig`,
with the ports of services/supervisor/ports/. The session

* starts a mission: hands the simulated vehicle the mission's configuration
  (services/supervisor/simulator.py), takes the vehicle (services/supervisor/watch.py, over the
  link's take-over: setpoints, offboard mode, arm), downloads its mission as
  System 1's operator waypoints, freezes the spec with the vehicle's position
  as the start, resets the EWS and prepares the planners with the
  configuration, or **resumes** one from the ``steps.jsonl`` a stopped
  supervisor left (the recorded decisions replayed, the EWS reset and
  replayed, the vehicle taken from where it is);
* between steps: pauses (services/supervisor/pause.py) while the vehicle is not
  flying offboard (lost for 3 s, or put in hold: watch.py), takes a newly uploaded
  mission as the next revision of the operator waypoints, holds while no
  planner of the controller is alive (lockstep: nothing advances while paused);
* is observed by :class:`~services.supervisor.observer.StackObserver`: the run
  record (services/supervisor/record.py) and the publications.

It reaches the services only through its :class:`~services.supervisor.ports.StackBus`
(transport and wall clock) and the vehicle only through its link, so a unit test
flies it in-process (tests/unit/services/supervisor/test_session.py).
"""

from __future__ import annotations

import logging
from typing import cast

import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.flight import true_position
from dualpilot.mission.records import result_from_log
from dualpilot.mission.result import Ending, MissionResult, StepRecord
from dualpilot.mission.step import Mission, MissionPorts
from dualpilot.model.dynamics import Array
from services.common import bus
from services.common.convert.supervisor import EventKind
from services.common.log import fields

from .airlink import LinkWatch
from .link import VehicleLink
from .observer import StackObserver
from .pause import PausePolicy
from .pool import PlannerPool, PoolParams
from .ports import Aborted, StackBus, StackFires, StackPlanners, vehicle_port
from .publish import Publications
from .record import Entries, RunRecord, StorageFault
from .simulator import configure_vehicle
from .watch import OffboardWatch, VehicleGone

log = logging.getLogger(__name__)

__all__ = ["Aborted", "StackSession", "StorageFault", "VehicleGone"]


#: how far (m) the vehicle's altitude may lie from a 3-D mission's start altitude (a float32
#: LOCAL_POSITION_NED z of an altitude up to the band's ceiling is within 1e-5 m of it)
START_ALTITUDE_TOL_M = 1e-3


class StackSession:
    """One mission of ``config`` flown through the services; ``run()`` flies it."""

    def __init__(self, b: StackBus, link: VehicleLink, config: MissionConfig, record: RunRecord,
                 waypoints: Array | None = None, airlink: LinkWatch | None = None):
        self.b = b
        self.link = link
        self.config = config
        self.spec = config.spec()  # the start: the vehicle's, when the mission starts
        self.record = record
        self.waypoints = waypoints
        self.mission_rev = 0  # the vehicle's mission download last seen
        self.mission: Mission | None = None
        self.fires: StackFires | None = None
        self.planners: StackPlanners | None = None
        self.pubs = Publications(b, b.stack.altitude_m)
        self.observer = StackObserver(b, link, record, self.pubs, self, airlink)
        self.pause = PausePolicy(b.stop, b.stack.pause_limit_s, self._announce_pause,
                                 b.wall.now, b.wait)
        self.watch = OffboardWatch(b, link, self.pause, self.observer.faults)
        self.vehicle = vehicle_port(b, link, config, self.spec.dynamics.dt_s, self.watch.ensure)
        self.resumed_at: int | None = None
        self.holding = ""

    @property
    def result(self) -> MissionResult | None:
        return None if self.mission is None else self.mission.result

    @property
    def state(self) -> Array:
        return self.mission.state if self.mission is not None else np.zeros(4)

    @property
    def waypoints_n(self) -> int:
        return 0 if self.waypoints is None else len(self.waypoints)

    def _steps(self) -> int:
        return self.result.steps if self.result is not None else 0

    def _announce_pause(self, kind: str, message: str) -> None:
        ev = EventKind.PAUSED if kind == "paused" else EventKind.RESUMED
        self.observer.event(ev, message=message, step=self._steps())

    # -- between steps ---------------------------------------------------------------------------
    def _update_waypoints(self) -> None:
        """A mission newly downloaded from the vehicle becomes the operator waypoints."""
        rev, wps, mission_id = self.link.mission.operator_waypoints()
        if rev == 0 or rev == self.mission_rev:
            return
        self.mission_rev = rev
        if not mission_id:
            return  # never uploaded: the --waypoints flag's stay
        area = self.spec.area_size_m
        if wps is not None and not all(0.0 <= v <= area for v in wps.ravel()):
            log.error("operator waypoints outside the area ignored", extra=fields(
                mission_id=mission_id, n=len(wps)))
            return
        same = (wps is None and self.waypoints is None) or (
            wps is not None and self.waypoints is not None and wps.shape == self.waypoints.shape
            and np.allclose(wps, self.waypoints))
        if same:
            return
        self.waypoints = wps
        log.info("operator waypoints from the vehicle", extra=fields(
            mission_id=mission_id, n=self.waypoints_n, waypoints=";".join(
                f"{e:.1f},{north:.1f}" for e, north in (wps if wps is not None else []))))
        if self.planners is not None:  # System 1 applies them at its next plan
            self.planners.set_waypoints(wps, publish=True)
        self.observer.event(EventKind.WAYPOINTS, step=self._steps(),
                            message=f"{self.waypoints_n} operator waypoints "
                                    f"(mission {mission_id:g})")

    def _hold_without_planners(self) -> None:
        """No planner of this controller alive and the vehicle at rest: pause (the vehicle holds,
        the lockstep clock and the fires wait) until one is back."""
        systems = self.config.systems()
        names = [f"system{k}" for k in systems]
        live = self.b.live
        if live is None or any(self.b.alive(n) for n in names):
            return
        if np.linalg.norm(self.state[self.spec.dynamics.dim:]) > 0.05:
            return  # still moving: this step brakes (no plan to fly)
        reason = f"holding: no planner alive ({', '.join(names)}: liveliness token gone)"
        self.holding = reason
        back: list[int] = []

        def resumed(paused: float) -> str:
            back[:] = [k for k in systems if self.b.alive(f"system{k}")]
            self._prepare_again(back)
            return f"{', '.join(f'system{k}' for k in back)} back after {paused:.1f} s"

        wait, self.pause.wait = self.pause.wait, (
            lambda period: live.wait_any(names, period, self.b.stop))  # woken by a token
        try:
            self.pause.hold(reason, lambda: any(self.b.alive(n) for n in names),
                            period_s=0.25, resumed=resumed)
        finally:
            self.pause.wait = wait
        self.holding = ""

    def _prepare_again(self, systems: list[int]) -> None:
        """A planner that came back is a fresh service: build this mission's planner."""
        assert self.planners is not None
        try:
            self.planners.prepare(systems)
            if self.planners.waypoints.revision:
                self.planners.publish_waypoints()
        except Aborted as err:
            log.warning("planner back but not ready", extra=fields(error=str(err)))

    # -- start ------------------------------------------------------------------------------------
    def start(self) -> None:
        """Take the vehicle, then start the mission from its state or resume its record."""
        self.record.claim()
        configure_vehicle(self.b, self.config)
        self.watch.take()
        # the states of the mission's dimension, from the vehicle in the air (in 3-D its z:
        # the lockstep take-off to the start altitude is instantaneous)
        self.link.position.set_dim(self.spec.dim)
        if not self.link.mission.wait_downloaded(self.b.stack.mission_wait_s, self.b.stop):
            log.warning("the vehicle's mission was not downloaded before the start")
        self._update_waypoints()
        got = self.link.position.wait_state(0, self.b.stack.vehicle_timeout_s, self.b.stop)
        if got is None:
            raise Aborted("no LOCAL_POSITION_NED from the vehicle")
        prior = self.record.prior()
        vehicle_ms, x0 = got
        if prior is None:  # at rest at boot: the in-process mission's hover_state(start)
            self.spec = self.config.spec(start=self.vehicle.start_position(x0))
            self._check_start_altitude(true_position(self.vehicle, x0[:self.spec.dim]))
        else:
            head = next(e for e in prior if e.get("kind") == "mission")
            start = cast(list[float], head["start"])
            self.spec = self.config.spec(start=(float(start[0]), float(start[1])))
        self._ports()
        if prior is not None:
            self._resume(prior, vehicle_ms, x0)
            return
        assert self.fires is not None
        self.vehicle.base_ms = vehicle_ms
        self.fires.reset()
        self.mission = self._mission(x0)
        self._prepare()
        self._open_record(fresh=True)
        self.pubs.state(self.state, 0)
        self.observer.event(EventKind.STARTED, position=self.state, message=(
            f"timing={self.config.timing.value} speed_factor={self.b.clock.speed_factor}"))
        log.info("mission started", extra=fields(
            mission=self.b.mission_id, controller=self.config.controller_name,
            seed=self.spec.seed, timing=self.config.timing.value,
            start_east_m=float(x0[0]), start_north_m=float(x0[1])))

    def _check_start_altitude(self, x0: Array) -> None:
        """A 3-D mission starts at the band's start altitude (the vehicle climbs there when it
        takes the mission's configuration: services/uavsim/missionconfig.py); Aborted else.
        ``x0`` is where the vehicle truly is (a plant's truth, not its noisy estimate)."""
        if self.spec.dim != 3:
            return
        want = self.spec.band.start_altitude_m
        if abs(float(x0[2]) - want) > START_ALTITUDE_TOL_M:
            raise Aborted(f"the vehicle is at {float(x0[2]):.6g} m, the mission starts at the "
                          f"band's start altitude {want:g} m (start_altitude_m)")

    def _ports(self) -> None:
        """The fire and planner ports of the mission's spec (the pool over Zenoh)."""
        b = self.b
        self.fires = StackFires(b, self.spec, self.config, self._caught_up)
        st = b.stack
        pool = PlannerPool(b.transport.planners(b.uav, b.stop, b.live), b.uav,
                           b.mission_id, b.deadline_s,
                           PoolParams(st.deadline_misses, st.health_every_s,
                                      st.health_timeout_s, st.prepare_timeout_s,
                                      (st.link.allowance_s("system1"),
                                       st.link.allowance_s("system2"))))
        self.planners = StackPlanners(b, self.spec, self.config, pool)
        if self.waypoints is not None:
            self.planners.set_waypoints(self.waypoints, publish=False)

    def _mission(self, state: Array) -> Mission:
        assert self.fires is not None and self.planners is not None
        try:
            return Mission(self.config, self.spec,
                           MissionPorts(self.fires, self.planners, self.vehicle), state,
                           observer=self.observer)
        except ValueError as err:
            raise Aborted(str(err)) from err

    def _prepare(self) -> None:
        assert self.planners is not None
        if self.planners.waypoints.revision:
            self.planners.publish_waypoints()
        self.planners.prepare(self.config.systems())
        bus.settle_heap()  # everything the mission needs is imported and built

    def _open_record(self, fresh: bool) -> None:
        self.record.open(fresh)
        if fresh:
            assert self.fires is not None
            self.record.head(self.config, self.spec, self.fires.params.substep_s,
                             self.b.clock.speed_factor)

    def _resume(self, entries: Entries, vehicle_ms: int, x: Array) -> None:
        """Pick the mission up where its record ends, from the vehicle's state now."""
        assert self.fires is not None
        result = result_from_log(entries, self.spec.dynamics.dt_s)
        result.spec = self.spec
        head = next(e for e in entries if e.get("kind") == "mission")
        steps = [e for e in entries if e.get("kind") == "step"]
        recorded = float(head.get("substep_s", self.fires.params.substep_s))  # type: ignore[arg-type]
        if recorded != self.fires.params.substep_s:
            raise Aborted(f"the record was flown with T_f = {recorded:g} s, this mission's is "
                          f"{self.fires.params.substep_s:g} s")
        clear = self.config.reading().mission.ignition_clearance_m
        self.fires.history = [
            (rec.t, rec.fire_substeps, None if clear is None else (rec.state[:2].copy(), clear))
            for rec in result.records]
        sim_s = float(steps[-1].get("sim_time_s", 0.0)) if steps else 0.0  # type: ignore[arg-type]
        self.b.clock.now_s = sim_s
        self.vehicle.base_ms = vehicle_ms - round(sim_s * 1000)
        self.resumed_at = result.steps
        self.fires.replay()
        self.mission = self._mission(x)
        self.mission.resume(result)
        self._prepare()
        self._open_record(fresh=False)
        self.pubs.state(self.state, result.steps)
        log.info("mission resumed from its record", extra=fields(
            mission=self.b.mission_id, step=result.steps,
            fire_substeps=sum(n for _, n, _ in self.fires.history)))
        self.observer.event(EventKind.RESUMED, step=result.steps, position=self.state,
                            message=f"supervisor restarted: mission picked up at step "
                                    f"{result.steps} from the vehicle's state "
                                    f"({x[0]:.1f}, {x[1]:.1f})")

    def _caught_up(self, owed: int, fires_active: int) -> None:
        self.record.line("fires_caught_up", owed_substeps=owed, fires_active=fires_active)

    # -- the loop ---------------------------------------------------------------------------------
    def step(self) -> StepRecord | None:
        """Between-step duties, then the mission's one step."""
        assert self.mission is not None and self.planners is not None
        if self.mission.done:
            return None
        self.record.check()
        self.watch.ensure()
        self._update_waypoints()
        self._hold_without_planners()
        self.observer.began()
        self.b.clock.start_step()
        self.planners.begin_step()
        assert self.fires is not None
        self.fires.begin_step(self.mission.result.steps)
        record = self.mission.step()
        if record is not None and not self.mission.done:
            self.observer.step_event(record, self.observer.step_note(record))
        return record

    def run(self) -> MissionResult:
        self.start()
        while self.step() is not None:
            pass
        assert self.result is not None
        return self.result

    def end_lost(self, reason: str) -> None:
        """The mission ends without a last step (the vehicle lost for good): the ``end`` line."""
        if self.result is None:
            return
        self.result.ending = Ending.VEHICLE_LOST
        cause = Ending.VEHICLE_LOST.failure_cause
        self.record.line("end", success=False, failure_cause=cause, steps=self.result.steps,
                         final_state=[float(v) for v in self.state], reason=reason)
        log.error("mission ended", extra=fields(cause=cause, reason=reason,
                                                steps=self.result.steps))

    def close(self) -> None:
        if self.planners is not None:
            self.planners.close()
        self.record.close()

    def announce_end(self, run_dir: str, aborted: str = "") -> None:
        r = self.result
        if aborted or r is None:
            self.observer.event(EventKind.ABORTED, message=aborted[:1000], success=False,
                                failure_cause="aborted")
            return
        self.observer.event(EventKind.ENDED, step=r.steps, success=r.success,
                            failure_cause=r.failure_cause, mission_time_s=r.mission_time_s,
                            position=self.state, message=run_dir)

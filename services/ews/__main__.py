"""EWS service: the fire process of Sec. II-B behind a Zenoh command queryable.

* ``<ns>/ews/command`` (queryable, FireCommand → FireUpdate): ``reset`` starts
  a mission's fire process from its seed and area (the spec's fire stream, as
  the in-process mission), with the fire process of the reset's mission
  configuration (its reading's FireParams: T_f, life_base, extent, the
  scenario, …; dualpilot/mission/config.py; a reset without one: the EWS's
  own, from ``--profile`` and its flags); ``advance`` propagates n sub-steps for mission
  step t, no front igniting within the command's keep-out radius of the UAV; ``forecast``
  answers with the occupancy forecast of the current fire state (the mission
  configuration's grid and ensemble, time-steps of the query's length), made
  only when asked and refused when the query names another revision of the fire
  state (sub-steps done) than the EWS holds.
  Sub-step k is published on
  ``<ns>/ews/fires`` when the stack's clock (carried in the command) reaches
  ``τ_t + k·T_f``: the fires propagate while the plan is computed (see
  services/common/clock.py). The reply carries every sub-step's state.
* ``<ns>/ews/forecast``: while anyone subscribes, after each command's sub-steps and
  before its reply,
  the occupancy forecast (P(a point is inside a fire region) on a grid, for the
  next ``--occupancy-horizon-s``; dualpilot/model/forecast.py) and
  the mean-motion forecast of each front over ``--forecast-horizon-s``
  (services/ews/forecast.py). The mean motion is the paper model's, so a scenario's
  fronts get none (horizon 0); the occupancy grid is the scenario's level set run
  ahead (dualpilot/model/physics_forecast.py).

Bad commands get an error reply (dualpilot.v1.Error), never a crash; each is
counted per key and reason in the status served on ``<ns>/status/ews``
(services/common/bus.py). ``--uav-ids`` serves a fleet (services/common/fleet.py):
one fire process per vehicle id, each seeded by its own supervisor's reset, so
every vehicle's fires are those of its in-process mission. An advance whose
clock would keep the EWS pacing for more than ``MAX_PACED_WAIT_S`` is refused,
so no command can stall it.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import replace
from typing import Any

import numpy as np
import zenoh

from dualpilot.model.field_forecast import field_forecast, forecast_step_substeps
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.forecast import ForecastParams
from dualpilot.readings import PROFILES, get_profile
from dualpilot.spec import Stream, stream_rng
from services.common import bus, fleet, keys, rejections, wire
from services.common import cli as common_cli
from services.common.convert import common as common_convert
from services.common.convert import fire as fire_convert
from services.common.log import fields
from services.msgs import common_pb2, fire_pb2

from .forecast import envelope, forecast_regions
from .warm import Warmer

log = logging.getLogger("services.ews")

#: Longest wall time one advance may keep the EWS pacing its sub-steps (s).
MAX_PACED_WAIT_S = 600.0


class Ews:
    """The fire process of one vehicle's mission, driven by FireCommands."""

    def __init__(self, session: zenoh.Session, uav: str, params: FireParams,
                 forecast_horizon_s: float, stop: threading.Event,
                 occupancy: ForecastParams | None = None, warmer: Warmer | None = None):
        self.session = session
        self.uav = uav
        self.own = params  # for a reset that carries no configuration
        self.params = params  # the current mission's
        self.stop = stop
        self.forecast_horizon_s = forecast_horizon_s
        self.stamper = wire.Stamper("ews", uav)
        self.fires_pub = session.declare_publisher(keys.fires(uav))
        self.forecast_pub = session.declare_publisher(keys.forecast(uav))
        self.field: FireField | None = None
        self.rng: np.random.Generator | None = None
        self.mission_id = ""
        self.step = 0
        self.sim_time_s = 0.0
        #: the occupancy forecast's grid and ensemble (None: not published)
        self.occupancy = occupancy
        self.own_occupancy = occupancy  # for a reset that carries no configuration
        self.seed = 0
        self.step_substeps = 0  # sub-steps run so far in the latest time-step
        #: the mission asks for its forecasts (each is published as it is answered)
        self.asked_forecasts = False
        #: warms each fire process once, from the first reset that runs it (shared by a
        #: fleet's vehicles: one per EWS process)
        self.warmer = warmer or Warmer()

    @property
    def forecast_substeps(self) -> int:
        """The front forecast's horizon in the current mission's sub-steps."""
        return max(0, math.ceil(self.forecast_horizon_s / self.params.substep_s))

    def state_msg(self) -> fire_pb2.FireState:
        assert self.field is not None
        f = self.field
        return fire_convert.fire_state_msg(f.fronts, f.extinct_hulls, self.step, f.substeps_done,
                                             self.params.substep_s, self.stamper, self.sim_time_s)

    def handle(self, cmd: fire_convert.FireCommand) -> fire_pb2.FireUpdate:
        update = fire_pb2.FireUpdate()
        if cmd.kind == "forecast":
            self.answer_forecast(cmd, update.forecast)
        elif cmd.kind == "reset":
            # the mission's fire process: its configuration's reading (else the EWS's own)
            params = self.own if cmd.config is None else cmd.config.reading().fire
            self.occupancy = self.own_occupancy if cmd.config is None else cmd.config.forecast
            self.params = params
            self.field = (FireField(params=params, area_size_m=cmd.area_size_m)
                          if cmd.area_size_m > 0 else FireField(params=params))
            self.rng = stream_rng(cmd.seed, Stream.FIRE)
            self.mission_id, self.step, self.sim_time_s = cmd.mission_id, 0, 0.0
            self.seed, self.step_substeps = cmd.seed, 0
            self.asked_forecasts = False
            if self.occupancy is not None and self.will_forecast(cmd):
                self.warmer.start(params, self.occupancy)
            state = self.state_msg()
            bus.put(self.fires_pub, "", state)
            update.states.append(state)
            log.info("fire process reset", extra=fields(mission=cmd.mission_id, seed=cmd.seed))
        else:
            if self.field is None or self.rng is None or cmd.mission_id != self.mission_id:
                raise rejections.invalid(f"no fire process for mission {cmd.mission_id!r} "
                                         f"(current {self.mission_id!r}): send reset first")
            if cmd.step < self.step:
                raise rejections.invalid(f"step {cmd.step} is before the current step {self.step}")
            anchor = cmd.anchor
            t0 = anchor.sim_time_s if anchor is not None else self.sim_time_s
            if anchor is not None:
                wait = anchor.wall_at(t0 + cmd.substeps * self.params.substep_s) - time.time()
                if wait > MAX_PACED_WAIT_S:
                    raise rejections.invalid(f"the clock would pace this advance for {wait:.3g} s "
                                             f"(at most {MAX_PACED_WAIT_S:g})",
                                             rejections.Reason.OUT_OF_RANGE)
            self.step_substeps = cmd.substeps + (self.step_substeps if cmd.step == self.step
                                                 else 0)
            self.step = cmd.step
            waited = 0.0
            for k in range(1, cmd.substeps + 1):
                self.field.substep(self.rng, cmd.step, keep_out=cmd.keep_out)
                self.sim_time_s = t0 + k * self.params.substep_s
                if anchor is not None:
                    waited += anchor.sleep_until(self.sim_time_s, self.stop)
                state = self.state_msg()
                bus.put(self.fires_pub, "", state)
                update.states.append(state)
            update.paced_wait_s = waited
        self.stamper.stamp(update.header, self.sim_time_s)
        return update

    def will_forecast(self, cmd: fire_convert.FireCommand) -> bool:
        """Whether the mission ``cmd`` resets will see forecasts: it asks for them (a
        risk-aware controller; a reset without a configuration may), or someone listens to
        ``<ns>/ews/forecast`` (a live view)."""
        matching: Any = self.forecast_pub.matching_status
        return cmd.config is None or cmd.config.risk or bool(matching.matching)

    def answer_forecast(self, cmd: fire_convert.FireCommand, out: fire_pb2.FireForecast) -> None:
        """The occupancy forecast of the fire state ``cmd`` names (its revision: sub-steps
        done), made now; raises CodecError for another mission or revision, or none to give."""
        f = self.field
        if f is None or cmd.mission_id != self.mission_id:
            raise rejections.invalid(f"no fire process for mission {cmd.mission_id!r} "
                                     f"(current {self.mission_id!r}): send reset first")
        if cmd.substeps_done != f.substeps_done:
            raise rejections.invalid(
                f"forecast asked from the fire state after {cmd.substeps_done} sub-steps; the "
                f"EWS holds the one after {f.substeps_done}", rejections.Reason.STALE)
        if self.occupancy is None:
            raise rejections.invalid("this EWS makes no occupancy forecast "
                                     "(--occupancy-horizon-s 0) and the mission set none")
        self.warmer.wait(f.params)  # the reset's warm-up, done in the background
        t0 = time.perf_counter()
        fc = field_forecast(f, self.occupancy, self.seed,
                            forecast_step_substeps(f.params, cmd.substeps))
        fire_convert.forecast_reply_msg(fc, cmd.step, time.perf_counter() - t0, out)
        self.stamper.stamp(out.header, self.sim_time_s)
        self.asked_forecasts = True

    def publish_answer(self, answer: fire_pb2.FireForecast) -> None:
        """A forecast the supervisor asked for, on ``<ns>/ews/forecast`` too while anyone
        subscribes (the live view shows what the plans were made on; nothing made twice),
        with the paper model's front forecast beside it."""
        matching: Any = self.forecast_pub.matching_status
        if not matching.matching or self.field is None:
            return
        m = fire_pb2.FireForecast()
        m.CopyFrom(answer)
        self._add_fronts(m)
        bus.put(self.forecast_pub, "", m)

    def publish_forecast(self) -> None:
        """Both forecasts of the current fire state on ``<ns>/ews/forecast``, made only while a
        subscriber matches the key (a physics scenario's run-ahead costs several steps' CPU)."""
        assert self.field is not None
        matching: Any = self.forecast_pub.matching_status  # a MatchingStatus (the stub: bool)
        if not matching.matching or self.asked_forecasts:  # then published with each answer
            return
        m = fire_pb2.FireForecast(substeps_done=self.field.substeps_done,
                                  substep_s=self.params.substep_s)
        self.stamper.stamp(m.header, self.sim_time_s)
        self._add_fronts(m)
        self.add_occupancy(m)
        bus.put(self.forecast_pub, "", m)

    def _add_fronts(self, m: fire_pb2.FireForecast) -> None:
        """The mean-motion forecast of each front into ``m`` (the paper model's; none for a
        physics scenario)."""
        assert self.field is not None
        if self.field.physics is not None:
            m.horizon_s = 0.0
            return
        m.horizon_s = self.forecast_substeps * self.params.substep_s
        for front in self.field.fronts:
            regions = forecast_regions(front, self.field.params, self.forecast_substeps)
            fm = m.fronts.add(front_id=front.front_id)
            for r in regions:
                common_convert.rect_to_msg(r, fm.regions.add())
            common_convert.polygon_to_msg(envelope(front, regions), fm.envelope)

    def add_occupancy(self, m: fire_pb2.FireForecast) -> None:
        """The occupancy forecast into ``m`` (the in-process fire port's: the paper's fronts on
        their own stream from the mission seed and the sub-steps done, or a scenario's level set
        run ahead; dualpilot/model/field_forecast.py), time-steps as long as the latest one."""
        f = self.field
        if self.occupancy is None or f is None:
            return
        self.warmer.wait(f.params)
        fc = field_forecast(f, self.occupancy, self.seed, max(1, self.step_substeps))
        fire_convert.occupancy_to_msg(fc, m.occupancy)


class Binding:
    """The fire process belongs to the session that reset it (the query's stated session id).

    While that session holds the vehicle's ``alive/supervisor`` token, commands
    from any other session are refused (a second supervisor, a replayed or
    rogue command); once it is gone, a reset from another session takes the
    fire process over (a restarted supervisor resuming the mission).
    """

    def __init__(self, live: bus.Liveliness):
        self.live = live
        self.session = ""
        self.mission_id = ""

    def check(self, cmd: fire_convert.FireCommand, who: str) -> None:
        """Raise CodecError when ``who`` may not send ``cmd``; a reset binds."""
        bound = self.session
        if bound and who != bound and bound in self.live.holders.get("supervisor", []):
            raise rejections.invalid(f"fire process of mission {self.mission_id!r} is bound to "
                                     f"supervisor session {bound}; {cmd.kind} from {who or '?'} "
                                     f"refused")
        if cmd.kind == "reset":
            if bound and who != bound:
                log.warning("fire process taken over", extra=fields(
                    mission=cmd.mission_id, previous=bound, session=who))
            self.session, self.mission_id = who, cmd.mission_id


def body(ctx: bus.Context, params: FireParams, forecast_horizon_s: float,
         occupancy: ForecastParams | None = None, warmer: Warmer | None = None) -> None:
    assert ctx.session is not None
    uav = ctx.settings.uav_id
    ews = Ews(ctx.session, uav, params, forecast_horizon_s, ctx.stop, occupancy, warmer)
    key = keys.fire_command(uav)
    inbox = bus.Inbox(key)
    queryable = ctx.session.declare_queryable(key, inbox.on_query)
    binding = Binding(bus.Liveliness(ctx.session, uav))
    ctx.announce()
    while not ctx.stop.is_set():
        item = inbox.get(timeout=0.2)
        if item is None or item.query is None:
            continue
        try:
            cmd = fire_convert.fire_command_from_msg(
                wire.parse(item.payload, fire_pb2.FireCommand, item.encoding))
            binding.check(cmd, item.attachment.decode("ascii", "replace"))
            update = ews.handle(cmd)
            # Before the reply: once answered, the supervisor starts its next step at once,
            # and a forecast computed then would take the CPU its plan request needs.
            if cmd.kind != "forecast":
                ews.publish_forecast()
            bus.reply(item.query, update)
            if cmd.kind == "forecast":  # after the reply: the plan request goes first
                ews.publish_answer(update.forecast)
        except rejections.CodecError as err:
            rejections.rejected("FireCommand", err, log, key=key)
            bus.reply_error(item.query, common_convert.error_msg(ews.stamper, err.code, str(err)))
        except Exception as err:  # a bug must not take the fire process down with it
            log.exception("fire command failed")
            bus.reply_error(item.query, common_convert.error_msg(
                ews.stamper, common_pb2.ERROR_CODE_INTERNAL, f"{type(err).__name__}: {err}"))
    queryable.undeclare()


def main(argv: list[str] | None = None) -> int:
    p = common_cli.parser("ews", "EWS fire forecaster (Sec. II-B) over Zenoh.")
    p.add_argument("--substep-s", type=float,
                   default=common_cli.env("FIRE_SUBSTEP_S", str(FireParams().substep_s)),
                   help="fire propagation sub-step T_f in s [FIRE_SUBSTEP_S]")
    p.add_argument("--profile", default=common_cli.env("READINGS_PROFILE", "today"),
                   choices=list(PROFILES),
                   help="the fire readings when a reset carries none [READINGS_PROFILE]")
    p.add_argument("--fire-life-base", default=common_cli.env("FIRE_LIFE_BASE", ""),
                   help="override: substep or step [FIRE_LIFE_BASE]")
    p.add_argument("--fire-extent", default=common_cli.env("FIRE_EXTENT", ""),
                   help="override: substep, step or birth [FIRE_EXTENT]")
    p.add_argument("--redraw-clearance", default=common_cli.env("FIRE_REDRAW_CLEARANCE", ""),
                   help="override: true or false [FIRE_REDRAW_CLEARANCE]")
    p.add_argument("--fire-scenario", default=common_cli.env("FIRE_SCENARIO", ""),
                   help="the fire process when a reset names none: paper or a named scenario "
                        "(dualpilot scenarios) [FIRE_SCENARIO]")
    p.add_argument("--forecast-horizon-s", type=float,
                   default=common_cli.env("FORECAST_HORIZON_S", "80"),
                   help="forecast horizon in simulated s [FORECAST_HORIZON_S]")
    grid = ForecastParams()
    p.add_argument("--occupancy-horizon-s", type=float,
                   default=common_cli.env("OCCUPANCY_HORIZON_S", str(grid.horizon_s)),
                   help="occupancy forecast horizon in simulated s; 0: none "
                        "[OCCUPANCY_HORIZON_S]")
    p.add_argument("--occupancy-interval-s", type=float,
                   default=common_cli.env("OCCUPANCY_INTERVAL_S", str(grid.interval_s)),
                   help="time between its slices (s) [OCCUPANCY_INTERVAL_S]")
    p.add_argument("--occupancy-resolution-m", type=float,
                   default=common_cli.env("OCCUPANCY_RESOLUTION_M", str(grid.resolution_m)),
                   help="side of its cells (m) [OCCUPANCY_RESOLUTION_M]")
    p.add_argument("--occupancy-members", type=int,
                   default=common_cli.env("OCCUPANCY_MEMBERS", str(grid.members)),
                   help="motion paths per front [OCCUPANCY_MEMBERS]")
    fleet.add_argument(p)
    args = p.parse_args(argv)
    try:
        settings = common_cli.settings("ews", args)
        uavs = fleet.uav_ids(args.uav_ids, settings.uav_id)
        params = replace(get_profile(args.profile).with_settings({k: v for k, v in (
            ("life_base", args.fire_life_base), ("extent", args.fire_extent),
            ("redraw_clearance", args.redraw_clearance), ("scenario", args.fire_scenario))
            if v}).fire, substep_s=args.substep_s)
        if not (math.isfinite(args.forecast_horizon_s) and args.forecast_horizon_s >= 0):
            raise ValueError("--forecast-horizon-s must be finite and >= 0")
        occupancy = None if args.occupancy_horizon_s == 0 else ForecastParams(
            members=args.occupancy_members, resolution_m=args.occupancy_resolution_m,
            horizon_s=args.occupancy_horizon_s, interval_s=args.occupancy_interval_s)
    except ValueError as err:
        p.error(str(err))
    def serve(ctx: bus.Context) -> None:
        warmer = Warmer()  # one for every vehicle's fire process: a fire process warms once
        fleet.for_each(ctx, uavs, lambda sub: body(sub, params, args.forecast_horizon_s,
                                                   occupancy, warmer))

    return bus.run_service(settings, serve)


if __name__ == "__main__":
    bus.leave(main())

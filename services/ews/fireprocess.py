"""The fire process of one vehicle's mission (Sec. II-B), driven by FireCommands.

A reset starts the process of the reset's mission configuration (its
reading's FireParams: T_f, life_base, extent, the scenario, …, and its
forecast's grid and ensemble; a reset that carries none runs the default
configuration's) from the mission's seed and area; an advance propagates its
sub-steps, paced by the stack's clock; a forecast query is answered from the
current fire state. The EWS reads no reading of its own: every process reads
the mission configuration it is given (dualpilot/mission/config.py).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Any

import numpy as np
import zenoh

from dualpilot.mission.config import MissionConfig
from dualpilot.model.field_forecast import field_forecast, forecast_step_substeps
from dualpilot.model.fire import FireParams
from dualpilot.model.fire_field import FireField
from dualpilot.model.forecast import ForecastParams
from dualpilot.spec import Stream, stream_rng
from services.common import bus, keys, rejections, wire
from services.common.convert import common as common_convert
from services.common.convert import config as config_convert
from services.common.convert import fire as fire_convert
from services.common.effective import EFFECTIVE
from services.common.log import fields
from services.msgs import fire_pb2

from .forecast import envelope, forecast_regions
from .warm import Warmer

log = logging.getLogger("services.ews")

#: Longest wall time one advance may keep the EWS pacing its sub-steps (s).
MAX_PACED_WAIT_S = 600.0
#: The configuration of a reset that carries none.
DEFAULT_CONFIG = MissionConfig()


class Ews:
    """The fire process of one vehicle's mission, driven by FireCommands."""

    def __init__(self, session: zenoh.Session, uav: str, forecast_horizon_s: float,
                 stop: threading.Event, warmer: Warmer | None = None):
        self.session = session
        self.uav = uav
        #: the current mission's fire process (until a reset: the default configuration's)
        self.params: FireParams = DEFAULT_CONFIG.reading().fire
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
        #: the current mission's occupancy forecast: its grid and ensemble
        self.occupancy: ForecastParams = DEFAULT_CONFIG.forecast
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
                                             self.params.substep_s, self.stamper, self.sim_time_s,
                                             f.extinct_tops if f.heights is not None else ())

    def handle(self, cmd: fire_convert.FireCommand) -> fire_pb2.FireUpdate:
        update = fire_pb2.FireUpdate()
        if cmd.kind == "forecast":
            self.answer_forecast(cmd, update.forecast)
        elif cmd.kind == "reset":
            # the mission's fire process: its configuration's reading (none sent: the defaults)
            config = DEFAULT_CONFIG if cmd.config is None else cmd.config
            params = self.params = config.reading().fire
            self.occupancy = config.forecast
            # 3-D: the fronts' tops, from the mission's spec (its band, clearance, seed) as
            # in-process (dualpilot/mission/local.py); None in 2-D
            heights = config.reading().altitude.fire_heights(config.spec(), params.scenario)
            self.field = (FireField(params=params, area_size_m=cmd.area_size_m, heights=heights)
                          if cmd.area_size_m > 0 else FireField(params=params, heights=heights))
            self.rng = stream_rng(cmd.seed, Stream.FIRE)
            self.mission_id, self.step, self.sim_time_s = cmd.mission_id, 0, 0.0
            self.seed, self.step_substeps = cmd.seed, 0
            self.asked_forecasts = False
            if self.will_forecast(cmd):
                self.warmer.start(params, self.occupancy)
            state = self.state_msg()
            bus.put(self.fires_pub, "", state)
            update.states.append(state)
            EFFECTIVE.record(cmd.mission_id, self.uav, config_convert.config_to_json(config),
                             fire=params, forecast=self.occupancy)
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
        if f is None:
            return
        self.warmer.wait(f.params)
        fc = field_forecast(f, self.occupancy, self.seed, max(1, self.step_substeps))
        fire_convert.occupancy_to_msg(fc, m.occupancy)

"""The fire port over the EWS's ``ews/command`` queryable (reset, advance, replay, ageing)."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.ports import KeepOut
from dualpilot.model.field_forecast import forecast_step_substeps
from dualpilot.model.fire import FireParams, FireSnapshot, Region
from dualpilot.model.forecast import OccupancyForecast
from dualpilot.model.stale_fire import credible_margin_m
from dualpilot.spec import MissionSpec
from services.common import bus, keys, rejections, wire
from services.common.convert import fire as fire_convert
from services.common.log import fields
from services.msgs import fire_pb2

from .forecasts import StackForecasts
from .stackbus import Aborted, StackBus

log = logging.getLogger("services.supervisor.ports")


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
    step is a ``forecast_stale`` fault, and every answer's cost is kept for the step
    record (:class:`~services.supervisor.ports.forecasts.StackForecasts`).
    """

    def __init__(self, b: StackBus, spec: MissionSpec, config: MissionConfig,
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
        self.forecasts = StackForecasts(b, self.params)

    # -- messages ---------------------------------------------------------------------------------
    def _command(self, cmd: fire_pb2.FireCommand,
                 timeout_s: float | None = None) -> fire_pb2.FireUpdate:
        key = keys.fire_command(self.b.uav)
        wait = self.b.stack.fire_timeout_s if timeout_s is None else timeout_s
        try:
            payload, enc = self.b.query(key, cmd, wait, trusted=self.b.trusted("ews"))
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
            self.forecasts.missing(self.step, self.revision(), why)
            return None
        return self.forecasts.get(self.step, self.revision(), n)

    def age_s(self) -> float:
        """Simulated s the fire process should have advanced beyond the last FireState."""
        return self.owed * self.params.substep_s

    def stale(self) -> bool:
        return self.age_s() >= self.b.stack.stale.stale_after_s

    def margin_m(self) -> float:
        if not self.stale():
            return 0.0
        return credible_margin_m(self.age_s(), self.params, self.b.stack.stale)

    def advance(self, t: int, n: int, keep_out: KeepOut | None) -> list[tuple[Region, ...]]:
        """Propagate ``n`` sub-steps from τ_t (now); each sub-step's regions (cuboids in 3-D),
        [] when owed."""
        self.history.append((t, n, keep_out))
        if self.owed or not self.b.alive("ews"):
            self.owed += n
            self._pace(n)
            return []
        cmd = self._advance_msg(t, n, keep_out, paced=True)  # sub-step k due at τ_t + k·T_f
        try:
            update = self._command(cmd, self._advance_wait_s(n))
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
                out.append(self._take(msg).current() if k == last
                           else fire_convert.current_from_msg(msg))
            except rejections.CodecError as err:
                rejections.rejected("FireState", err, log)
                raise Aborted(f"EWS sent an invalid fire state: {err}") from err
        return out

    def _advance_wait_s(self, n: int) -> float:
        """How long the advance of ``n`` sub-steps from now waits (StackParams.fire_wait_s)."""
        clock = self.b.clock
        pacing = (clock.anchor.wall_at(clock.now_s + n * self.params.substep_s) - time.time()
                  if clock.speed_factor > 0 else 0.0)
        return self.b.stack.fire_wait_s(pacing, self.b.dt_s, clock.speed_factor)

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

"""The fire port's forecasts: the EWS's occupancy forecast of the fire state the step plans on.

:class:`StackForecasts` asks the EWS (a ``forecast`` FireCommand on
``ews/command``) for the forecast of exactly one fire revision (the sub-steps
done) and time-step length, as the in-process port makes it, and keeps it
until the fires advance. Without one (late, refused, another revision, a
reply that does not decode) the step flies without it, the paper's planners
and threat rule: each such step is one ``forecast_stale`` fault
(:meth:`StackForecasts.take_faults`), and every answer's cost is kept for the
step record (:meth:`StackForecasts.take_costs`).
"""

from __future__ import annotations

import logging
import time

import numpy as np

from dualpilot.model.fire import FireParams
from dualpilot.model.forecast import OccupancyForecast
from services.common import bus, keys, rejections, wire
from services.common.convert import fire as fire_convert
from services.common.log import fields
from services.msgs import fire_pb2

from .stackbus import Aborted, StackBus

log = logging.getLogger("services.supervisor.ports")


class StackForecasts:
    """The forecasts asked of the EWS in one mission, their faults and their costs."""

    def __init__(self, b: StackBus, params: FireParams):
        self.b = b
        self.params = params
        self._forecasts: dict[tuple[int, int], OccupancyForecast | None] = {}
        self._faults: list[str] = []
        self._costs: list[dict[str, object]] = []
        self._received: list[tuple[float, float, int]] = []  # (compute s, wall s, bytes)
        self._missing = 0  # steps that flew without the forecast they asked for
        self._missing_step = -1

    def get(self, step: int, revision: int, n: int) -> OccupancyForecast | None:
        """The forecast of fire revision ``revision`` for time-steps of ``n`` sub-steps, asked
        at ``step`` (a refused or missing answer is not asked again for the same revision and
        length: None, and the step's fault)."""
        key = (revision, n)
        if key not in self._forecasts:
            self._forecasts = {k: v for k, v in self._forecasts.items() if k[0] == key[0]}
            self._forecasts[key] = self._ask(step, revision, n)
        elif self._forecasts[key] is None:
            self.missing(step, revision, f"the EWS gave no forecast of revision {revision}")
        return self._forecasts[key]

    def _ask(self, step: int, revision: int, n: int) -> OccupancyForecast | None:
        b = self.b
        cmd = fire_convert.fire_forecast_query_msg(b.mission_id, step, revision, n, b.stamper,
                                                   b.clock.now_s)
        key = keys.fire_command(b.uav)
        t0 = time.perf_counter()
        speed = b.clock.speed_factor
        try:
            payload, enc = b.query(key, cmd, b.stack.forecast_wait_s(b.dt_s, speed),
                                   trusted=b.trusted("ews"))
            update = wire.parse(payload, fire_pb2.FireUpdate, enc)
            fc = self._checked(update, step, revision)
        except rejections.CodecError as err:
            rejections.rejected("FireForecast", err, log, key=key)
            self.missing(step, revision, f"refused: {err}")
            return None
        except TimeoutError as err:
            if b.stop.is_set():
                raise Aborted("stopped") from err
            self.missing(step, revision, f"late: {err}")
            return None
        except bus.QueryError as err:
            self.missing(step, revision, str(err))
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

    def _checked(self, update: fire_pb2.FireUpdate, step: int,
                 revision: int) -> OccupancyForecast:
        """The reply's forecast, if it is the one asked for (CodecError otherwise)."""
        if not update.HasField("forecast"):
            raise rejections.invalid("the EWS replied without a forecast")
        got = update.forecast
        if got.substeps_done != revision or got.step != step:
            raise rejections.invalid(
                f"a forecast of step {got.step} from fire revision {got.substeps_done}, asked "
                f"for step {step} from {revision}", rejections.Reason.STALE)
        if not np.isclose(got.substep_s, self.params.substep_s, rtol=1e-12, atol=0.0):
            raise rejections.invalid(f"a forecast at T_f = {got.substep_s:g} s, the mission "
                                     f"runs {self.params.substep_s:g} s")
        fc = fire_convert.occupancy_from_msg(got)
        if fc is None:
            raise rejections.invalid("the EWS's forecast carries no occupancy grid")
        return fc

    def missing(self, step: int, revision: int, why: str) -> None:
        """A forecast_stale fault, one a step however often the step asks."""
        if self._missing_step == step:
            return
        self._missing_step = step
        log.warning("no fire forecast for this step: flying without it", extra=fields(
            step=step, revision=revision, reason=why))
        self._faults.append(why)
        self._missing += 1

    def summary(self) -> dict[str, object]:
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

"""In-process adapters of the mission step's ports: the fire process, the planners, Eq. (1)."""

from __future__ import annotations

import time
from typing import cast

import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.ports import KeepOut, PlanRequest
from dualpilot.mission.step import Mission, MissionPorts
from dualpilot.model.dynamics import Array, DynamicsParams, hover_state, step
from dualpilot.model.field_forecast import field_forecast, forecast_step_substeps
from dualpilot.model.fire import FireParams, FireSnapshot
from dualpilot.model.fire_field import FireField
from dualpilot.model.forecast import ForecastParams, OccupancyForecast
from dualpilot.model.geometry import Rect
from dualpilot.plan import ForecastPlanner, Plan, Planner, PlanStatus
from dualpilot.spec import MissionSpec, Stream


class LocalFires:
    """The fire process of Sec. II-B in this process, on the spec's fire stream."""

    def __init__(self, spec: MissionSpec, params: FireParams = FireParams(),
                 forecast_params: ForecastParams | None = None):
        self.field = FireField(params=params, area_size_m=spec.area_size_m)
        self.rng = spec.rng(Stream.FIRE)
        self.seed = spec.seed
        self.forecast_params = forecast_params or ForecastParams()
        self._forecasts: dict[tuple[int, int], OccupancyForecast] = {}

    def snapshot(self) -> FireSnapshot:
        return self.field.snapshot()

    def margin_m(self) -> float:
        return 0.0  # the fire process itself: never stale

    def forecast(self, substeps_per_step: int) -> OccupancyForecast | None:
        """The forecast from the current state (the paper's fronts: on its own stream, from the
        seed and the sub-steps done; a physics scenario: its level set run ahead), kept until
        the fires advance."""
        f = self.field
        n = forecast_step_substeps(f.params, substeps_per_step)
        key = (f.substeps_done, n)
        got = self._forecasts.get(key)
        if got is None:
            self._forecasts = {k: v for k, v in self._forecasts.items() if k[0] == key[0]}
            got = field_forecast(f, self.forecast_params, self.seed, n)
            self._forecasts[key] = got
        return got

    def advance(self, t: int, n: int, keep_out: KeepOut | None) -> list[tuple[Rect, ...]]:
        out = []
        for _ in range(n):
            self.field.substep(self.rng, t, keep_out=keep_out)
            out.append(tuple(f.region for f in self.field.fronts))
        return out


class LocalPlanners:
    """Planner objects called directly; a planner's ValueError is an INVALID_INPUT plan."""

    def __init__(self, planners: dict[int, Planner]):
        self.planners = planners

    def available(self, system: int) -> bool:
        return system in self.planners

    def uses_forecast(self, system: int) -> bool:
        return bool(getattr(self.planners.get(system), "uses_forecast", False))

    def plan(self, request: PlanRequest) -> Plan:
        t0 = time.perf_counter()
        try:
            planner = self.planners[request.system]
            if request.forecast is not None and self.uses_forecast(request.system):
                return cast(ForecastPlanner, planner).plan(
                    request.state, request.obstacles, request.objective, request.prev_control,
                    forecast=request.forecast)
            return planner.plan(
                request.state, request.obstacles, request.objective, request.prev_control)
        except ValueError as err:  # bad input to the planner: not flyable, not fatal
            return Plan.failed(request.system, PlanStatus.INVALID_INPUT,
                               time.perf_counter() - t0, str(err))

    def launch(self, request: PlanRequest) -> object:
        """In one process the background plan is computed at once (it is due later)."""
        return self.plan(request)

    def collect(self, ticket: object) -> Plan:
        assert isinstance(ticket, Plan)
        return ticket


class LocalVehicle:
    """Eq. (1) with the commanded control: the vehicle reaches x_{t+1} = Φ x_t + Γ u_t."""

    def __init__(self, state: Array, dynamics: DynamicsParams):
        self.state = np.asarray(state, dtype=float).copy()
        self.dyn = dynamics
        self._control: Array | None = None

    def command(self, target: Array, control: Array, after_s: float) -> None:
        self._control = np.asarray(control, dtype=float)

    def observe(self) -> Array:
        if self._control is not None:
            self.state = step(self.state, self._control, self.dyn)
            self._control = None
        return self.state.copy()


def local_mission(config: MissionConfig, planners: dict[int, Planner] | None = None) -> Mission:
    """The mission of ``config`` flown in this process (its planners built from the spec by
    default: the config's methods, risk-aware with ``config.risk``, System 2 with its time
    limit)."""
    spec = config.spec()
    if planners is None:
        from dualpilot.planners import build_planners

        planners = build_planners(spec, config.methods(), risk=config.risk,
                                  system2_params=config.system2_params())
    state = hover_state(np.array(spec.start), spec.dynamics)
    fires = LocalFires(spec, config.reading().fire, config.forecast)
    ports = MissionPorts(fires, LocalPlanners(planners),
                         LocalVehicle(state, spec.dynamics))
    return Mission(config, spec, ports, state)

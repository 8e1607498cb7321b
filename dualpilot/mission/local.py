"""In-process adapters of the mission step's ports: the fire process, the planners, Eq. (1);
the vehicle of an in-process mission is its plant (dualpilot/mission/flight.py)."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import cast

import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.dimension import check_dimension
from dualpilot.mission.flight import PlantVehicle
from dualpilot.mission.ports import KeepOut, PlanRequest
from dualpilot.mission.step import Mission, MissionPorts
from dualpilot.model.dynamics import Array, DynamicsParams, hover_state, step
from dualpilot.model.field_forecast import field_forecast, forecast_step_substeps
from dualpilot.model.fire import FireParams, FireSnapshot, Region
from dualpilot.model.fire_field import FireField
from dualpilot.model.fire_height import FireHeights
from dualpilot.model.forecast import ForecastParams, OccupancyForecast
from dualpilot.model.geometry import Polytope
from dualpilot.plan import ForecastPlanner, Plan, Planner, PlanStatus
from dualpilot.plant import make_plant
from dualpilot.spec import MissionSpec, Stream


class LocalFires:
    """The fire process of Sec. II-B in this process, on the spec's fire stream (and, in 3-D,
    its fronts' tops from ``heights``)."""

    def __init__(self, spec: MissionSpec, params: FireParams = FireParams(),
                 forecast_params: ForecastParams | None = None,
                 heights: FireHeights | None = None):
        self.field = FireField(params=params, area_size_m=spec.area_size_m, heights=heights)
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

    def advance(self, t: int, n: int,
                keep_out: KeepOut | None) -> Sequence[tuple[Region, ...]]:
        out = []
        for _ in range(n):
            self.field.substep(self.rng, t, keep_out=keep_out)
            out.append(self.field.current())
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
            # a planner is built for the spec's dimension and takes obstacles of its kind
            # (prisms in 3-D); the Planner protocol names the planar kind until a planner
            # plans in 3-D
            obstacles = cast(tuple[Polytope, ...], request.obstacles)
            if request.forecast is not None and self.uses_forecast(request.system):
                return cast(ForecastPlanner, planner).plan(
                    request.state, obstacles, request.objective, request.prev_control,
                    forecast=request.forecast)
            return planner.plan(
                request.state, obstacles, request.objective, request.prev_control)
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


def local_vehicle(config: MissionConfig, spec: MissionSpec,
                  state: Array) -> LocalVehicle | PlantVehicle:
    """The vehicle of an in-process mission at ``state``: Eq. (1) itself for the ideal plant
    (:class:`LocalVehicle`, today's), else the reading's plant on the spec's plant stream."""
    params = config.reading().plant_params()
    if params.kind == "ideal":
        return LocalVehicle(state, spec.dynamics)
    return PlantVehicle(make_plant(params, state, spec.dynamics, spec.rng(Stream.PLANT)))


def local_mission(config: MissionConfig, planners: dict[int, Planner] | None = None) -> Mission:
    """The mission of ``config`` flown in this process (by default the planners of the systems
    its controller asks, built from the spec: the config's methods, risk-aware with
    ``config.risk``, System 1 with its ``s1_altitude``, System 2 with its time limit), its
    vehicle the reading's plant (:func:`local_vehicle`)."""
    spec = config.spec()
    if planners is None:
        from dualpilot.planners import build_planner

        check_dimension(config)  # before anything is built: the controller, by name

        methods = config.methods()
        planners = {s: build_planner(s, spec, methods[s], config.system2_params() if s == 2
                                     else config.system1_params(), config.risk)
                    for s in config.systems()}
    state = hover_state(spec.start_position, spec.dynamics)
    reading = config.reading()
    heights = reading.altitude.fire_heights(spec, reading.fire.scenario)
    fires = LocalFires(spec, reading.fire, config.forecast, heights)
    ports = MissionPorts(fires, LocalPlanners(planners), local_vehicle(config, spec, state))
    return Mission(config, spec, ports, ports.vehicle.observe())

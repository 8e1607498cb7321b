"""The plant: what flies between two planning steps, apart from the planners' model.

``ideal`` is Eq. (1) exactly (:func:`dualpilot.model.dynamics.step`, the same
call the in-process vehicle makes, so its states are bit-identical); its path
over a step is Eq. (1)'s straight segment p_t + s·v_t. ``multirotor`` is a
quadrotor under PX4's cascaded controller (:mod:`dualpilot.plant.multirotor`)
fed the 20 Hz setpoint stream of the segment (:mod:`dualpilot.plant.setpoints`),
in wind (:mod:`dualpilot.plant.wind`), flying on a GPS/EKF-like estimate
(:mod:`dualpilot.plant.sensors`). Both fly one ΔT per call from their own state
and return the path at the integration rate, the true state and the measured
state at the end. The plant is always 3-D; a 2-D model state holds the altitude.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, Protocol, get_args

import numpy as np

from dualpilot.arrays import Array
from dualpilot.model.dynamics import DynamicsParams, check_state, step
from dualpilot.plant.layout import P, V
from dualpilot.plant.params import MultirotorParams
from dualpilot.plant.sensors import GpsError, GpsParams
from dualpilot.plant.setpoints import hermite_stream, segment_path, to_plant
from dualpilot.plant.wind import Wind, WindParams

PlantKind = Literal["ideal", "multirotor"]


@dataclass(frozen=True)
class PlantParams:
    """Which plant flies, and the multirotor's airframe, controller, air and sensors.

    The default, ``ideal``, is today's Eq. (1) vehicle: wind and sensor errors
    apply to the multirotor only.
    """

    kind: PlantKind = "ideal"
    multirotor: MultirotorParams = field(default_factory=MultirotorParams)
    wind: WindParams = field(default_factory=WindParams)
    gps: GpsParams = field(default_factory=GpsParams)

    def __post_init__(self) -> None:
        if self.kind not in get_args(PlantKind):
            raise ValueError(f"plant must be one of {get_args(PlantKind)}, not {self.kind!r}")


@dataclass(frozen=True)
class Flight:
    """One ΔT flown: the path at the integration rate and the states at its end.

    ``times_s`` (N+1,) from 0 to ΔT; ``positions``, ``velocities`` (N+1, 3) the true
    path (ENU, m and m/s); ``reference`` (N+1, 3) Eq. (1)'s straight segment from
    the plan's start at the same times; ``state`` and ``measured`` the true and
    measured model states at the end (the model's dimension); ``wind`` (N, 3) the
    air (m/s) over each integration step.
    """

    times_s: Array
    positions: Array
    velocities: Array
    reference: Array
    state: Array
    measured: Array
    wind: Array

    def tracking_error_m(self, axes: int = 3) -> Array:
        """‖flown − Eq. (1) path‖ (m) at each integration time, over the first ``axes`` axes
        (2: the horizontal distance, what the 2-D missions' d_safe measures)."""
        diff = self.positions[:, :axes] - self.reference[:, :axes]
        return np.asarray(np.linalg.norm(diff, axis=1))


class Plant(Protocol):
    """What the vehicle port flies (see module docstring)."""

    @property
    def state(self) -> Array:
        """The true model state now."""
        ...

    def fly(self, start: Array, control: Array) -> Flight:
        """Fly the Eq. (1) segment planned from ``start`` with ``control`` (N) for one ΔT."""
        ...

    def measure(self) -> Array:
        """The measured model state now (what LOCAL_POSITION_NED carries)."""
        ...


def _model_state(p: Array, v: Array, dim: int) -> Array:
    return np.concatenate([p[:dim], v[:dim]])


class IdealPlant:
    """Eq. (1) exactly, with the path of its straight segment at ``rate_hz``."""

    def __init__(self, state: Array, dyn: DynamicsParams, rate_hz: float = 100.0,
                 altitude_m: float = 50.0):
        self._state = check_state(state, dyn).copy()
        self.dyn = dyn
        self.rate_hz = rate_hz
        self.altitude_m = altitude_m

    @property
    def state(self) -> Array:
        return self._state.copy()

    def fly(self, start: Array, control: Array) -> Flight:
        n = max(int(round(self.dyn.dt_s * self.rate_hz)), 1)
        times = np.linspace(0.0, self.dyn.dt_s, n + 1)
        path = segment_path(self._state, times, self.dyn.dim, self.altitude_m)
        nxt = step(self._state, control, self.dyn)
        p1, v1 = to_plant(nxt, self.dyn.dim, self.altitude_m)
        path[-1] = p1
        _, v0 = to_plant(self._state, self.dyn.dim, self.altitude_m)
        vel = np.broadcast_to(v0, (n + 1, 3)).copy()
        vel[-1] = v1
        reference = segment_path(start, times, self.dyn.dim, self.altitude_m)
        self._state = nxt
        return Flight(times, path, vel, reference, nxt.copy(), nxt.copy(), np.zeros((n, 3)))

    def measure(self) -> Array:
        return self._state.copy()


class MultirotorPlant:
    """A quadrotor under PX4's cascaded controller, in wind, on a noisy estimate.

    ``rng`` is spawned into the wind's and the sensors' streams, so a seed
    reproduces a flight exactly. The turbulence's scales are those at the start's altitude
    (a 2-D state's ``altitude_m``; a 3-D state's z), kept for the whole flight.
    """

    def __init__(self, state: Array, dyn: DynamicsParams, rng: np.random.Generator,
                 params: PlantParams | None = None):
        from dualpilot.plant.multirotor import hover_vector  # the compiled flight: here only

        params = params if params is not None else PlantParams(kind="multirotor")
        self.dyn = dyn
        self.params = params.multirotor
        wind_rng, gps_rng = rng.spawn(2)
        p, v = to_plant(check_state(state, dyn), dyn.dim, self.params.altitude_m)
        self.x = hover_vector(p, v, self.params)
        self.air = Wind(params.wind, float(p[2]), wind_rng)
        self.gps = GpsError(params.gps, gps_rng)
        self._measured = self._measure()

    @property
    def state(self) -> Array:
        return _model_state(self.x[P:P + 3], self.x[V:V + 3], self.dyn.dim)

    def measure(self) -> Array:
        return self._measured.copy()

    def _measure(self) -> Array:
        pm, vm = self.gps.measure(self.x[P:P + 3], self.x[V:V + 3])
        return _model_state(pm, vm, self.dyn.dim)

    def fly(self, start: Array, control: Array) -> Flight:
        start = check_state(start, self.dyn)
        target = step(start, control, self.dyn)
        mr = self.params
        stream = hermite_stream(start, target, self.dyn.dt_s, mr.setpoint_hz, self.dyn.dim,
                                mr.altitude_m)
        flight = self.fly_stream(stream)
        reference = segment_path(start, flight.times_s, self.dyn.dim, mr.altitude_m)
        return Flight(flight.times_s, flight.positions, flight.velocities, reference,
                      flight.state, flight.measured, flight.wind)

    def fly_stream(self, setpoints: Array, duration_s: float | None = None) -> Flight:
        """Fly one ΔT (or ``duration_s``, s: a simulated vehicle on its own clock flies each
        setpoint of its 20 Hz stream as it comes) under a stream of [p, v, a] setpoints
        (S, 9) at ``setpoint_hz``; the reference of the returned flight is the stream's
        positions, held."""
        from dualpilot.plant.multirotor import fly as fly_multirotor  # compiled

        mr = self.params
        span = self.dyn.dt_s if duration_s is None else duration_s
        n = max(int(round(span * mr.rate_hz)), 1)
        dt = 1.0 / mr.rate_hz
        wind = self.air.sample(n, dt, self.x[V:V + 3])
        before = self.gps.error.copy()
        after = self.gps.sample(n, dt)
        seen = np.vstack([before[None, :], after[:-1]])
        path = fly_multirotor(self.x, setpoints, 1.0 / mr.setpoint_hz, wind, seen, mr)
        self._measured = self._measure()
        times = np.arange(n + 1, dtype=np.float64) * dt
        held = np.minimum((times * mr.setpoint_hz + 1e-9).astype(int), len(setpoints) - 1)
        return Flight(times, path[:, :3], path[:, 3:], np.asarray(setpoints)[held, :3],
                      self.state, self._measured.copy(), wind)


def make_plant(params: PlantParams, state: Array, dyn: DynamicsParams,
               rng: np.random.Generator) -> IdealPlant | MultirotorPlant:
    """The plant of ``params.kind`` at model state ``state`` (hovering attitude)."""
    if params.kind == "ideal":
        mr = params.multirotor
        return IdealPlant(state, dyn, mr.rate_hz, mr.altitude_m)
    return MultirotorPlant(state, dyn, rng, params)

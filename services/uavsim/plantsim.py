"""The plant a simulated vehicle flies when its mission says ``plant=multirotor``.

The mission's configuration (``config.reading().plant``, the one road:
services/uavsim/missionconfig.py) chooses the plant; uavsim reads no plant setting
of its own. ``ideal`` leaves the vehicle as it always was (Eq. (1) in one-second
jumps, services/uavsim/vehicle.py). ``multirotor`` is the pure core's plant
(:class:`dualpilot.plant.MultirotorPlant`: PX4's cascaded controller on a rigid
body, in the mission's wind, on a GPS/EKF-like estimate), made at the vehicle's
state on the mission's plant stream (``spec.rng(Stream.PLANT)``), as the in-process
loop makes it (:func:`dualpilot.mission.local.local_vehicle`):

* **lockstep**: each new setpoint [p*, v*] is one ΔT of the mission's flight stream
  from the vehicle's measured state to the setpoint's velocity
  (:func:`dualpilot.mission.flight.fly_ramp`, the stream the in-process
  :class:`~dualpilot.mission.flight.PlantVehicle` flies towards Eq. (1)'s v_{t+1}),
  so with the same plant, wind and seed the stack flies the in-process flight;
* **real time** (the vehicle's own clock): the newest setpoint flies for each period
  of the 20 Hz setpoint stream (``MultirotorParams.setpoint_hz``) as it comes due
  (services/uavsim/plantclock.py), like a SITL's flight controller. The truth is then
  the path of the last ΔT and the setpoint positions held along it: its tracking error
  is the distance to the setpoint, which runs ahead of the vehicle (the setpoint of a
  step is the state due at its end), not lockstep's distance to Eq. (1)'s segment.

The vehicle's reported state (LOCAL_POSITION_NED, services/uavsim/telemetry.py) is
then the plant's measurement, the autopilot's estimate; the truth of the latest
flight (:class:`~services.common.convert.plant.FlightTruth`) goes to the supervisor
on the simulator's side channel (services/uavsim/truth.py), and the air to a ground
station (WIND_COV, WIND: :meth:`PlantSim.air`). In a 2-D mission the plant flies the
horizontal at its own altitude (``MultirotorParams.altitude_m``) and the altitude the
vehicle reports is its navigator's, as before; in a 3-D mission (lockstep only so far) the
model's z is the plant's altitude, the setpoints' z and v_z fly, the measured state carries
the vertical GPS error, and the truth is 3-D.
"""

from __future__ import annotations

import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.mission.flight import fly_ramp
from dualpilot.model.dynamics import Array
from dualpilot.plant import MultirotorPlant
from dualpilot.plant.setpoints import to_plant
from dualpilot.spec import Stream
from services.common.convert.plant import FlightTruth

#: how much of the latest air (s) the wind report averages (PX4 and ArduPilot report an
#: estimate smoothed over about a second)
AIR_WINDOW_S = 1.0


class PlantSim:
    """The multirotor a vehicle flies (module docstring), its latest flight and air."""

    def __init__(self, plant: MultirotorPlant, time_ms: int, own_clock: bool = False):
        self.plant = plant
        self.dim = plant.dyn.dim
        self.own_clock = own_clock
        self.flights = 0
        self.time_ms = int(time_ms)  #: the vehicle's clock at the end of the latest flight
        self.path = np.empty((0, self.dim))
        self.planned = np.empty((0, self.dim))
        self.held: Array | None = None  #: own clock: the navigator's target [p*, v*]
        mr = plant.params
        self.air_samples = np.broadcast_to(plant.air.mean, (1, 3)).copy()
        self.air_keep = max(int(round(AIR_WINDOW_S * mr.rate_hz)), 1)

    @staticmethod
    def for_config(config: MissionConfig, state: Array, time_ms: int,
                   own_clock: bool = False) -> PlantSim | None:
        """The plant of ``config`` at the vehicle's ``state`` (None: the ideal plant, the
        vehicle's own Eq. (1)); ValueError for a plant the vehicle cannot fly."""
        params = config.reading().plant_params()
        if params.kind == "ideal":
            return None
        spec = config.spec()
        if spec.dim != 2 and own_clock:
            raise ValueError(f"plant={params.kind} flies a 3-D mission in lockstep only so far "
                             "(on its own clock: dim=2)")
        plant = MultirotorPlant(np.asarray(state, dtype=float), spec.dynamics,
                                spec.rng(Stream.PLANT), params)
        return PlantSim(plant, time_ms, own_clock)

    # -- what the vehicle and its telemetry read ------------------------------------------------
    def measured(self) -> Array:
        """The measured model state [p, v] (m, m/s): what LOCAL_POSITION_NED carries."""
        return self.plant.measure()

    def truth(self) -> FlightTruth:
        """The latest flight's truth (before the first: the state at rest, no path)."""
        return FlightTruth(self.time_ms, self.plant.state, self.path, self.planned,
                           self.flights)

    def air(self) -> tuple[Array, float, float]:
        """The air the vehicle flew through over the last :data:`AIR_WINDOW_S`: its mean
        (m/s, ENU) and the variances (m²/s²) of its horizontal (the sum of east and north)
        and vertical components."""
        a = self.air_samples
        return (a.mean(axis=0), float(a[:, 0].var() + a[:, 1].var()), float(a[:, 2].var()))

    # -- flying ---------------------------------------------------------------------------------
    def apply(self, state: Array, target: Array, due_ms: int) -> Array:
        """One ΔT towards the setpoint ``target`` [p*, v*] from the measured ``state``, due at
        ``due_ms``; the measured state after it. Lockstep: the flight
        (:func:`~dualpilot.mission.flight.fly_ramp` to v*); own clock: ``target`` is held for
        the stream's periods (:meth:`fly_held`) and nothing flies here."""
        target = np.asarray(target, dtype=float)
        if self.own_clock:
            self.held = target
            return self.measured()
        flight = fly_ramp(self.plant, np.asarray(state, dtype=float), target[self.dim:])
        d = self.dim
        self._took(flight.positions[:, :d], flight.reference[:, :d], flight.wind, due_ms)
        return flight.measured.copy()

    def fly_held(self, target: Array, duration_s: float, end_ms: int) -> Array:
        """Own clock: ``duration_s`` (s) towards ``target`` [p*, v*] held (its velocity as
        feed-forward, no acceleration: SET_POSITION_TARGET_LOCAL_NED's position and velocity),
        ending at ``end_ms``; the measured state after it. The truth then holds the path of
        the last ΔT (the periods flown, joined) and the setpoint positions held along it."""
        mr = self.plant.params
        p, v = to_plant(np.asarray(target, dtype=float), self.dim, mr.altitude_m)
        setpoint = np.concatenate([p, v, np.zeros(3)])[None, :]
        flight = self.plant.fly_stream(setpoint, duration_s)
        path, held = flight.positions[:, :2], flight.reference[:, :2]
        if len(self.path):  # the last ΔT of the path, the periods joined end to start
            path, held = np.vstack([self.path, path[1:]]), np.vstack([self.planned, held[1:]])
        keep = int(round(self.plant.dyn.dt_s * mr.rate_hz)) + 1
        self._took(path[-keep:], held[-keep:], flight.wind, end_ms)
        return flight.measured.copy()

    def idle(self, end_ms: int) -> None:
        """Own clock: a period not flown (on the ground, disarmed), ending at ``end_ms``."""
        self.time_ms = int(end_ms)
        self.path, self.planned = np.empty((0, self.dim)), np.empty((0, self.dim))

    def _took(self, path: Array, planned: Array, wind: Array, end_ms: int) -> None:
        self.flights += 1
        self.time_ms = int(end_ms)
        self.path, self.planned = np.asarray(path), np.asarray(planned)
        self.air_samples = np.vstack([self.air_samples, wind])[-self.air_keep:]

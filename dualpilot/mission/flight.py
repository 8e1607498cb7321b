"""The flight between two planning steps: the plant flies, and the flight is judged.

The planners keep Eq. (1) as their model and plan from the *measured* state;
what flies is the plant (:mod:`dualpilot.plant`). :class:`PlantVehicle` is the
in-process vehicle port that flies one: told the plan's first control, it flies
the Eq. (1) segment planned from the state it last reported (its measurement)
for one ΔT, and reports the measured state at the end. The ideal plant is
Eq. (1) exactly (the same :func:`dualpilot.model.dynamics.step` call as the
vehicle of today), so its states, and every number of a mission flown with it,
are bit-identical.

The multirotor is fed the segment's *velocities* (:func:`plan_stream`): the 20 Hz
stream of the motion whose velocity ramps from v_t to Eq. (1)'s v_{t+1} over the
step, p(s) = p_t + s·v_t + s²(v_{t+1} − v_t)/(2ΔT), with its velocity and
acceleration as feed-forward. Eq. (1) moves the position by ΔT·v_t only (its
acceleration shows in the position one step later), so a vehicle made to be at
Eq. (1)'s p_{t+1} *and* at v_{t+1} has to back up and then accelerate beyond its
tilt limit: replanned every step from its measured state, it never picks up speed
(measured: from hover under u = (7.5, 7.5) N it stays below 1.5 m/s per axis and
within 1 m of its start over 12 s, where Eq. (1) flies 155 m per axis). Flying the
velocities, it reaches Eq. (1)'s speeds; its path then departs from the planned
straight segment by up to
ΔT·‖v_{t+1} − v_t‖/2 while it accelerates or turns, which the tube margin covers
(:mod:`dualpilot.plant.reading`).

Safety is judged on the flight (:func:`judge_flight`): d_safe along the
plant's true path, every integration step's segment checked exactly against the
regions the step's failure rule counts (the rectangles in the plane in 2-D; in 3-D the
fronts' cuboids, at the exact 3-D distance,
:class:`~dualpilot.model.segment3.SegmentChecker3`). In 3-D the plant's altitude is the
model's z (up): the setpoints carry z and v_z, the measured state the vertical GPS error,
and the tracking error is the 3-D distance. A flight that passes within d_safe of a region
whose planned segment (Eq. (1)'s straight segment from the measured start) kept d_safe is
a ``tracking_breach``; one whose planned segment did not is a ``fire_contact``, as it
always was. A vehicle that reports no path (the ideal plant's,
in-process or in the stack) is judged on its straight segment. The stack's vehicle
flies the same plant (services/uavsim/plantsim.py: :func:`fly_ramp` towards each
setpoint's velocity) and reports its true path on the simulator's side channel
(services/supervisor/ports/plant.py), so the stack judges the flight as this loop does.
"""

from __future__ import annotations

from typing import Protocol, cast, runtime_checkable

import numpy as np

from dualpilot.mission.result import Ending
from dualpilot.model.dynamics import Array, DynamicsParams, step
from dualpilot.model.fire import Region
from dualpilot.model.geometry import Rect, SegmentChecker
from dualpilot.model.prism import Cuboid
from dualpilot.model.segment3 import SegmentChecker3
from dualpilot.plant.params import MultirotorParams
from dualpilot.plant.plant import Flight, IdealPlant, MultirotorPlant
from dualpilot.plant.setpoints import hermite_stream, segment_path


@runtime_checkable
class FlownPath(Protocol):
    """What a vehicle port that flies a plant tells the step beyond the measured state."""

    def true_position(self) -> Array:
        """Where the vehicle truly is (m, the mission's axes: x, y and, in 3-D, z)."""
        ...

    def flown_path(self) -> Array | None:
        """The last flight's true path (k, dim) at the integration rate (None: none flown, or
        a straight segment the step checks itself)."""
        ...

    def planned_path(self) -> Array:
        """The last flight's planned segment (2, dim): Eq. (1) from the measured start."""
        ...


def ramp_stream(start: Array, velocity: Array, dyn: DynamicsParams,
                params: MultirotorParams) -> Array:
    """The setpoints (S, 9) of [p, v, a] at ``params.setpoint_hz`` of the motion from
    ``start`` whose velocity ramps to ``velocity`` (m/s) over ΔT (module docstring; the cubic
    Hermite curve with these ends is that parabola)."""
    n = dyn.dim
    v1 = np.asarray(velocity, dtype=float)
    end = np.concatenate([start[:n] + 0.5 * dyn.dt_s * (start[n:] + v1), v1])
    return hermite_stream(start, end, dyn.dt_s, params.setpoint_hz, n, params.altitude_m)


def plan_stream(start: Array, control: Array, dyn: DynamicsParams,
                params: MultirotorParams) -> Array:
    """The setpoints (S, 9) of the step planned from ``start`` with ``control`` (N): the
    :func:`ramp_stream` to Eq. (1)'s v_{t+1}."""
    return ramp_stream(start, step(start, control, dyn)[dyn.dim:], dyn, params)


def fly_ramp(plant: MultirotorPlant, start: Array, velocity: Array) -> Flight:
    """One ΔT of the multirotor under :func:`ramp_stream` from ``start`` to ``velocity``
    (m/s), its reference Eq. (1)'s straight segment from ``start``. The stack's vehicle
    flies this towards its setpoint's velocity v_{t+1} (services/uavsim/plantsim.py)."""
    start = np.asarray(start, dtype=float)
    flight = plant.fly_stream(ramp_stream(start, velocity, plant.dyn, plant.params))
    reference = segment_path(start, flight.times_s, plant.dyn.dim, plant.params.altitude_m)
    return Flight(flight.times_s, flight.positions, flight.velocities, reference,
                  flight.state, flight.measured, flight.wind)


def fly_plan(plant: IdealPlant | MultirotorPlant, start: Array, control: Array) -> Flight:
    """One ΔT of the step planned from ``start`` with ``control``: the ideal plant steps
    Eq. (1); the multirotor flies :func:`plan_stream` (:func:`fly_ramp`)."""
    if isinstance(plant, IdealPlant):
        return plant.fly(start, control)
    return fly_ramp(plant, start, step(start, control, plant.dyn)[plant.dyn.dim:])


class PlantVehicle:
    """The in-process vehicle port flying a plant (module docstring).

    ``tracking_error_m`` collects each flight's distance (m) between the true path and the
    planned segment at every integration step, over the mission's axes (horizontal in 2-D,
    what its d_safe measures; 3-D in 3-D).
    """

    def __init__(self, plant: IdealPlant | MultirotorPlant):
        self.plant = plant
        self.dim = plant.dyn.dim
        self._start = plant.measure()
        self._control: Array | None = None
        self.flight: Flight | None = None
        self.tracking_error_m: list[Array] = []

    def measured(self) -> Array:
        """The measured model state now (what the step plans from)."""
        return self._start.copy()

    def command(self, target: Array, control: Array, after_s: float) -> None:
        self._control = np.asarray(control, dtype=float)

    def observe(self) -> Array:
        if self._control is not None:
            self.flight = fly_plan(self.plant, self._start, self._control)
            self._control = None
            self._start = self.plant.measure()
            self.tracking_error_m.append(self.flight.tracking_error_m(axes=self.dim)[1:])
        return self._start.copy()

    def true_position(self) -> Array:
        return np.asarray(self.plant.state[:self.dim])

    def flown_path(self) -> Array | None:
        if self.flight is None or isinstance(self.plant, IdealPlant):
            return None  # Eq. (1)'s path is the straight segment the step checks
        return np.asarray(self.flight.positions[:, :self.dim])

    def planned_path(self) -> Array:
        assert self.flight is not None
        return np.asarray(self.flight.reference[[0, -1], :self.dim])


def true_position(vehicle: object, measured: Array) -> Array:
    """Where the vehicle truly is (m): a plant's true position, else ``measured``, the
    measured state's position (the stack's vehicle reports no other)."""
    if isinstance(vehicle, FlownPath):
        return vehicle.true_position()
    return np.asarray(measured)


def path_clear(path: Array, regions: tuple[Region, ...], d_m: float) -> bool:
    """Whether the polyline ``path`` (k, 2) or (k, 3) keeps at least ``d_m`` (m) from every
    region, each of its segments checked exactly: rectangles in the plane
    (:class:`~dualpilot.model.geometry.SegmentChecker`), cuboids in 3-D at the exact 3-D
    distance (:class:`~dualpilot.model.segment3.SegmentChecker3`)."""
    if not regions:
        return True
    if path.shape[1] == 3:
        if not all(isinstance(r, Cuboid) for r in regions):
            raise ValueError("a 3-D flown path is judged against cuboids")
        checker3 = SegmentChecker3([cast(Cuboid, r).prism for r in regions])
        return bool(checker3.clear(path[:-1], path[1:], d_m).all())
    checker = SegmentChecker([r.polytope() for r in regions if isinstance(r, Rect)])
    if checker.n_hulls != len(regions):
        raise ValueError("a planar flown path is judged against rectangles")
    return bool(checker.clear(path[:-1], path[1:], d_m).all())


def judge_flight(vehicle: object, regions: tuple[Region, ...], d_safe_m: float
                 ) -> tuple[Ending | None, tuple[Region, ...]]:
    """The plant's last flown path judged against ``regions`` at ``d_safe_m`` (m): (FIRE_CONTACT
    or TRACKING_BREACH when it came within d_safe, by whether its planned segment did too,
    else None; the regions the step's straight-segment check still has to judge: none once
    a path was judged, all of them for a vehicle that reports no curved path)."""
    if not isinstance(vehicle, FlownPath):
        return None, regions
    path = vehicle.flown_path()
    if path is None:
        return None, regions
    if path_clear(path, regions, d_safe_m):
        return None, ()
    if path_clear(vehicle.planned_path(), regions, d_safe_m):
        return Ending.TRACKING_BREACH, ()
    return Ending.FIRE_CONTACT, ()


@runtime_checkable
class TrackingLog(Protocol):
    """A vehicle port that collects each flight's tracking error (m, at every integration
    step): :class:`PlantVehicle`, and the stack's port of a plant's vehicle."""

    tracking_error_m: list[Array]


def tracking_errors(vehicle: object) -> list[Array]:
    """The flights' tracking errors a :class:`TrackingLog` collected (else none)."""
    return vehicle.tracking_error_m if isinstance(vehicle, TrackingLog) else []

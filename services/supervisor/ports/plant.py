"""The vehicle port of a plant's vehicle: the autopilot's estimate on MAVLink, the truth beside.

A mission whose plant is not Eq. (1) (``plant=multirotor``) is flown by uavsim's plant
(services/uavsim/plantsim.py). The step plans from the measured state, which
LOCAL_POSITION_NED carries (:class:`StackVehicle`), and judges the flight on the truth,
as the in-process :class:`~dualpilot.mission.flight.PlantVehicle` does: where the vehicle
truly is, the path it flew at the integration rate and the planned segment from the
measured start (:class:`~dualpilot.mission.flight.FlownPath`), and each flight's
tracking error (:class:`~dualpilot.mission.flight.TrackingLog`), in the mission's dimension
(3-D in a 3-D mission). The truth comes from the
simulator's side channel (``<ns>/uavsim/flight``, services/uavsim/truth.py): after each
state, the flight that ended at its time; before the first, the plant at rest.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np

from dualpilot.mission.config import MissionConfig
from dualpilot.model.dynamics import Array
from services.common import bus, keys, rejections, wire
from services.common.convert import plant as plant_convert
from services.msgs import common_pb2, plant_pb2

from ..link import VehicleLink
from .stackbus import Aborted, StackBus
from .vehicle import StackVehicle

log = logging.getLogger(__name__)

#: how long (wall s) to wait between two asks for a flight the vehicle has not reported yet
RETRY_S = 0.01


class PlantStackVehicle(StackVehicle):
    """:class:`StackVehicle` with the plant's truth (module docstring)."""

    def __init__(self, b: StackBus, link: VehicleLink, dt_s: float,
                 ensure_offboard: Callable[[], None]):
        super().__init__(b, link, dt_s, ensure_offboard)
        self.key = keys.sim_flight(b.uav)
        self.truth: plant_convert.FlightTruth | None = None
        self.tracking_error_m: list[Array] = []

    def observe(self) -> Array:
        state = super().observe()
        self.truth = self.ask(self.due_ms)
        if len(self.truth.path):
            self.tracking_error_m.append(self.truth.tracking_error_m())
        return state

    def ask(self, after_ms: int) -> plant_convert.FlightTruth:
        """The plant's latest flight ended at or after ``after_ms`` (the vehicle's clock);
        Aborted when the vehicle does not give it within ``vehicle_timeout_s``."""
        b = self.b
        deadline = b.wall.now() + b.stack.vehicle_timeout_s
        request = plant_convert.request_msg(after_ms, b.stamper)
        while True:
            left = deadline - b.wall.now()
            try:
                payload, enc = b.query(self.key, request, max(left, 0.0),
                                       trusted=b.trusted("uavsim"))
                return plant_convert.flight_from_msg(wire.parse(payload, plant_pb2.PlantFlight,
                                                                enc))
            except rejections.CodecError as err:
                rejections.rejected("PlantFlight", err, log, key=self.key)
                raise Aborted(f"the vehicle's ground truth: {err}") from err
            except bus.QueryError as err:
                if err.code != common_pb2.ERROR_CODE_UNAVAILABLE or left <= 0:
                    raise Aborted(f"the vehicle's ground truth: {err}") from err
            except TimeoutError as err:
                raise Aborted(f"the vehicle gave no ground truth: {err}") from err
            if b.wait(RETRY_S):
                raise Aborted("stopped")

    def start_position(self, measured: Array) -> tuple[float, float]:
        """Where the mission starts: the plant's true position (its estimate is ``measured``)."""
        self.truth = self.ask(0)
        return float(self.truth.state[0]), float(self.truth.state[1])

    def true_position(self) -> Array:
        if self.truth is None:
            self.truth = self.ask(0)
        return np.asarray(self.truth.state[:self.truth.dim])

    def flown_path(self) -> Array | None:
        if self.truth is None or not len(self.truth.path):
            return None
        return np.asarray(self.truth.path)

    def planned_path(self) -> Array:
        assert self.truth is not None and len(self.truth.planned)
        return np.asarray(self.truth.planned[[0, -1]])


def vehicle_port(b: StackBus, link: VehicleLink, config: MissionConfig, dt_s: float,
                 ensure_offboard: Callable[[], None]) -> StackVehicle:
    """The vehicle port of ``config``'s plant: :class:`StackVehicle` for Eq. (1) (its state is
    the truth), :class:`PlantStackVehicle` else."""
    if config.reading().plant.plant == "ideal":
        return StackVehicle(b, link, dt_s, ensure_offboard)
    return PlantStackVehicle(b, link, dt_s, ensure_offboard)

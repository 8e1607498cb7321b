"""plant.proto ↔ core types: the simulated plant's ground truth over one flight.

:class:`FlightTruth` is what the supervisor's port of a plant's vehicle needs beyond
the autopilot's estimate to judge a flight as the in-process loop does
(dualpilot/mission/flight.py): the true position, the true path at the integration
rate and Eq. (1)'s planned segment at the same times. The decoder checks sizes,
finiteness and ranges (services/common/limits.py) and that path and planned segment
pair up; a bad message raises :class:`~services.common.rejections.CodecError`. A 3-D
mission's flight (``dim`` 3) carries the altitude and the climb, and its path and planned
segment as (east, north, up) triples; a 2-D one is the message it always was.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dualpilot.model.dynamics import Array
from services.common.convert.common import packed_from_msg, packed_to_msg
from services.common.limits import MAX_ABS_M, check_altitudes, check_int, check_state_values
from services.common.rejections import Reason, invalid
from services.common.wire import Stamper
from services.msgs import plant_pb2

#: the most points of one flight's path (a ΔT of 60 s at 1 kHz)
MAX_PATH_POINTS = 60_001
#: the vehicle's clock (ms since boot) is at most this (about 31,700 years)
MAX_TIME_MS = 1 << 50


@dataclass(frozen=True)
class FlightTruth:
    """The plant's latest flight: ``time_ms`` the vehicle's clock at its end, ``state`` the
    true [p, v] now (m, m/s; the mission's dimension), ``path`` and ``planned`` (k, dim) the
    true path and Eq. (1)'s straight segment from the measured start at the integration
    times (m; k = 0 before the first flight), ``flights`` how many the plant has flown."""

    time_ms: int
    state: Array
    path: Array
    planned: Array
    flights: int

    @property
    def dim(self) -> int:
        """The mission's dimension (2 or 3)."""
        return len(self.state) // 2

    def tracking_error_m(self) -> Array:
        """The distance (m) between path and planned segment after the flight's start, over
        the mission's axes (as :meth:`dualpilot.plant.Flight.tracking_error_m` with ``axes``
        the dimension, ``[1:]``)."""
        return np.asarray(np.linalg.norm(self.path - self.planned, axis=1)[1:])


def request_msg(after_ms: int, stamper: Stamper) -> plant_pb2.PlantFlightRequest:
    m = plant_pb2.PlantFlightRequest(after_ms=int(after_ms))
    stamper.stamp(m.header)
    return m


def request_from_msg(m: plant_pb2.PlantFlightRequest) -> int:
    """The request's ``after_ms`` (checked)."""
    return check_int(int(m.after_ms), "after_ms", 0, MAX_TIME_MS)


def flight_msg(truth: FlightTruth, stamper: Stamper) -> plant_pb2.PlantFlight:
    m = plant_pb2.PlantFlight(time_ms=int(truth.time_ms), flights=int(truth.flights))
    stamper.stamp(m.header)
    x = check_state_values(np.asarray(truth.state, dtype=float), "true state")
    n = len(x) // 2
    m.position.east_m, m.position.north_m = float(x[0]), float(x[1])
    m.velocity_mps.east_m, m.velocity_mps.north_m = float(x[n]), float(x[n + 1])
    if n == 3:
        m.dim, m.altitude_m, m.velocity_up_mps = 3, float(x[2]), float(x[5])
    packed_to_msg(truth.path, m.path_m)
    packed_to_msg(truth.planned, m.planned_m)
    return m


def _state_from_msg(m: plant_pb2.PlantFlight) -> Array:
    """The true state the message carries: [p, v] of its ``dim`` (checked)."""
    e, n, ve, vn = (m.position.east_m, m.position.north_m, m.velocity_mps.east_m,
                    m.velocity_mps.north_m)
    if m.dim == 3:
        return check_state_values(np.array([e, n, m.altitude_m, ve, vn, m.velocity_up_mps]),
                                  "true state")
    if m.dim not in (0, 2) or m.altitude_m or m.velocity_up_mps:
        raise invalid(f"a flight of dim {m.dim} (2 or 3; an altitude or climb only in 3-D)",
                      Reason.SIZE)
    return check_state_values(np.array([e, n, ve, vn]), "true state")


def flight_from_msg(m: plant_pb2.PlantFlight) -> FlightTruth:
    time_ms = check_int(int(m.time_ms), "time_ms", 0, MAX_TIME_MS)
    x = _state_from_msg(m)
    dim = len(x) // 2
    path = packed_from_msg(m.path_m, "true path", dim, MAX_PATH_POINTS, MAX_ABS_M)
    planned = packed_from_msg(m.planned_m, "planned segment", dim, MAX_PATH_POINTS, MAX_ABS_M)
    if path.shape != planned.shape or len(path) == 1:
        raise invalid(f"a flight of {len(path)} path and {len(planned)} planned points (as "
                      "many, none or at least 2)", Reason.SIZE)
    if dim == 3:
        check_altitudes(path[:, 2].tolist(), "true path altitude")
        check_altitudes(planned[:, 2].tolist(), "planned segment altitude")
    if len(path) and not np.allclose(path[-1], x[:dim], rtol=0.0, atol=1e-9):
        raise invalid("the true path does not end at the true position")
    return FlightTruth(time_ms, x, path, planned, int(m.flights))

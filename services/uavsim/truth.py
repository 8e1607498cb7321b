"""The simulator's side channel: the plant's ground truth, on ``<ns>/uavsim/flight``.

A vehicle flying a plant other than Eq. (1) (services/uavsim/plantsim.py) reports its
autopilot's estimate on MAVLink; where it truly flew is what a simulator knows and an
autopilot does not (as Gazebo's ground-truth topic beside PX4 SITL). The supervisor's
port of a plant's vehicle (services/supervisor/ports/plant.py) asks for the latest
flight ended at or after a time on the vehicle's clock (``PlantFlightRequest``) and
judges it as the in-process loop judges its plant's flight (dualpilot/mission/flight.py).

The callback only enqueues; the vehicle's loop answers between two passes
(services/uavsim/sidechannel.py), so a reply never sees half a flight. A request that does
not decode, a vehicle flying the ideal plant (it has no truth apart from its state) and
a flight not flown yet get an error reply (a bad request counted per key and reason).
"""

from __future__ import annotations

import zenoh

from services.common import keys, rejections, wire
from services.common.convert import plant as plant_convert
from services.msgs import common_pb2, plant_pb2

from .sidechannel import SideChannel
from .vehicle import Vehicle


def unavailable(message: str) -> rejections.CodecError:
    """What the vehicle cannot give (yet): an UNAVAILABLE error reply, not a bad request."""
    return rejections.CodecError(common_pb2.ERROR_CODE_UNAVAILABLE, message,
                                 rejections.Reason.UNAVAILABLE)


def answer(vehicle: Vehicle, stamper: wire.Stamper, payload: bytes,
           encoding: str) -> plant_pb2.PlantFlight:
    """The reply to one request (CodecError: a bad request; UNAVAILABLE: the ideal plant, a
    flight not flown yet)."""
    after_ms = plant_convert.request_from_msg(
        wire.parse(payload, plant_pb2.PlantFlightRequest, encoding))
    if vehicle.plant is None:
        raise unavailable("this vehicle flies the ideal plant (Eq. (1)): its state is the truth")
    truth = vehicle.plant.truth()
    if truth.time_ms < after_ms:
        raise unavailable(f"no flight ended at or after {after_ms} ms yet (the latest: "
                          f"{truth.time_ms} ms)")
    return plant_convert.flight_msg(truth, stamper)


def flight_truths(session: zenoh.Session, uav: str, vehicle: Vehicle) -> SideChannel:
    """The ``uavsim/flight`` queryable of one vehicle, answered from its loop."""
    stamper = wire.Stamper("uavsim", uav)
    return SideChannel(session, keys.sim_flight(uav),
                       lambda item: answer(vehicle, stamper, item.payload, item.encoding),
                       "PlantFlightRequest", stamper, max_items=64, max_bytes=64 * 1024)

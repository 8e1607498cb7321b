"""The mission step's ports over the stack, one port a module.

Each adapter turns a port call of :class:`dualpilot.mission.step.Mission`
into messages and back, checking every reply before it acts
(services/common/convert/). Time is the lockstep SimClock
(services/common/clock.py): the fires' sub-steps and the vehicle's ΔT advance
it.

- ``params.py``: how the supervisor talks to the stack (:class:`StackParams`).
- ``stackbus.py``: what every adapter shares (:class:`StackBus`): the
  transport to the services, the vehicle id, the clocks, the stop event; and
  :class:`Aborted`.
- ``fires.py``: the fire port over the EWS (:class:`StackFires`), and
  ``forecasts.py`` its occupancy forecasts (:class:`StackForecasts`).
- ``planners.py``: the planner port over the planner pool (:class:`StackPlanners`).
- ``vehicle.py``: the vehicle port over MAVLink (:class:`StackVehicle`), and ``plant.py``
  that of a plant's vehicle, with the simulator's ground truth (:class:`PlantStackVehicle`).
"""

from services.supervisor.ports.fires import StackFires
from services.supervisor.ports.forecasts import StackForecasts
from services.supervisor.ports.params import StackParams
from services.supervisor.ports.planners import StackPlanners
from services.supervisor.ports.plant import PlantStackVehicle, vehicle_port
from services.supervisor.ports.stackbus import (
    Aborted,
    MonotonicClock,
    StackBus,
    StackTransport,
    WallClock,
    ZenohStackTransport,
)
from services.supervisor.ports.vehicle import StackVehicle

__all__ = ["Aborted", "MonotonicClock", "PlantStackVehicle", "StackBus", "StackFires",
           "StackForecasts", "StackParams", "StackPlanners", "StackTransport", "StackVehicle",
           "WallClock", "ZenohStackTransport", "vehicle_port"]

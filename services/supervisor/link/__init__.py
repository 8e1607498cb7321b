"""The supervisor's MAVLink link to its vehicle: an offboard companion, in MAVSDK/PX4 order.

One concern a module, as MAVProxy's modules (link, mode, arm, cmdlong, wp):
each component handles the messages it names and sends what it must, with
its own small interface; :class:`~services.supervisor.link.vehicle.VehicleLink`
only puts them together, reads the link and hands each frame to its
component.

- ``connection.py``: the MAVLink connection, filtered to the vehicle's
  autopilot, its frames dispatched by type; the companion's HEARTBEAT.
- ``heartbeat.py``: what the vehicle's HEARTBEAT says (autopilot, mode,
  arming, every change and each time it left offboard control) and whether it
  is still alive.
- ``position.py``: LOCAL_POSITION_NED (with the vehicle's ``time_boot_ms``),
  GLOBAL_POSITION_INT and the geodetic origin.
- ``setpoints.py``: the current SET_POSITION_TARGET_LOCAL_NED and its stream
  (the stream process, services/supervisor/stream/, or a thread).
- ``commands.py``: COMMAND_LONG and its COMMAND_ACK, with retries.
- ``takeover.py``: taking the vehicle: heartbeat, position, setpoints,
  offboard mode, arm.
- ``mission.py``: the operator's mission, downloaded whenever ``MIS_ID``
  changes (mission protocol).
- ``params.py``: the link's settings (:class:`LinkParams`).
"""

from services.supervisor.link.heartbeat import ModeChange
from services.supervisor.link.params import STREAMS, LinkParams
from services.supervisor.link.takeover import OffboardError
from services.supervisor.link.vehicle import VehicleLink

__all__ = ["STREAMS", "LinkParams", "ModeChange", "OffboardError", "VehicleLink"]

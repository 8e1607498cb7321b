"""What a ground station sees of the air: the plant's wind, as each autopilot reports it.

A vehicle flying the mission's multirotor (services/uavsim/plantsim.py) flies through
the mission's wind (steady, Dryden turbulence, gusts: :mod:`dualpilot.plant.wind`) and
tells its ground station about it once a second (services/uavsim/intervals.py), as
the autopilot it claims to be does, from the air it flew through over the last second
(:meth:`~services.uavsim.plantsim.PlantSim.air`: a smoothed value, as the autopilots'
estimators give):

* **PX4**: WIND_COV (common dialect; PX4's ``MavlinkStreamWindCov``): ``wind_x``,
  ``wind_y``, ``wind_z`` the air's velocity north, east and down (m/s), ``var_horiz``
  and ``var_vert`` its variances (m²/s²), ``wind_alt`` the altitude (m AMSL);
  the accuracies are not known (NaN);
* **ArduPilot**: WIND (ardupilotmega dialect; ArduPilot's ``GCS_MAVLINK::send_wind``):
  ``direction`` where the wind comes *from* (deg, ``atan2(−east, −north)``, as
  ArduPilot computes it), ``speed`` the length of the wind vector (m/s) and ``speed_z``
  its down component (m/s).

A vehicle flying Eq. (1) (the ideal plant) has no air: it sends neither, as before.
"""

from __future__ import annotations

import math

from services.common import mav

from .autopilot import Autopilot
from .outbox import Outbox

m = mav.mavlink
#: the wind messages: PX4's and ArduPilot's
WIND_IDS = (m.MAVLINK_MSG_ID_WIND_COV, m.MAVLINK_MSG_ID_WIND)


def own_wind_id(ap: Autopilot) -> int:
    """The wind message of the autopilot ``ap`` claims to be."""
    ardupilot = ap.flavour.autopilot == m.MAV_AUTOPILOT_ARDUPILOTMEGA
    return int(m.MAVLINK_MSG_ID_WIND if ardupilot else m.MAVLINK_MSG_ID_WIND_COV)


def has_wind(ap: Autopilot, msg_id: int) -> bool:
    """Whether ``ap`` sends ``msg_id`` (its flavour's wind message, while a plant flies)."""
    return ap.vehicle.plant is not None and msg_id == own_wind_id(ap)


def send_wind(ap: Autopilot, outbox: Outbox, msg_id: int, amsl_m: float,
              link: str | None = None) -> None:
    """Send ``msg_id`` (WIND_COV or WIND) if :func:`has_wind` (module docstring); ``amsl_m``
    the vehicle's altitude above mean sea level (m)."""
    plant = ap.vehicle.plant
    if plant is None or not has_wind(ap, msg_id):
        return
    (east, north, up), var_h, var_v = plant.air()
    east, north, down = float(east), float(north), -float(up)
    if msg_id == m.MAVLINK_MSG_ID_WIND:
        direction = math.degrees(math.atan2(-east, -north))
        outbox.send(link, "wind", direction, math.sqrt(east**2 + north**2 + down**2), down)
        return
    nan = float("nan")
    outbox.send(link, "wind_cov", ap.vehicle.time_ms * 1000, north, east, down, var_h, var_v,
                amsl_m, nan, nan)

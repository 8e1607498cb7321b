"""The offboard-loss failsafe (PX4 ``COM_OF_LOSS_T`` / ``COM_OF_RSM_T``), on either clock.

In offboard mode, no setpoint for ``COM_OF_LOSS_T`` s of wall time: the
vehicle reports the failsafe (hold mode: LOITER, AUTO.LOITER; a STATUSTEXT;
``SIM_FAILSAFES`` + 1). Setpoints take control back only once the stream has
been live again for ``COM_OF_RSM_T`` s; a commanded mode change ends it.

What the hold does depends on who keeps time (services/uavsim/clock.py):

* **realtime** (PX4 SITL): the vehicle's own clock runs on, so it brakes to
  a stop and holds there.
* **lockstep** (the stack): the supervisor is the clock. Between two stamps
  no simulated time passes, so a silent companion means the simulated world
  is paused, not that the vehicle drifts: the vehicle holds *as it is* —
  same position, same velocity, same clock — and the next stamp after the
  resume flies on from exactly there. The failsafe stays visible to a
  ground station (mode, STATUSTEXT, parameter) and the supervisor records
  it as the fault ``vehicle_hold`` (services/supervisor/faults.py), but it
  never changes the mission's simulated state.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from services.common.log import fields

from . import flavour as fl

if TYPE_CHECKING:
    from .endpoint import Endpoint

log = logging.getLogger("services.uavsim")


def check_offboard(ep: Endpoint, now: float) -> None:
    """Enter the failsafe when the stream is lost; leave it when the stream is back.

    Call it after the waiting datagrams were read: a vehicle process that was
    itself kept off the CPU must find the setpoints queued for it first.
    """
    if ep.mode == fl.OFFBOARD and ep.last_setpoint and not ep.stream_live(now):
        ep.failsafe = True
        ep.failsafe_since = now
        ep.stream_stats.failsafe()
        ep.set_param("SIM_FAILSAFES", ep.p("SIM_FAILSAFES") + 1)
        silence = round(now - ep.last_setpoint, 3)
        if ep.realtime is not None:
            ep.vehicle.brake()
            log.warning("offboard setpoints lost: braking to a hold", extra=fields(
                silence_s=silence))
            ep.set_mode(fl.HOLD, "offboard lost, holding")
        else:
            log.warning("offboard setpoints lost: holding as it is (lockstep: no simulated "
                        "time passes until the next setpoint)", extra=fields(
                            silence_s=silence, time_ms=ep.vehicle.time_ms))
            ep.set_mode(fl.HOLD, "offboard lost, paused")
    elif (ep.failsafe and ep.mode == fl.HOLD and ep.stream_live(now)
          and now - ep.stream_since >= ep.p("COM_OF_RSM_T")):
        log.info("offboard setpoints back: resuming", extra=fields(
            held_s=round(now - ep.failsafe_since, 3)))
        ep.end_failsafe(now)
        ep.set_mode(fl.OFFBOARD, "offboard stream back")

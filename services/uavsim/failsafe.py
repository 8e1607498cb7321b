"""The offboard-loss failsafe (PX4 ``COM_OF_LOSS_T`` / ``COM_OF_RSM_T``), in wall time.

In offboard mode, no setpoint for ``COM_OF_LOSS_T`` s: the vehicle brakes to a
stop and holds (the flavour's hold mode: LOITER, AUTO.LOITER). Setpoints take
control back only once the stream has been live again for ``COM_OF_RSM_T`` s;
a commanded mode change ends the failsafe.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from services.common.log import fields

from . import flavour as fl

if TYPE_CHECKING:
    from .__main__ import Endpoint

log = logging.getLogger("services.uavsim")


def check_offboard(ep: Endpoint, now: float) -> None:
    """Enter the failsafe when the stream is lost; leave it when the stream is back."""
    if ep.mode == fl.OFFBOARD and ep.last_setpoint and not ep.stream_live(now):
        ep.failsafe = True
        ep.vehicle.brake()
        log.warning("offboard setpoints lost: holding", extra=fields(
            silence_s=round(now - ep.last_setpoint, 3)))
        ep.set_mode(fl.HOLD, "offboard lost, holding")
    elif (ep.failsafe and ep.mode == fl.HOLD and ep.stream_live(now)
          and now - ep.stream_since >= ep.p("COM_OF_RSM_T")):
        ep.failsafe = False
        log.info("offboard setpoints back: resuming")
        ep.set_mode(fl.OFFBOARD, "offboard stream back")

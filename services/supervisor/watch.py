"""The session's watch on its vehicle: taken, paused while it is not flying offboard, gone.

:meth:`OffboardWatch.take` puts the vehicle under offboard control before the
first step (services/supervisor/link/takeover.py). Between steps (and while
the vehicle port waits for a state) :meth:`OffboardWatch.ensure` pauses the
mission while the vehicle is not flying offboard — lost (no heartbeat for the
link's 3 s: the ``vehicle_lost`` fault) or put in hold — and takes it again
when it comes back; a vehicle whose heartbeat and liveliness token are both
gone for ``vehicle_gone_s`` ends the mission (:class:`VehicleGone`). Time is
the bus's wall clock, so the rule runs on a fake one in a unit test.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from services.common.log import fields

from . import faults as fault_names
from .faults import FaultLog
from .link import OffboardError, VehicleLink
from .pause import PausePolicy
from .ports import Aborted, StackBus

log = logging.getLogger("services.supervisor.session")


class VehicleGone(Aborted):
    """The vehicle is lost for good: its token is gone and its heartbeat too (the mission ends)."""


@dataclass
class _Absence:
    """What one pause has seen of the vehicle: lost (no heartbeat), and since when it is gone
    (no heartbeat and no liveliness token; wall s)."""

    lost: bool
    gone_since: float | None = None


class OffboardWatch:
    """Takes the vehicle and keeps the mission paused while it is not flying offboard."""

    def __init__(self, b: StackBus, link: VehicleLink, pause: PausePolicy, faults: FaultLog):
        self.b = b
        self.link = link
        self.pause = pause
        self.faults = faults

    def take(self) -> None:
        """Put the vehicle under offboard control (Aborted when it cannot be)."""
        try:
            self.link.takeover.start_offboard(self.b.stop, self.b.stack.offboard_timeout_s)
        except OffboardError as err:
            raise Aborted(f"vehicle: {err}") from err
        if self.b.stop.is_set():
            raise Aborted("stopped")
        log.info("vehicle under offboard control",
                 extra=fields(status=self.link.status.status()))

    def ensure(self) -> None:
        """Pause while the vehicle is not flying offboard; take it again when it comes back."""
        status = self.link.status
        if status.offboard():
            return
        lost = not status.alive()
        if lost:
            self.faults.note(fault_names.VEHICLE_LOST)
        reason = ("vehicle lost: no heartbeat for 3 s" if lost
                  else f"vehicle not flying offboard ({status.status()})")
        absence = _Absence(lost)
        self.pause.hold(reason, status.offboard, lambda _paused: self._tick(absence))

    def _tick(self, absence: _Absence) -> None:
        """Each time round the pause: notice a loss, a return (take the vehicle again) or a
        vehicle gone for good (VehicleGone)."""
        b, status = self.b, self.link.status
        gone = not status.alive() and not b.alive("uavsim")
        now = b.wall.now()
        if not gone:
            absence.gone_since = None
        elif absence.gone_since is None:
            absence.gone_since = now
        elif now - absence.gone_since > b.stack.vehicle_gone_s:
            raise VehicleGone(f"vehicle lost: no heartbeat and its liveliness token gone "
                              f"for {b.stack.vehicle_gone_s:g} s")
        if not status.alive():
            if not absence.lost:
                self.faults.note(fault_names.VEHICLE_LOST)
            absence.lost = True
        elif absence.lost:  # back after a loss: take it again (the steps it still needs)
            absence.lost = False
            try:
                self.link.takeover.start_offboard(b.stop, b.stack.offboard_timeout_s)
            except OffboardError as err:
                log.warning("could not take the vehicle back", extra=fields(error=str(err)))

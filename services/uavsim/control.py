"""Who may steer the vehicle: one link and one peer on it at a time (:class:`ControlArbiter`).

The vehicle has an offboard link (the companion: the supervisor, MAVSDK) and
a ground-station link. Control messages (setpoints, arming, mode changes,
take-off, landing, return, reposition) count only from the link in control
and, on it, from one peer (address, system, component):

* The offboard link is in control at boot.
* A ground station takes over with an accepted mode change, return, landing,
  reposition, mission start or forced disarm (the operator's explicit
  take-over), or with any control message while the link in control is lost
  (no frame from it for COM_DL_LOSS_T, or never one: a lone vehicle that a
  ground station flies).
* It hands control back by asking for offboard mode while the offboard link
  streams setpoints; the companion's stream during the take-over keeps that
  link's signal live without flying it (:meth:`ControlArbiter.waiting`).
* On the link in control a second peer is refused until the first has been
  silent for COM_OF_LOSS_T.

:meth:`ControlArbiter.check` answers before the command runs;
:meth:`ControlArbiter.commit` makes its :class:`Decision` the new state once
the command was accepted, so a refused command never moves control.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from services.common.log import fields

log = logging.getLogger("services.uavsim")

OFFBOARD, GCS = "offboard", "gcs"
Peer = tuple[Any, int, int]  #: (address, system id, component id)


@dataclass(frozen=True)
class Decision:
    """The answer to one control message: refused (why), or the control it leaves."""

    refused: str = ""  #: why not ('' when allowed)
    link: str = OFFBOARD  #: the link in control afterwards
    controller: Peer | None = None  #: the peer in control afterwards (None: the next to stream)


@dataclass
class ControlArbiter:
    """The link and peer in control (module docstring); times are monotonic s."""

    loss_s: Callable[[], float]  #: COM_OF_LOSS_T
    link_loss_s: Callable[[], float]  #: COM_DL_LOSS_T
    link: str = OFFBOARD
    controller: Peer | None = None
    controller_heard: float = 0.0
    heard: dict[str, float] = field(default_factory=dict)  #: the last usable frame per link

    def heard_on(self, link: str, now: float) -> None:
        """A usable frame arrived on ``link``."""
        self.heard[link] = now

    def lost(self, link: str, now: float) -> bool:
        """No frame on ``link`` for COM_DL_LOSS_T (or never one)."""
        last = self.heard.get(link)
        return last is None or now - last > self.link_loss_s()

    def waiting(self, link: str) -> bool:
        """A setpoint on ``link`` is the companion waiting for a hand-back: not flown, not
        refused (the offboard link's stream while a ground station is in control)."""
        return link == OFFBOARD and self.link == GCS

    def check(self, link: str, peer: Peer, now: float, takeover: bool = False,
              hands_back: bool = False) -> Decision:
        """May ``peer`` on ``link`` send this control message? ``takeover``: it is one a
        ground station takes control with; ``hands_back``: it asks for offboard mode while
        the offboard link streams."""
        if link != self.link:
            if not ((link == GCS and takeover) or self.lost(self.link, now)):
                return Decision(f"the {self.link} link is in control", self.link,
                                self.controller)
        elif (self.controller is not None and self.controller != peer
              and now - self.controller_heard <= self.loss_s()):
            return Decision(f"a second peer {peer[1]}:{peer[2]} while {self.controller[1]}:"
                            f"{self.controller[2]} is in control", self.link, self.controller)
        if link == GCS and hands_back:
            return Decision("", OFFBOARD, None)
        return Decision("", link, peer)

    def commit(self, decision: Decision, now: float) -> None:
        """The command ``decision`` allowed was carried out: control is as it says."""
        if decision.refused:
            return
        if decision.link != self.link:
            log.warning("control moves", extra=fields(to=decision.link, was=self.link,
                                                      peer=str(decision.controller)))
        elif decision.controller != self.controller and self.controller is not None:
            log.info("controller changed", extra=fields(link=decision.link,
                                                        peer=str(decision.controller)))
        self.link, self.controller = decision.link, decision.controller
        if decision.controller is not None:
            self.controller_heard = now

"""The one pause/resume policy of a stack mission.

A mission pauses while something it needs is missing: the vehicle is not
flying offboard (lost for 3 s, or put in hold by a ground station), or no
planner of its controller is alive. While paused nothing advances (the clock
is lockstep); the pause is announced (PAUSED, with its reason), ends when the
need is met (RESUMED) and aborts the mission when it lasts longer than
``limit_s`` or the supervisor is stopped. What to do while waiting (take the
vehicle again when it is back, notice it is gone for good) is the caller's
``tick``; time comes from an injected clock, so the policy is unit-tested
without a process (tests/unit/services/supervisor/test_pause.py).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from services.common.log import fields

from .ports import Aborted

log = logging.getLogger("services.supervisor.session")

#: announce(kind, message): "paused" or "resumed", with its reason
Announce = Callable[[str, str], None]


@dataclass
class PausePolicy:
    """Pauses the mission until a condition holds; aborts it after ``limit_s``."""

    stop: threading.Event
    limit_s: float
    announce: Announce
    clock: Callable[[], float] = time.monotonic
    #: how the wait between checks is spent (default: the stop event's wait)
    wait: Callable[[float], object] | None = None
    pauses: int = 0
    paused_s: float = field(default=0.0)

    def hold(self, reason: str, until: Callable[[], bool],
             tick: Callable[[float], None] | None = None, period_s: float = 0.05,
             resumed: Callable[[float], str] = lambda s: f"paused {s:.1f} s") -> float:
        """Pause (PAUSED ``reason``) until ``until()``; ``tick(paused_s)`` each time round.

        Returns the seconds paused after announcing RESUMED (``resumed(s)`` its message);
        raises Aborted when stopped or past ``limit_s`` (and whatever ``tick`` raises).
        """
        t0 = self.clock()
        self.pauses += 1
        log.warning("mission paused", extra=fields(reason=reason))
        self.announce("paused", reason)
        while not until():
            if self.stop.is_set():
                raise Aborted("stopped")
            paused = self.clock() - t0
            if paused > self.limit_s:
                raise Aborted(f"paused for more than {self.limit_s:g} s: {reason}")
            if tick is not None:
                tick(paused)
            (self.wait or self.stop.wait)(period_s)
        paused = self.clock() - t0
        self.paused_s += paused
        log.info("mission resumed", extra=fields(paused_s=round(paused, 3)))
        self.announce("resumed", resumed(paused))
        return paused

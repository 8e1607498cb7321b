"""The vehicle's two clocks: lockstep (our missions) and real time (standard offboard clients).

* **lockstep** (``--clock lockstep``, the stack's mode): the supervisor stamps
  each setpoint with the simulated time it is due (``time_boot_ms``) and each
  new stamp is one ΔT step of Eq. (1) (services/common/clock.py); repeats are
  the keep-alive stream. A mission is then reproducible at any speed factor.
* **realtime** (``--clock realtime``, as PX4 SITL): the vehicle integrates
  Eq. (1) on its own clock, one ΔT step every ΔT / ``speed_factor`` wall
  seconds towards the newest setpoint; ``time_boot_ms`` of a setpoint is
  ignored (MAVSDK stamps its host's uptime). The simulated clock runs from
  boot whether or not the vehicle flies.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

LOCKSTEP = "lockstep"
REALTIME = "realtime"
CLOCKS = (LOCKSTEP, REALTIME)


@dataclass
class RealtimeClock:
    """Simulated ms since boot at ``speed_factor`` × wall time; steps due every ``dt_ms``."""

    speed_factor: float = 1.0
    dt_ms: int = 1000
    t0: float = field(default_factory=time.monotonic)
    next_step_ms: int = 1000

    def __post_init__(self) -> None:
        if not self.speed_factor > 0:
            raise ValueError(f"a real-time vehicle needs a speed factor > 0, got "
                             f"{self.speed_factor}")
        self.next_step_ms = self.dt_ms

    def now_ms(self, now: float) -> int:
        return int((now - self.t0) * self.speed_factor * 1000.0)

    def due_steps(self, now: float, limit: int = 10) -> list[int]:
        """The step times (simulated ms) that have come due since the last call (at most
        ``limit``: a process stalled for long skips ahead rather than flying a burst)."""
        sim = self.now_ms(now)
        due: list[int] = []
        while self.next_step_ms <= sim:
            if len(due) < limit:
                due.append(self.next_step_ms)
            self.next_step_ms += self.dt_ms
        return due

    def wall_until_next(self, now: float) -> float:
        """Wall seconds until the next step is due (0 if it is)."""
        ahead_ms = self.next_step_ms - self.now_ms(now)
        return max(0.0, ahead_ms / 1000.0 / self.speed_factor)

"""The stack's one simulated clock, paced by a speed factor.

The supervisor is its master (lockstep): simulated time (s) advances only by
mission events and never runs ahead of ``speed_factor`` × wall time. Step t,
starting at τ_t, is *planning*, n = ⌈T_s / T_f⌉ fire sub-steps with the
vehicle paused (Sec. IV), then *flight*, ΔT, towards a setpoint due at
τ_t + n·T_f + ΔT (MAVLink ``time_boot_ms``). ``speed_factor`` 1 is real time,
20 flies a 1 s step in 50 ms of wall time, 0 (or inf) is unpaced.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass


def check_speed_factor(factor: float) -> float:
    """A speed factor is > 0, or 0 / inf for unpaced; returns 0.0 for unpaced."""
    if math.isnan(factor) or factor < 0:
        raise ValueError(f"speed factor must be >= 0 (0 or inf: unpaced), got {factor}")
    return 0.0 if math.isinf(factor) else float(factor)


@dataclass(frozen=True)
class Anchor:
    """Simulated time ``sim_time_s`` happened at wall time ``wall_ns`` (time.time_ns)."""

    sim_time_s: float
    wall_ns: int
    speed_factor: float  # 0: unpaced

    def wall_at(self, sim_s: float) -> float:
        """Wall time (unix s) at which simulated time ``sim_s`` is due."""
        if self.speed_factor == 0:
            return self.wall_ns / 1e9
        return self.wall_ns / 1e9 + (sim_s - self.sim_time_s) / self.speed_factor

    def sleep_until(self, sim_s: float, stop: threading.Event | None = None) -> float:
        """Sleep until ``sim_s`` is due (or ``stop`` is set); returns the seconds slept."""
        if self.speed_factor == 0:
            return 0.0
        t0 = time.time()
        delay = self.wall_at(sim_s) - t0
        if delay <= 0:
            return 0.0
        if stop is None:
            time.sleep(delay)
        else:
            stop.wait(delay)
        return time.time() - t0


class SimClock:
    """The master clock: current simulated time and its anchor to the wall clock."""

    def __init__(self, speed_factor: float):
        self.speed_factor = check_speed_factor(speed_factor)
        self.now_s = 0.0
        self.anchor = Anchor(0.0, time.time_ns(), self.speed_factor)

    def start_step(self) -> Anchor:
        """Re-anchor at the current simulated time if the wall clock ran ahead (lockstep)."""
        now_wall = time.time()
        if self.speed_factor == 0 or now_wall > self.anchor.wall_at(self.now_s):
            self.anchor = Anchor(self.now_s, time.time_ns(), self.speed_factor)
        return self.anchor

    def advance(self, dt_s: float) -> float:
        if not (math.isfinite(dt_s) and dt_s >= 0):
            raise ValueError(f"clock can only advance by a finite dt >= 0, got {dt_s}")
        self.now_s += dt_s
        return self.now_s

    def sleep_until_now(self, stop: threading.Event | None = None) -> float:
        """Wait until the current simulated time is due on the wall clock."""
        return self.anchor.sleep_until(self.now_s, stop)

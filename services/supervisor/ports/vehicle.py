"""The vehicle port over MAVLink: a setpoint due at a simulated time, then the state."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dualpilot.model.dynamics import Array

from ..link import VehicleLink
from .stackbus import Aborted, StackBus


class StackVehicle:
    """The vehicle port over MAVLink: a setpoint due at a simulated time, then the state.

    ``ensure_offboard`` is called while the vehicle is not flying offboard: the
    session pauses the mission there (nothing advances: the clock is lockstep).
    """

    def __init__(self, b: StackBus, link: VehicleLink, dt_s: float,
                 ensure_offboard: Callable[[], None]):
        self.b = b
        self.link = link
        self.dt_s = dt_s
        self.ensure_offboard = ensure_offboard
        self.base_ms = 0  # the vehicle's boot time (ms) at the mission's τ = 0
        self.due_ms = 0
        self.sent = 0.0  # perf_counter when the last setpoint left

    def command(self, target: Array, control: Array, after_s: float) -> None:
        self.due_ms = self.base_ms + round((self.b.clock.now_s + after_s) * 1000)
        self.sent = self.link.setpoints.send(np.asarray(target, dtype=float), self.due_ms)

    def start_position(self, measured: Array) -> tuple[float, float]:
        """Where the mission starts: the vehicle's ``measured`` position (Eq. (1)'s vehicle
        measures exactly; a plant's port says its truth)."""
        return float(measured[0]), float(measured[1])

    def observe(self) -> Array:
        """The state at or after the setpoint's due time; the flight lasts ΔT of sim time."""
        state = self.read_state(self.due_ms)
        self.b.clock.advance(self.dt_s)
        return state

    def read_state(self, min_ms: int) -> Array:
        """The vehicle's state at or after ``min_ms``; pauses while the vehicle is not flying
        offboard (lost, or holding), aborts after ``vehicle_timeout_s`` without it otherwise."""
        wall = self.b.wall
        deadline = wall.now() + self.b.stack.vehicle_timeout_s
        while True:
            got = self.link.position.wait_state(min_ms, 0.25, self.b.stop)
            if got is not None:
                return got[1]
            if self.b.stop.is_set():
                raise Aborted("stopped")
            if not self.link.status.offboard():
                self.ensure_offboard()
                deadline = wall.now() + self.b.stack.vehicle_timeout_s
            elif wall.now() > deadline:
                raise Aborted(f"no vehicle state at or after {min_ms} ms")

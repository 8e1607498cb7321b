"""Taking the vehicle under offboard control, in MAVSDK/PX4 order.

Wait for a heartbeat and a valid position, stream setpoints that hold the
current state, switch to offboard (PX4 OFFBOARD, ArduPilot GUIDED), arm; a
refused command is logged and retried (``attempts``), then the take-over
fails with :class:`OffboardError`. Steps already satisfied are skipped, so it
also re-takes a vehicle that came back.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Protocol

from services.common import mav, mavmodes
from services.common.log import fields

from .commands import result_name

log = logging.getLogger("services.supervisor.link")
m = mav.mavlink


class OffboardError(RuntimeError):
    """The vehicle could not be put under offboard control."""


class Heard(Protocol):
    """What the take-over reads of the vehicle's heartbeat (heartbeat.py: VehicleStatus)."""

    modes: mavmodes.ModeMap | None
    mode: int
    armed: bool

    def wait_vehicle(self, timeout_s: float, stop: threading.Event) -> bool: ...

    def offboard(self) -> bool: ...

    def status(self) -> str: ...


class Located(Protocol):
    """position.py: Position."""

    def valid(self) -> bool: ...


class Holding(Protocol):
    """setpoints.py: Setpoints."""

    def hold(self) -> None: ...


class Commanding(Protocol):
    """commands.py: Commands."""

    attempts: int

    def command(self, cmd: int, *params: float, stop: threading.Event | None = None) -> int: ...


class TakeOver:
    """Puts the vehicle under offboard control (module docstring)."""

    def __init__(self, heard: Heard, located: Located, setpoints: Holding, commands: Commanding,
                 period_s: float):
        """``period_s``: the setpoint stream's period (the stream runs 5 of them before the
        mode switch)."""
        self.heard = heard
        self.located = located
        self.setpoints = setpoints
        self.commands = commands
        self.period_s = period_s

    def start_offboard(self, stop: threading.Event, timeout_s: float = 30.0,
                       retry_wait_s: float = 0.5) -> None:
        """Heartbeat, a valid position, setpoints, offboard mode, arm (MAVSDK/PX4 order).

        Raises OffboardError when the vehicle refuses (after ``attempts`` tries with
        ``retry_wait_s`` between them) or ``timeout_s`` passes; returns early when ``stop``
        is set.
        """
        deadline = time.monotonic() + timeout_s
        heard = self.heard
        if not heard.wait_vehicle(timeout_s, stop):
            raise OffboardError("no heartbeat from the vehicle")
        while not self.located.valid():
            if stop.wait(0.05) or time.monotonic() > deadline:
                raise OffboardError("no valid position from the vehicle")
        self.setpoints.hold()
        stop.wait(5 * self.period_s)  # PX4 accepts offboard only with the stream already live
        modes = heard.modes
        assert modes is not None  # set with the first heartbeat
        log.info("taking the vehicle", extra=fields(autopilot=modes.family,
                                                    offboard=modes.name(modes.offboard)))
        self._command("offboard mode", lambda: heard.mode == modes.offboard,
                      m.MAV_CMD_DO_SET_MODE,
                      (float(m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), *modes.offboard_request),
                      stop, retry_wait_s)
        self._command("arm", lambda: heard.armed, m.MAV_CMD_COMPONENT_ARM_DISARM, (1.0,),
                      stop, retry_wait_s)
        while not (heard.offboard() or stop.is_set()):  # the heartbeat confirms it
            if time.monotonic() > deadline:
                raise OffboardError(f"vehicle not under offboard control ({heard.status()})")
            stop.wait(0.05)

    def _command(self, what: str, done: Callable[[], bool], cmd: int, params: tuple[float, ...],
                 stop: threading.Event, retry_wait_s: float) -> None:
        """One step: ``cmd`` until accepted (or ``done()`` already); OffboardError when refused
        ``attempts`` times or UNSUPPORTED."""
        attempts = self.commands.attempts
        for attempt in range(1, attempts + 1):
            if done() or stop.is_set():
                return
            result = self.commands.command(cmd, *params, stop=stop)
            if result == m.MAV_RESULT_ACCEPTED:
                log.info("vehicle accepted", extra=fields(command=what))
                return
            log.warning("vehicle refused a command", extra=fields(
                command=what, result=result_name(result), attempt=attempt, of=attempts))
            if result == m.MAV_RESULT_UNSUPPORTED:
                raise OffboardError(f"{what}: UNSUPPORTED")
            stop.wait(retry_wait_s)
        raise OffboardError(f"{what} refused {attempts} times")

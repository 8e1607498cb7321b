"""Commands to the vehicle: COMMAND_LONG, re-sent until its COMMAND_ACK comes."""

from __future__ import annotations

import threading
import time
from typing import Any

from services.common import mav

from .connection import Send

m = mav.mavlink


def result_name(result: int) -> str:
    """A MAV_RESULT's name (NO_ANSWER for -1: no COMMAND_ACK came)."""
    if result < 0:
        return "NO_ANSWER"
    entry = m.enums["MAV_RESULT"].get(result)
    return entry.name if entry is not None else str(result)


class Commands:
    """COMMAND_LONG to the vehicle's autopilot and the COMMAND_ACKs it sends back."""

    MESSAGES = ("COMMAND_ACK",)

    def __init__(self, send: Send, target: tuple[int, int], attempts: int = 3,
                 timeout_s: float = 1.0):
        self.send = send
        self.target = target
        self.attempts = attempts
        self.timeout_s = timeout_s
        self.cond = threading.Condition()
        self.acks: dict[int, int] = {}  # command → the result of its last COMMAND_ACK

    def on_message(self, msg: Any) -> None:
        with self.cond:
            self.acks[int(msg.command)] = int(msg.result)
            self.cond.notify_all()

    def command(self, cmd: int, *params: float, stop: threading.Event | None = None) -> int:
        """COMMAND_LONG, re-sent (``confirmation`` + 1) until a COMMAND_ACK arrives; the result,
        or -1 if none came after ``attempts`` tries of ``timeout_s`` each."""
        p = [float(v) for v in params] + [0.0] * (7 - len(params))
        for confirmation in range(self.attempts):
            with self.cond:
                self.acks.pop(cmd, None)
            self.send("command_long", *self.target, cmd, confirmation, *p)
            deadline = time.monotonic() + self.timeout_s
            with self.cond:
                while True:
                    result = self.acks.get(cmd)
                    if result is not None and result != m.MAV_RESULT_IN_PROGRESS:
                        return int(result)
                    remaining = deadline - time.monotonic()
                    if remaining <= 0 or (stop is not None and stop.is_set()):
                        break
                    self.cond.wait(min(remaining, 0.1))
            if stop is not None and stop.is_set():
                break
        return -1

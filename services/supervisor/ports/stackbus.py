"""What every port of one mission shares: the stack's transport, the vehicle id, the clocks.

:class:`StackBus` is handed to each adapter of the step's ports (fires,
planners, vehicle) and to the session's publishers. It reaches the services
through a :class:`StackTransport` (the stack's: :class:`ZenohStackTransport`,
queries and publishers on one Zenoh session) and keeps wall time on a
:class:`WallClock` (the stack's: :class:`MonotonicClock`): the two seams an
in-process test replaces (tests/unit/services/supervisor/test_session.py), so the
session and its ports run without a process, a socket or a sleep.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import zenoh
from google.protobuf.message import Message

from services.common import bus, wire
from services.common.clock import SimClock

from ..pool import Transport, ZenohTransport
from .params import StackParams

#: publishes one protobuf message on the key it was made for
Publish = Callable[[Message], None]


class Aborted(RuntimeError):
    """The stack could not finish the mission (a service or the vehicle stopped answering)."""


class StackTransport(Protocol):
    """How a mission's ports reach the services."""

    def query(self, key: str, msg: Message, timeout_s: float, stop: threading.Event,
              trusted: bus.Trusted) -> tuple[bytes, str]:
        """The first trusted reply's (payload, encoding) to ``msg`` on ``key``; raises
        TimeoutError (no reply), :class:`services.common.bus.QueryError` (an error reply)."""
        ...

    def publisher(self, key: str) -> Publish:
        """A publisher on ``key``, declared once."""
        ...

    def put(self, key: str, msg: Message) -> None:
        """Publish one message on ``key`` (a publisher declared for it alone)."""
        ...

    def planners(self, uav: str, stop: threading.Event,
                 live: bus.Liveliness | None) -> Transport:
        """The planner pool's transport (services/supervisor/pool.py)."""
        ...


class ZenohStackTransport:
    """The stack's transport: queries and publishers on the supervisor's Zenoh session."""

    def __init__(self, session: zenoh.Session):
        self.session = session

    def query(self, key: str, msg: Message, timeout_s: float, stop: threading.Event,
              trusted: bus.Trusted) -> tuple[bytes, str]:
        return bus.request(self.session, key, msg, timeout_s, stop, trusted=trusted)

    def publisher(self, key: str) -> Publish:
        pub = self.session.declare_publisher(key)
        return lambda msg: bus.put(pub, "", msg)

    def put(self, key: str, msg: Message) -> None:
        pub = self.session.declare_publisher(key)
        bus.put(pub, "", msg)
        pub.undeclare()

    def planners(self, uav: str, stop: threading.Event,
                 live: bus.Liveliness | None) -> Transport:
        return ZenohTransport(self.session, uav, stop, live)


class WallClock(Protocol):
    """Wall time (monotonic s) and the waits on it."""

    def now(self) -> float: ...

    def wait(self, seconds: float, stop: threading.Event) -> bool:
        """Wait ``seconds`` or until ``stop`` is set; whether it is set."""
        ...


class MonotonicClock:
    """The process's monotonic clock; a wait is the stop event's."""

    def now(self) -> float:
        return time.monotonic()

    def wait(self, seconds: float, stop: threading.Event) -> bool:
        return stop.wait(seconds)


@dataclass
class StackBus:
    """What every adapter shares: the transport, the vehicle id, the clocks, the stop event."""

    transport: StackTransport
    uav: str
    mission_id: str
    stamper: wire.Stamper
    clock: SimClock  # the mission's simulated time (lockstep)
    stop: threading.Event
    stack: StackParams
    live: bus.Liveliness | None = None
    dt_s: float = 1.0  # the control period ΔT (s)
    wall: WallClock = field(default_factory=MonotonicClock)  # pauses, losses, timeouts

    def deadline_s(self, system: int) -> float:
        """The plan deadline of ``system`` (wall s): the explicit one, or periods × ΔT; plus
        the link's round trip when the system is behind the air–ground link."""
        st = self.stack
        allowance = st.link.allowance_s(f"system{system}")  # behind the air–ground link
        if st.plan_deadline_s is not None:
            return st.plan_deadline_s[system - 1] + allowance
        return st.plan_deadline_periods[system - 1] * self.dt_s + allowance

    def alive(self, service: str) -> bool:
        """The service's liveliness token is up (always True without a tracker)."""
        return self.live is None or not self.live.missing({service})

    def query(self, key: str, msg: Message, timeout_s: float,
              trusted: bus.Trusted = None) -> tuple[bytes, str]:
        """The first trusted reply's (payload, encoding) to ``msg`` on ``key`` (TimeoutError,
        QueryError)."""
        return self.transport.query(key, msg, timeout_s, self.stop, trusted)

    def trusted(self, service: str) -> str | None:
        """Whose replies count for ``service``: the token holder's Zenoh id ("" nobody yet);
        None (anyone) without a tracker."""
        return None if self.live is None else self.live.holder(service)

    def wait(self, seconds: float) -> bool:
        """Wait ``seconds`` of wall time or until stopped (whether stopped)."""
        return self.wall.wait(seconds, self.stop)

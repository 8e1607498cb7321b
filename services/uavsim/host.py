"""A vehicle host's loop: every simulated vehicle of the process served by one thread.

Each vehicle's :class:`~services.uavsim.endpoint.Endpoint` runs the same
passes it runs alone (what is due, a wait on its links until its next
deadline or a datagram, then the reads, the failsafes and the tick), but one
loop waits on the links of all of them at once (``selectors``: epoll on
Linux) and runs the pass of each vehicle whose links are ready or whose
deadline has come. A host of 50 vehicles then has no thread per vehicle:
no handing of the GIL from thread to thread and one wake-up for the
vehicles whose telemetry is due at the same time (they booted together,
services/uavsim/intervals.py). Log lines name the vehicle whose pass is
running.
"""

from __future__ import annotations

import selectors
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from services.common.log import tag_vehicle

from .endpoint import Endpoint


@dataclass(eq=False)
class Hosted:
    """One vehicle of the host: its endpoint, the tick after each pass, its next deadline."""

    uav: str
    endpoint: Endpoint
    on_tick: Callable[[float], None] | None = None
    deadline: float = 0.0  #: monotonic s by which its next pass is due
    fds: dict[int, str] = field(default_factory=dict)  #: its links' registered descriptors


class Host:
    """The vehicles of one process and the loop that serves them all (module docstring)."""

    def __init__(self) -> None:
        self.vehicles: list[Hosted] = []
        self.selector = selectors.DefaultSelector()

    def add(self, uav: str, endpoint: Endpoint,
            on_tick: Callable[[float], None] | None = None) -> None:
        self.vehicles.append(Hosted(uav, endpoint, on_tick))

    def _register(self, v: Hosted) -> None:
        """Wait on ``v``'s links as they are now (a TCP link's descriptor changes)."""
        fds = v.endpoint.fds()
        if fds == v.fds:
            return
        for fd in v.fds:
            self.selector.unregister(fd)
        for fd, link in fds.items():
            self.selector.register(fd, selectors.EVENT_READ, (v, link))
        v.fds = fds

    def run(self, stop: threading.Event) -> None:
        """Serve every vehicle until ``stop`` (checked at least every MAX_WAIT_S)."""
        for v in self.vehicles:
            tag_vehicle(v.uav)
            v.deadline = v.endpoint.begin(time.monotonic())
            self._register(v)
        try:
            while not stop.is_set():
                self._turn()
        finally:
            self.selector.close()

    def _turn(self) -> None:
        """One wait on every link, then the pass of each vehicle that is ready or due."""
        wait = min(v.deadline for v in self.vehicles) - time.monotonic()
        ready: dict[Hosted, list[str]] = {}
        for key, _events in self.selector.select(max(0.0, wait)):
            v, link = key.data
            ready.setdefault(v, []).append(link)
        now = time.monotonic()
        for v in self.vehicles:
            links = ready.get(v)
            if links is None and v.deadline > now:
                continue
            tag_vehicle(v.uav)
            v.endpoint.settle(links or (), v.on_tick)
            v.deadline = v.endpoint.due_work(time.monotonic())
            self._register(v)

"""One thread that reads and polls every vehicle link of the supervisor process.

A link whose stream the stream process sends (a UDP link,
services/supervisor/link/) needs a reader, which handles what the vehicle
sends, and a poller, which asks for the mission id and the origin at 1 Hz and
keeps the stream's destination and heartbeat period. A fleet's supervisor
host flies 50 vehicles: rather than two threads a vehicle, all woken by every
telemetry frame and handing the GIL to each other, :func:`link_loop` gives the
process's one :class:`LinkLoop`, which waits on every link at once
(``selectors``: epoll on Linux), reads those that are ready and polls them all
every :data:`POLL_PERIOD_S`. A link's error is logged and the others go on.
"""

from __future__ import annotations

import logging
import selectors
import threading
import time
from typing import Any, Protocol

from services.common.log import tag_vehicle

log = logging.getLogger(__name__)

#: the reader waits at most this long between two looks at the links (s)
READER_PERIOD_S = 0.1
#: the poller's period with a stream process (s): the stream's destination and heartbeat rate
POLL_PERIOD_S = 0.25


class Polled(Protocol):
    """What the loop needs of a link (services/supervisor/link/vehicle.py: VehicleLink)."""

    conn: Any
    tag: str | None

    def listening(self, now: float) -> None: ...

    def read(self) -> None: ...

    def poll(self, now: float) -> None: ...


class LinkLoop:
    """The links of the process and the thread that serves them (module docstring)."""

    def __init__(self) -> None:
        self.selector = selectors.DefaultSelector()
        self.lock = threading.Lock()
        self.links: tuple[Polled, ...] = ()  # replaced, never changed in place
        self.next_poll = 0.0
        self.thread = threading.Thread(target=self._run, name="mav-links", daemon=True)
        self.thread.start()

    def add(self, link: Polled) -> None:
        with self.lock:
            self.selector.register(link.conn.fd, selectors.EVENT_READ, link)
            self.links = (*self.links, link)

    def remove(self, link: Polled) -> None:
        """Stop serving ``link`` (before its socket is closed)."""
        with self.lock:
            self.links = tuple(lk for lk in self.links if lk is not link)
            for key in list(self.selector.get_map().values()):
                if key.data is link:
                    self.selector.unregister(key.fd)

    def _run(self) -> None:
        while True:
            self._turn()

    def _turn(self) -> None:
        links = self.links
        now = time.monotonic()
        for link in links:
            link.listening(now)
        wait = min(READER_PERIOD_S, max(0.0, self.next_poll - now)) if links else READER_PERIOD_S
        with self.lock:
            keys = dict(self.selector.get_map())
        if not keys:
            time.sleep(wait)
            return
        for key, _events in self.selector.select(wait):
            self._serve(key.data, key.data.read)
        now = time.monotonic()
        if now >= self.next_poll:
            self.next_poll = now + POLL_PERIOD_S
            for link in self.links:
                self._serve(link, lambda lk=link: lk.poll(now))

    @staticmethod
    def _serve(link: Polled, work: Any) -> None:
        tag_vehicle(link.tag)
        try:
            work()
        except Exception:  # one link's fault never stops the others' reading
            log.exception("vehicle link failed")
        finally:
            tag_vehicle(None)


_LOOP: LinkLoop | None = None
_LOOP_LOCK = threading.Lock()


def link_loop() -> LinkLoop:
    """The process's link loop (started on first use)."""
    global _LOOP
    with _LOOP_LOCK:
        if _LOOP is None:
            _LOOP = LinkLoop()
        return _LOOP

"""One vehicle's link: its components put together, read and polled.

:class:`VehicleLink` opens the connection, makes each component
(services/supervisor/link/__init__.py) and gives it the message types it
handles. For a UDP link the process's one link loop reads and polls it
(services/supervisor/linkloop.py) and the stream process sends its stream;
a link that is not UDP (tcp, serial) has a reader and a poller thread of its
own, the poller also sending the heartbeat and the setpoint stream. A
watcher thread downloads the operator's mission. The poll asks for ``MIS_ID``
and the origin at 1 Hz, once the vehicle is heard.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from services.common.log import vehicle_thread

from ..linkloop import link_loop
from .commands import Commands
from .connection import Channel, Connection
from .heartbeat import VehicleStatus
from .mission import MissionDownload
from .params import LinkParams
from .position import Position
from .setpoints import Setpoints
from .takeover import TakeOver

log = logging.getLogger("services.supervisor.link")


class VehicleLink:
    """Offboard link to one vehicle (system ``params.target_system``, component 1)."""

    def __init__(self, params: LinkParams, connection: Channel | None = None,
                 clock: Callable[[], float] = time.monotonic):
        """``connection``: the MAVLink connection (default: opened from ``params.url``);
        ``clock``: monotonic s, when the vehicle was last heard (a unit test's fake)."""
        self.params = params
        c = self.connection = Connection(params) if connection is None else connection
        self.conn, self.tag = c.conn, c.tag  # what the link loop serves, and names
        self.status = VehicleStatus(params.target_system, params.lost_after_s,
                                    lambda: c.listened, clock)
        self.position = Position(c.send, c.target)
        self.setpoints = Setpoints(c, params, self.status.alive, self.position.latest)
        self.commands = Commands(c.send, c.target, params.command_attempts,
                                 params.command_timeout_s)
        self.takeover = TakeOver(self.status, self.position, self.setpoints, self.commands,
                                 params.period_s)
        self.mission = MissionDownload(c.send, c.target, lambda: self.position.origin)
        for part in (self.status, self.position, self.commands, self.mission):
            c.on(part.MESSAGES, part.on_message)
        self._stop = threading.Event()
        self._next_poll = 0.0
        self._threads = [threading.Thread(target=vehicle_thread(self.mission.watch),
                                          name="mav-mission", daemon=True)]
        if self.setpoints.stream is None:  # else the process's link loop reads and polls it
            self._threads += [
                threading.Thread(target=vehicle_thread(lambda: c.serve(self._stop)),
                                 name="mav-reader", daemon=True),
                threading.Thread(target=vehicle_thread(self._serve), name="mav-poller",
                                 daemon=True)]

    # -- what the link loop needs (linkloop.Polled) ----------------------------------------------
    def listening(self, now: float) -> None:
        self.connection.listening(now)

    def read(self) -> None:
        self.connection.read()

    def poll(self, now: float) -> None:
        """The stream's destination and heartbeat period; the parameter and origin polls at
        1 Hz (from the link loop, or from the poller thread)."""
        self.setpoints.update_stream()
        if now >= self._next_poll and self.status.seen.is_set():
            self.mission.poll()
            self.position.poll()
            self._next_poll = now + 1.0

    # -- life -----------------------------------------------------------------------------------
    def start(self) -> None:
        self.setpoints.update_stream()  # speak first so a udpin vehicle learns our address
        if self.setpoints.stream is None:
            self.connection.heartbeat()
        for th in self._threads:
            th.start()
        if self.setpoints.stream is not None:
            link_loop().add(self)

    def close(self) -> dict[str, object]:
        """Stop the stream and the threads, close the link; the stream's statistics."""
        if self.setpoints.stream is not None:
            link_loop().remove(self)
        stats = self.setpoints.close()
        self._stop.set()
        self.mission.close()
        for th in self._threads:
            if th.is_alive():
                th.join(1.0)
        self.connection.close()
        return stats

    def _serve(self) -> None:
        """A link that is not UDP: the polls, the heartbeat and the setpoint stream."""
        next_hb = 0.0
        while not self._stop.is_set():
            now = time.monotonic()
            self.poll(now)
            if now >= next_hb:
                self.connection.heartbeat()
                next_hb = now + (1.0 if self.status.alive() else 0.2)
            self.setpoints.repeat()
            self._stop.wait(self.params.period_s)

"""The MAVLink connection to one vehicle: opened, read, filtered, dispatched by message type.

Frames from anyone but the vehicle's autopilot (system ``target_system``,
component 1) and frames that do not decode are dropped; every other frame
goes to the handler its type was given to (:meth:`Connection.on`), as
MAVProxy hands each packet to its modules. The companion's own frames use
signing link id 0 (the stream process signs on link id 1).
"""

from __future__ import annotations

import logging
import select
import socket
import threading
import time
from collections.abc import Callable, Iterable
from typing import Any, Protocol

from services.common import mav
from services.common.log import vehicle_tag

from ..linkloop import READER_PERIOD_S
from .params import LinkParams

log = logging.getLogger("services.supervisor.link")
m = mav.mavlink

#: sends message ``name`` with its fields (services/common/mav.py: Sender)
Send = Callable[..., Any]
#: handles one frame from the vehicle
Handler = Callable[[Any], None]


def destinations(conn: Any) -> list[tuple[str, int]]:
    """Where a UDP link sends: its fixed destination (udpout), else the peers heard (udpin)."""
    if not getattr(conn, "udp_server", True):
        host, port = conn.destination_addr
        try:
            return [(socket.gethostbyname(host), int(port))]
        except OSError:  # not resolvable yet (a container still starting): asked again
            return []
    return sorted((str(a), int(p)) for a, p in getattr(conn, "clients", ()))


class Channel(Protocol):
    """What the link's components need of its connection (:class:`Connection`; a unit test's
    simulated vehicle)."""

    conn: Any  # the pymavlink connection (its ``fd`` for the link loop, its UDP socket)
    target: tuple[int, int]  # (system, component) of the vehicle's autopilot
    udp: bool
    tag: str | None

    @property
    def listened(self) -> float:
        """When the reader last waited for the vehicle (monotonic s)."""
        ...

    def send(self, name: str, *args: Any) -> Any: ...

    def on(self, kinds: Iterable[str], handler: Handler) -> None: ...

    def listening(self, now: float) -> None: ...

    def read(self) -> None: ...

    def serve(self, stop: threading.Event) -> None: ...

    def heartbeat(self) -> None: ...

    def destinations(self) -> list[tuple[str, int]]: ...

    def close(self) -> None: ...


class Connection:
    """The link's pymavlink connection and the handlers of what the vehicle sends."""

    def __init__(self, params: LinkParams):
        self.conn = mav.connect(params.url, params.target_system,
                                mav.MAV_COMP_ID_ONBOARD_COMPUTER, params.passphrase,
                                key=params.key, link_id=0)
        self.send: Send = mav.Sender(self.conn)
        self.target_system = params.target_system
        self.target = (params.target_system, mav.MAV_COMP_ID_AUTOPILOT1)
        #: a UDP link: its stream is the stream process's, its reading the link loop's
        self.udp = isinstance(getattr(self.conn, "port", None), socket.socket)
        self.tag: str | None = vehicle_tag()  # the vehicle this link's log lines name
        self.listened = time.monotonic()  # when the reader last waited for the vehicle
        self.handlers: dict[str, Handler] = {}

    def on(self, kinds: Iterable[str], handler: Handler) -> None:
        """Frames of these types go to ``handler``."""
        for kind in kinds:
            self.handlers[kind] = handler

    def listening(self, now: float) -> None:
        """The reader waits for the vehicle from ``now`` (monotonic s) on."""
        self.listened = now

    def read(self) -> None:
        """Handle every frame waiting on the link."""
        while (msg := self.conn.recv_msg()) is not None:
            self.dispatch(msg)

    def dispatch(self, msg: Any) -> None:
        """One frame to its handler, if it is the vehicle's autopilot's."""
        kind = msg.get_type()
        if kind == "BAD_DATA" or msg.get_srcSystem() != self.target_system:
            return
        if msg.get_srcComponent() != mav.MAV_COMP_ID_AUTOPILOT1:
            return
        handler = self.handlers.get(kind)
        if handler is not None:
            handler(msg)

    def serve(self, stop: threading.Event) -> None:
        """A link that is not UDP: read it on this thread until ``stop``."""
        fd = self.conn.fd
        while not stop.is_set():
            self.listening(time.monotonic())
            ready, _, _ = select.select([fd], [], [], READER_PERIOD_S)
            if ready:
                self.read()

    def heartbeat(self) -> None:
        """The companion's HEARTBEAT (an onboard controller)."""
        self.send("heartbeat", m.MAV_TYPE_ONBOARD_CONTROLLER, m.MAV_AUTOPILOT_INVALID, 0, 0,
                  m.MAV_STATE_ACTIVE)

    def destinations(self) -> list[tuple[str, int]]:
        return destinations(self.conn)

    def close(self) -> None:
        self.conn.close()

"""Where the vehicle's messages go: one link, or every link (:class:`Outbox`).

The components (parameters, commands, mission, telemetry) talk through this
one small interface, so a unit test hands them a :class:`RecordingOutbox`
and reads what a ground station would have received, without a socket.
"""

from __future__ import annotations

from typing import Any, Protocol

from services.common import mav

m = mav.mavlink
#: STATUSTEXT carries 50 characters
STATUSTEXT_CHARS = 50


class Outbox(Protocol):
    def send(self, link: str | None, name: str, *args: Any) -> None:
        """Send message ``name`` (``heartbeat``, ``command_ack``, …) with ``args`` on ``link``,
        or on every link when ``link`` is None."""


class LinkOutbox:
    """The real outbox: pymavlink senders by link name; a flight log gets each frame once."""

    def __init__(self, senders: dict[str, mav.Sender]):
        self.senders = senders

    def send(self, link: str | None, name: str, *args: Any) -> None:
        if link is not None:
            self.senders[link](name, *args)
            return
        for k, sender in enumerate(self.senders.values()):
            sender.message(getattr(sender.mav, f"{name}_encode")(*args), log=k == 0)


class RecordingOutbox:
    """An outbox that keeps what was sent: (link, name, args)."""

    def __init__(self) -> None:
        self.sent: list[tuple[str | None, str, tuple[Any, ...]]] = []

    def send(self, link: str | None, name: str, *args: Any) -> None:
        self.sent.append((link, name, args))

    def named(self, name: str) -> list[tuple[Any, ...]]:
        return [args for _link, n, args in self.sent if n == name]

    def texts(self) -> list[str]:
        """The STATUSTEXTs sent, decoded."""
        return [args[1].decode() for args in self.named("statustext")]

    def clear(self) -> None:
        self.sent.clear()


def statustext(outbox: Outbox, text: str, severity: int = m.MAV_SEVERITY_INFO) -> None:
    """A STATUSTEXT on every link (cut to the 50 characters it carries)."""
    outbox.send(None, "statustext", severity, text.encode()[:STATUSTEXT_CHARS])

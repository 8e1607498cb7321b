"""The simulated vehicle's links as they are read: datagrams, framing, the peers telemetry goes to.

A UDP datagram is parsed on its own (a truncated frame never swallows the
next datagram's bytes) and judged by when it arrived (services/uavsim/arrivals.py);
at most one framing problem is counted per datagram (too large, truncated,
BAD_DATA, a message id not in the dialect, MAVLink 1 but for a HEARTBEAT). Only
a peer that sent a usable frame becomes a client that telemetry goes to
(bounded: the least recently heard goes first). A stream link (TCP, ArduPilot
SITL's habit) is read by pymavlink. Each decoded frame goes to the endpoint's
``handle`` (services/uavsim/endpoint.py), with where and when it came from.
"""

from __future__ import annotations

import logging
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from services.common import mav, mavlink_codec, rejections
from services.common.log import fields

from . import arrivals

log = logging.getLogger("services.uavsim")

#: UDP peers a ``udpin`` link sends to (those that sent a usable frame), the least recently
#: heard dropped first; a peer silent for CLIENT_TIMEOUT_S is dropped (one is always kept).
MAX_CLIENTS = 8
#: datagrams read from one link before the loop sends telemetry again (a flood cannot starve it)
MAX_DATAGRAMS_PER_POLL = 200
CLIENT_TIMEOUT_S = 10.0


@dataclass(frozen=True)
class Arrival:
    """Where a frame came from: its datagram's address (None: a stream link) and when it
    arrived (monotonic s; None: the kernel did not say)."""

    addr: Any = None
    rx_time: float | None = None


#: handle(link, msg, arrival): act on one decoded frame; False if it was rejected
Handle = Callable[[str, Any, Arrival], bool]
#: reject(link, error): count and log a rejected input of ``link``
Reject = Callable[[str, rejections.CodecError], None]


def add_client(conn: Any, addr: tuple[str, int]) -> None:
    """Send telemetry to ``addr`` from now on (bounded: the least recently heard goes)."""
    now = time.time()
    conn.timeout = CLIENT_TIMEOUT_S
    conn.clients.add(addr)
    conn.clients_last_alive[addr] = now
    while len(conn.clients) > MAX_CLIENTS:
        oldest = min(conn.clients, key=lambda a: conn.clients_last_alive.get(a, 0.0))
        conn.clients.discard(oldest)
        conn.clients_last_alive.pop(oldest, None)


class LinkReader:
    """Reads the vehicle's links and hands each usable frame on (module docstring)."""

    def __init__(self, links: dict[str, Any], handle: Handle, reject: Reject,
                 unsigned: Callable[[int], None]):
        """``unsigned(total)``: the frames the keyed links refused so far, each time it grows."""
        self.links = links
        self.handle = handle
        self.reject = reject
        self.unsigned = unsigned
        self.rejected_seen = 0
        for conn in links.values():
            if isinstance(getattr(conn, "port", None), socket.socket):
                arrivals.enable(conn.port)

    def bad_frame(self, link: str, msg: Any) -> rejections.CodecError:
        """The rejection for a BAD_DATA frame (an unsigned one is also counted as such)."""
        why = str(getattr(msg, "reason", ""))
        reason = mavlink_codec.mavlink_frame_reason(why)
        if reason is rejections.Reason.UNSIGNED:
            self.count_unsigned()
        return rejections.invalid(f"bad frame on {link}: {why}", reason)

    def count_unsigned(self) -> None:
        """An unsigned or wrongly signed frame on a signed link (the caller counts the
        rejection itself, reason ``unsigned``)."""
        total = sum(mav.rejected_frames(conn) for conn in self.links.values())
        if total != self.rejected_seen:
            self.rejected_seen = total
            self.unsigned(total)

    def receive(self, link: str) -> None:
        """Read every waiting datagram of ``link`` and handle its frames (never raises)."""
        conn = self.links[link]
        port = getattr(conn, "port", None)
        if not isinstance(port, socket.socket) or port.type != socket.SOCK_DGRAM:
            while (msg := conn.recv_msg()) is not None:  # a stream (TCP): pymavlink reads
                if msg.get_type() == "BAD_DATA":
                    self.reject(link, self.bad_frame(link, msg))
                else:
                    self.handle(link, msg, Arrival())
            return
        for _ in range(MAX_DATAGRAMS_PER_POLL):  # then telemetry and the failsafe get a turn
            try:
                data, addr, rx_time = arrivals.recv(port)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as err:  # e.g. ICMP port unreachable reported on the socket
                log.debug("recv failed", extra=fields(link=link, error=str(err)))
                return
            try:
                if self.datagram(link, conn, data, Arrival(addr, rx_time)) and getattr(
                        conn, "udp_server", False):
                    add_client(conn, addr)  # udpin: the peers telemetry goes to
            except Exception:  # a bug must not take the vehicle down: count it, go on
                log.exception("frame handling failed")
                self.reject(link, rejections.invalid("frame handling failed (internal error)"))

    def datagram(self, link: str, conn: Any, data: bytes, arrival: Arrival) -> bool:
        """Parse and handle one datagram; True if it held at least one usable frame."""
        if len(data) > mavlink_codec.MAX_MAVLINK_DATAGRAM:
            self.reject(link, rejections.invalid(
                f"datagram of {len(data)} bytes (at most {mavlink_codec.MAX_MAVLINK_DATAGRAM})",
                rejections.Reason.TOO_LARGE))
            return False
        parser = conn.mav
        parser.buf, parser.buf_index = bytearray(), 0
        parser.expected_length = mav.mavlink.HEADER_LEN_V1 + 2
        framing: rejections.CodecError | None = None
        usable = False
        msgs = parser.parse_buffer(data) or []
        if parser.buf_len() > 0:
            framing = rejections.invalid(f"truncated frame: {parser.buf_len()} bytes left over",
                                         rejections.Reason.MALFORMED)
            parser.buf, parser.buf_index = bytearray(), 0
        for msg in msgs:
            kind = msg.get_type()
            if kind == "BAD_DATA":
                framing = framing or self.bad_frame(link, msg)
                continue
            if kind.startswith("UNKNOWN_"):
                if framing is None:
                    framing = rejections.invalid(f"message id {kind[8:]} is not in the dialect",
                                                 rejections.Reason.UNKNOWN_MESSAGE)
                continue
            if msg.get_msgbuf()[0] == mav.mavlink.PROTOCOL_MARKER_V1 and kind != "HEARTBEAT":
                if framing is None:  # a MAVLink 1 HEARTBEAT is how a GCS finds us, then v2
                    framing = rejections.invalid(f"MAVLink 1 {kind}: this vehicle speaks MAVLink 2",
                                                 rejections.Reason.MAVLINK1)
                continue
            usable = self.handle(link, msg, arrival) or usable
        if framing is not None:
            self.reject(link, framing)
        return usable

"""What the supervisor and its stream process say to each other (one JSON object a datagram).

The two ends share a ``SOCK_SEQPACKET`` Unix socket pair: message
boundaries are kept, a link's UDP socket travels with its ``link`` message
(SCM_RIGHTS), and the child sees end-of-file the moment its parent dies.

Parent → child: ``link`` (a vehicle link: id, destinations, MAVLink ids,
signing key, rate), ``dests``, ``setpoint`` (sent at once, then streamed),
``heartbeat`` (its period), ``close``, ``lease`` (the parent is alive),
``stats``. Child → parent: ``hello`` (pid, the scheduling it got),
``sent`` (a setpoint left: its time on CLOCK_MONOTONIC, which both
processes read), ``stats``, ``log``.
"""

from __future__ import annotations

import json
import socket
from typing import Any

#: largest control message (bytes)
MAX_MESSAGE = 8192
#: the parent renews its lease this often (s) ...
LEASE_EVERY_S = 0.5
#: ... and the child stops streaming when it has heard nothing for this long (s): a parent
#: that stopped scheduling its threads looks dead to the vehicle, which then fails safe
LEASE_S = 3.0


def send(sock: socket.socket, msg: dict[str, Any], fds: list[int] | None = None) -> None:
    """One message (and ``fds``); raises OSError when the other end is gone."""
    data = json.dumps(msg, separators=(",", ":")).encode()
    if len(data) > MAX_MESSAGE:
        raise ValueError(f"control message of {len(data)} bytes")
    if fds:
        socket.send_fds(sock, [data], fds)
    else:
        sock.send(data)


def recv(sock: socket.socket) -> tuple[dict[str, Any] | None, list[int]]:
    """The next message and the fds that came with it; (None, []) at end of file."""
    data, fds, _flags, _addr = socket.recv_fds(sock, MAX_MESSAGE, 4)
    if not data:
        for fd in fds:
            socket.close(fd)
        return None, []
    msg = json.loads(data)
    if not isinstance(msg, dict) or not isinstance(msg.get("op"), str):
        raise ValueError(f"not a control message: {data[:80]!r}")
    return msg, list(fds)

"""When a datagram arrived: the kernel's receive timestamp (SO_TIMESTAMPNS), on the monotonic clock.

The vehicle judges its setpoint stream (the offboard-loss failsafe, the gaps
of services/uavsim/stream_stats.py) by when each setpoint reached its
socket, as an autopilot's interrupt-driven receive would, not by when this
simulator process was next scheduled to read it. The kernel stamps each
datagram on the wall clock; it is mapped onto ``time.monotonic()`` by the
offset between the two clocks read side by side (a step of the wall clock
while a datagram waits shifts that one stamp, no more).
"""

from __future__ import annotations

import contextlib
import socket
import struct
import time
from typing import Any

_SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)  # Linux's value where unnamed
_SCM_TIMESTAMPNS = _SO_TIMESTAMPNS
_TIMESPEC = struct.Struct("@qq")
_ANC = socket.CMSG_SPACE(_TIMESPEC.size)


def enable(sock: socket.socket) -> None:
    """Ask the kernel to stamp every datagram received on ``sock`` (without: read times)."""
    with contextlib.suppress(OSError):
        sock.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)


def recv(sock: socket.socket, size: int = 65536) -> tuple[bytes, Any, float]:
    """(data, address, arrival on the monotonic clock) of the next datagram; raises as recvfrom.

    Without a kernel stamp the arrival is now.
    """
    data, anc, _flags, addr = sock.recvmsg(size, _ANC)
    mono, wall = time.monotonic(), time.time()
    for level, kind, raw in anc:
        if level == socket.SOL_SOCKET and kind == _SCM_TIMESTAMPNS and len(raw) >= _TIMESPEC.size:
            sec, nsec = _TIMESPEC.unpack(raw[:_TIMESPEC.size])
            stamped = sec + nsec * 1e-9
            return data, addr, min(mono, mono - (wall - stamped))
    return data, addr, mono

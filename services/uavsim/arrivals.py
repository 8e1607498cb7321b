"""When a datagram arrived: the kernel's receive timestamp (SO_TIMESTAMPNS), on the monotonic clock.

The vehicle judges its setpoint stream (the offboard-loss failsafe, the gaps
of services/uavsim/stream_stats.py) by when each setpoint reached its
socket, as an autopilot's interrupt-driven receive would, not by when this
simulator process was next scheduled to read it. The kernel stamps each
datagram on the wall clock; it is mapped onto ``time.monotonic()`` by the
offset between the two clocks read side by side (a step of the wall clock
while a datagram waits shifts that one stamp, no more): :func:`arrival`.

Linux turns receive stamping on in deferred work (a static key flipped by a
work queue after the first ``setsockopt``), so the first datagrams on a newly
stamped socket may carry the time they were read instead; a vehicle's link
is unaffected beyond them (the arrival is then the read time, as without
stamping).
"""

from __future__ import annotations

import contextlib
import socket
import struct
import time
from collections.abc import Iterable
from typing import Any

_SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)  # Linux's value where unnamed
_SCM_TIMESTAMPNS = _SO_TIMESTAMPNS
_TIMESPEC = struct.Struct("@qq")
_ANC = socket.CMSG_SPACE(_TIMESPEC.size)

#: one ancillary item of ``recvmsg``: (level, type, data)
Ancillary = tuple[int, int, bytes]


def enable(sock: socket.socket) -> None:
    """Ask the kernel to stamp every datagram received on ``sock`` (without: read times)."""
    with contextlib.suppress(OSError):
        sock.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)


def kernel_stamp(ancillary: Iterable[Ancillary]) -> float | None:
    """The wall-clock receive stamp (s) in a datagram's ancillary data; None without one."""
    for level, kind, raw in ancillary:
        if level == socket.SOL_SOCKET and kind == _SCM_TIMESTAMPNS and len(raw) >= _TIMESPEC.size:
            sec, nsec = _TIMESPEC.unpack(raw[:_TIMESPEC.size])
            return sec + nsec * 1e-9
    return None


def timespec(stamp_s: float) -> bytes:
    """``stamp_s`` (wall s) as the kernel's SCM_TIMESTAMPNS payload (a struct timespec)."""
    sec = int(stamp_s)
    return _TIMESPEC.pack(sec, round((stamp_s - sec) * 1e9))


def stamp_item(stamp_s: float) -> Ancillary:
    """The ancillary item the kernel attaches for a datagram stamped at ``stamp_s`` (wall s)."""
    return socket.SOL_SOCKET, _SCM_TIMESTAMPNS, timespec(stamp_s)


def arrival(stamp_wall_s: float | None, mono_now_s: float, wall_now_s: float) -> float:
    """The arrival on the monotonic clock (s) of a datagram stamped at ``stamp_wall_s``,
    read when the clocks showed ``mono_now_s`` / ``wall_now_s``: the read time less the
    datagram's wait, never later than the read (a wall-clock step cannot put an arrival
    in the future); the read time without a stamp."""
    if stamp_wall_s is None:
        return mono_now_s
    return min(mono_now_s, mono_now_s - (wall_now_s - stamp_wall_s))


def recv(sock: socket.socket, size: int = 65536) -> tuple[bytes, Any, float]:
    """(data, address, arrival on the monotonic clock) of the next datagram; raises as recvfrom.

    Without a kernel stamp the arrival is now.
    """
    data, anc, _flags, addr = sock.recvmsg(size, _ANC)
    mono, wall = time.monotonic(), time.time()
    return data, addr, arrival(kernel_stamp(anc), mono, wall)

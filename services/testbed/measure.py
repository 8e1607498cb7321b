"""What a link does, measured with real packets between two hosts of a test bed.

Both ends of a flow are sockets of this process opened inside the hosts' namespaces
(:func:`services.testbed.netns.socket_in`), so a datagram's one-way delay is read on one
clock. :func:`ping` sends ICMP echo requests (the kernel of the other host answers),
:func:`udp_flow` a paced stream of sequenced datagrams, :func:`tcp_transfer` a bulk transfer.
"""

from __future__ import annotations

import contextlib
import os
import socket
import struct
import threading
import time
from dataclasses import dataclass, field

from services.testbed.bed import Host
from services.testbed.netns import socket_in

ICMP_ECHO, ICMP_REPLY = 8, 0
UDP_HEADER = struct.Struct("!Id")  # sequence, send time (s, this process's monotonic clock)


def _checksum(data: bytes) -> int:
    if len(data) % 2:
        data += b"\0"
    total = sum(struct.unpack(f"!{len(data) // 2}H", data))
    total = (total >> 16) + (total & 0xFFFF)
    total += total >> 16
    return ~total & 0xFFFF


def _echo(ident: int, seq: int, payload: bytes) -> bytes:
    head = struct.pack("!BBHHH", ICMP_ECHO, 0, 0, ident, seq)
    return struct.pack("!BBHHH", ICMP_ECHO, 0, _checksum(head + payload), ident, seq) + payload


def ping(src: Host, dst: Host, count: int, interval_s: float = 0.2, timeout_s: float = 2.0,
         size: int = 56) -> list[float | None]:
    """Round-trip times (ms) of ``count`` ICMP echoes from ``src`` to ``dst``; None: lost."""
    target = dst.address(src.name)
    ident = os.getpid() & 0xFFFF
    out: list[float | None] = []
    with socket_in(src.netns, socket.AF_INET, socket.SOCK_RAW, socket.IPPROTO_ICMP) as s:
        for seq in range(count):
            start = time.monotonic()
            s.sendto(_echo(ident, seq, b"\xa5" * size), (target, 0))
            out.append(_await_reply(s, ident, seq, start, timeout_s))
            time.sleep(max(0.0, start + interval_s - time.monotonic()))
    return out


def _await_reply(s: socket.socket, ident: int, seq: int, start: float,
                 timeout_s: float) -> float | None:
    while (left := start + timeout_s - time.monotonic()) > 0:
        s.settimeout(left)
        try:
            packet = s.recv(65535)
        except TimeoutError:
            return None
        ihl = (packet[0] & 0x0F) * 4
        kind, _, _, rid, rseq = struct.unpack("!BBHHH", packet[ihl:ihl + 8])
        if kind == ICMP_REPLY and rid == ident and rseq == seq:
            return (time.monotonic() - start) * 1000.0
    return None


@dataclass
class Flow:
    """A UDP flow: each datagram's send time and, if it came, its arrival time (s, this
    process's monotonic clock), by sequence number; arrivals with a lower sequence number
    than one before them; the newest arrival's time (0 before the first)."""

    sent_at: list[float] = field(default_factory=list)
    arrived_at: dict[int, float] = field(default_factory=dict)
    out_of_order: int = 0
    last_arrival: float = 0.0

    @property
    def sent(self) -> int:
        return len(self.sent_at)

    @property
    def received(self) -> int:
        return len(self.arrived_at)

    @property
    def delays_ms(self) -> dict[int, float]:
        """One-way delays of the datagrams that arrived, ms."""
        return {k: (t - self.sent_at[k]) * 1000.0 for k, t in self.arrived_at.items()}

    @property
    def loss(self) -> float:
        return 1.0 - self.received / self.sent if self.sent else 0.0


#: the receiving socket's buffer (bytes): a reader that falls behind on a loaded machine
#: finds its datagrams waiting (the kernel's default, ~208 kB, holds a few hundred)
RCVBUF_BYTES = 4 << 20
#: the longest wait for stragglers after the last datagram left (s), however busy the flow
DRAIN_CAP_S = 10.0


def udp_flow(src: Host, dst: Host, count: int, rate_pps: float, size: int = 200,
             drain_s: float = 3.0) -> Flow:
    """``count`` datagrams of ``size`` bytes from ``src`` to ``dst`` at ``rate_pps``; waits
    for stragglers until none has arrived for ``drain_s`` (at most :data:`DRAIN_CAP_S` after
    the last left), then reads what the socket still holds. A datagram counts as lost only
    when it never reached the receiving socket: not when a loaded machine's reader or
    impairer was slow."""
    flow = Flow()
    target = dst.address(src.name)
    with socket_in(dst.netns) as rx, socket_in(src.netns) as tx:
        rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RCVBUF_BYTES)
        rx.bind((target, 0))
        port = rx.getsockname()[1]
        done = threading.Event()
        reader = threading.Thread(target=_receive, args=(rx, flow, done), daemon=True)
        reader.start()
        start = time.monotonic()
        pad = b"\0" * max(0, size - UDP_HEADER.size)
        for seq in range(count):
            time.sleep(max(0.0, start + seq / rate_pps - time.monotonic()))
            now = time.monotonic()
            flow.sent_at.append(now)
            tx.sendto(UDP_HEADER.pack(seq, now) + pad, (target, port))
        _await_quiet(flow, time.monotonic(), drain_s)
        done.set()
        reader.join()
        rx.setblocking(False)
        _take_waiting(rx, flow)
    return flow


def _await_quiet(flow: Flow, last_sent: float, quiet_s: float) -> None:
    """Sleep until nothing has arrived for ``quiet_s`` since the later of the last send and
    the last arrival, or :data:`DRAIN_CAP_S` after the last send."""
    cap = last_sent + DRAIN_CAP_S
    while True:
        newest = max(last_sent, flow.last_arrival)
        wake = min(newest + quiet_s, cap)
        now = time.monotonic()
        if now >= wake:
            return
        time.sleep(wake - now)


def _take_waiting(rx: socket.socket, flow: Flow) -> None:
    """Record the datagrams the socket holds when the reader stopped (non-blocking)."""
    last = max(flow.arrived_at, default=-1)
    while True:
        try:
            data = rx.recv(65535)
        except BlockingIOError:
            return
        last = _arrived(flow, data, time.monotonic(), last)


def _arrived(flow: Flow, data: bytes, now: float, last: int) -> int:
    """Record one datagram; the highest sequence number seen so far, this one's included."""
    seq, _ = UDP_HEADER.unpack_from(data)
    flow.arrived_at[seq] = now
    flow.last_arrival = now
    if seq < last:
        flow.out_of_order += 1
    return max(last, seq)


def _receive(rx: socket.socket, flow: Flow, done: threading.Event) -> None:
    rx.settimeout(0.1)
    last = -1
    while not done.is_set():
        try:
            data = rx.recv(65535)
        except TimeoutError:
            continue
        last = _arrived(flow, data, time.monotonic(), last)


@dataclass(frozen=True)
class Transfer:
    """A TCP transfer: bytes received and the seconds from connect to the last byte;
    ``complete`` when every byte offered arrived (else the time limit ended it)."""

    nbytes: int
    seconds: float
    complete: bool = True

    @property
    def mbit_s(self) -> float:
        return self.nbytes * 8 / self.seconds / 1e6 if self.seconds > 0 else 0.0


def tcp_transfer(src: Host, dst: Host, nbytes: int, timeout_s: float = 120.0,
                 congestion: str = "", limit_s: float | None = None) -> Transfer:
    """Send ``nbytes`` over one TCP connection from ``src`` to ``dst``, for at most
    ``limit_s`` (then the connection is reset and what arrived by then counts).

    ``congestion``: the sender's congestion control (e.g. ``cubic``; default the host's).
    """
    target = dst.address(src.name)
    got = [0, 0.0]  # bytes, time of the last
    end_at = time.monotonic() + (limit_s if limit_s is not None else timeout_s)
    with socket_in(dst.netns, kind=socket.SOCK_STREAM) as server, \
            socket_in(src.netns, kind=socket.SOCK_STREAM) as client:
        server.bind((target, 0))
        server.listen(1)
        server.settimeout(timeout_s)
        reader = threading.Thread(target=_sink, args=(server, got, end_at, timeout_s),
                                  daemon=True)
        reader.start()
        client.settimeout(timeout_s)
        if congestion:
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_CONGESTION, congestion.encode())
        start = time.monotonic()
        client.connect((target, server.getsockname()[1]))
        chunk = b"\x5a" * (1 << 14)
        left = nbytes
        while left > 0 and time.monotonic() < end_at:
            try:
                left -= client.send(chunk[:min(left, len(chunk))])
            except (ConnectionResetError, BrokenPipeError):
                break  # the receiver stopped at the time limit
        if left == 0:
            with contextlib.suppress(OSError):
                client.shutdown(socket.SHUT_WR)
        else:  # out of time: reset, so nothing still queued is waited for
            with contextlib.suppress(OSError):
                client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            client.close()
        reader.join(timeout_s)
    return Transfer(int(got[0]), got[1] - start, complete=left == 0 and got[0] == nbytes)


def _sink(server: socket.socket, got: list[float], end_at: float, timeout_s: float) -> None:
    conn, _ = server.accept()
    with conn:
        conn.settimeout(timeout_s)
        while True:
            try:
                data = conn.recv(1 << 16)
            except OSError:  # reset at the time limit
                return
            now = time.monotonic()
            if not data or now > end_at:
                return
            got[0] += len(data)
            got[1] = now

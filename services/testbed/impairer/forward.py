"""The impairer's data path: frames between two interfaces through two :class:`Channel` s.

Each end is an ``AF_PACKET`` socket bound to one interface of the wire namespace (a veth whose
peer is a host's link interface). A frame read on end A goes through the channel of A's host
and is written, when due, on end B, where the kernel's queue of B (a ``tc tbf`` bandwidth, if
set) takes it to B's host; and back. Frames the socket itself wrote come back to it marked
``PACKET_OUTGOING`` and are skipped. One thread reads, schedules and writes; the control
thread changes the channels under the same lock.
"""

from __future__ import annotations

import errno
import logging
import selectors
import socket
import struct
import threading
import time
from collections.abc import Callable
from typing import Any

from services.testbed.impairer.channel import Channel, Outage
from services.testbed.impairer.control import Request

log = logging.getLogger(__name__)

ETH_P_ALL = 0x0003
SOL_PACKET = 263
PACKET_STATISTICS = 6
#: the largest frame read; one longer than ``FRAME_MTU`` means segmentation offload was left on
MAX_FRAME = 65535
FRAME_MTU = 1518
#: a bound on frames read from one socket per wake-up, so one direction cannot starve the other
BATCH = 64
#: the longest sleep when nothing is due, s (how often the stop flag is looked at)
IDLE_S = 0.2


def packet_socket(ifname: str, rcvbuf: int = 4 << 20) -> socket.socket:
    """A raw ``AF_PACKET`` socket on ``ifname`` reading every protocol, non-blocking."""
    s = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    s.bind((ifname, ETH_P_ALL))
    s.setblocking(False)
    return s


def kernel_drops(s: socket.socket) -> int:
    """Frames the kernel dropped because this socket's buffer was full, since the last call."""
    raw = s.getsockopt(SOL_PACKET, PACKET_STATISTICS, 8)
    return int(struct.unpack("II", raw)[1])


class Forwarder:
    """Two ends (host name → interface), a channel per sending host, a shared outage."""

    def __init__(self, ends: dict[str, str], seed: int,
                 clock: Callable[[], float] = time.monotonic):
        if len(ends) != 2:
            raise ValueError(f"a link has two ends, got {ends}")
        self.hosts = tuple(ends)
        self.clock = clock
        self.outage = Outage()
        self.lock = threading.Lock()
        self.channels = {h: Channel(f"{seed}:{h}", self.outage) for h in self.hosts}
        self.socks = {h: packet_socket(ifname) for h, ifname in ends.items()}
        self.drops = 0
        self.oversize = 0

    def peer(self, host: str) -> str:
        return self.hosts[1] if host == self.hosts[0] else self.hosts[0]

    # -- control ---------------------------------------------------------------------------
    def handle(self, req: Request) -> dict[str, Any]:
        """Apply one control request (already checked); the reply's fields."""
        with self.lock:
            now = self.clock()
            if req.cmd == "set":
                assert req.impairment is not None
                imp = req.impairment
                for h in (self.hosts if req.source is None else (req.source,)):
                    self.channels[h].configure(imp.delay_ms, imp.jitter_ms, imp.loss)
                log.info("set %s: delay %.1f ms, jitter %.1f ms, loss %.3f",
                         req.source or "both", imp.delay_ms, imp.jitter_ms, imp.loss)
            elif req.cmd == "outage":
                end = self.outage.begin(now, req.seconds if req.seconds else float("inf"))
                log.info("outage for %s s", req.seconds or "ever")
                return {"down_for_s": None if req.seconds is None else end - now}
            elif req.cmd == "up":
                self.outage.end(now)
                log.info("link up")
            elif req.cmd == "stats":
                return self.stats(now)
            return {}

    def stats(self, now: float) -> dict[str, Any]:
        for s in self.socks.values():
            self.drops += kernel_drops(s)
        until = self.outage.until(now)
        return {
            "directions": {h: {"delay_ms": c.delay_ms, "jitter_ms": c.jitter_ms, "loss": c.loss,
                               "queued": c.queued(), **c.counters.wire()}
                           for h, c in self.channels.items()},
            "down_for_s": None if until is None else (until - now if until < float("inf")
                                                      else "ever"),
            "kernel_drops": self.drops, "oversize": self.oversize,
        }

    # -- data path -------------------------------------------------------------------------
    def run(self, stop: threading.Event) -> None:
        sel = selectors.DefaultSelector()
        for host, s in self.socks.items():
            sel.register(s, selectors.EVENT_READ, host)
        try:
            while not stop.is_set():
                events = sel.select(self._timeout())
                with self.lock:
                    for key, _ in events:
                        self._read(key.data, key.fileobj)  # type: ignore[arg-type]
                    self._flush()
        finally:
            sel.close()
            for s in self.socks.values():
                s.close()

    def _timeout(self) -> float:
        with self.lock:
            dues = [d for c in self.channels.values() if (d := c.next_due()) is not None]
        return IDLE_S if not dues else min(IDLE_S, max(0.0, min(dues) - self.clock()))

    def _read(self, host: str, s: socket.socket) -> None:
        channel = self.channels[host]
        for _ in range(BATCH):
            try:
                frame, addr = s.recvfrom(MAX_FRAME)
            except BlockingIOError:
                return
            if addr[2] == socket.PACKET_OUTGOING:
                continue
            if len(frame) > FRAME_MTU:
                self.oversize += 1
                if self.oversize == 1:
                    log.warning("a %d-byte frame on %s: offloads on at its sender?",
                                len(frame), host)
            channel.offer(self.clock(), frame)

    def _flush(self) -> None:
        now = self.clock()
        for host, channel in self.channels.items():
            out = self.socks[self.peer(host)]
            for frame in channel.due(now):
                try:
                    out.send(frame)
                    channel.sent(frame, True)
                except OSError as err:  # ENOBUFS: the tbf queue is full; EAGAIN: so is ours
                    if err.errno not in (errno.ENOBUFS, errno.EAGAIN, errno.EMSGSIZE):
                        raise
                    channel.sent(frame, False)

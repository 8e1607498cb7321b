"""The stream process's loop: every vehicle link's setpoints and heartbeats, on time.

:class:`Streamer` takes the supervisor's control messages (services/supervisor/
stream/protocol.py) and keeps each :class:`Link` beating; :func:`raise_priority`
asks for real-time scheduling first. Standard library and
services/common/mavframe.py only: the process stays small.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import time
from dataclasses import dataclass, field
from typing import Any

from services.common.mavframe import Framer
from services.supervisor.stream import protocol

#: SCHED_RR priority asked for (1–99; PX4's and MAVSDK's I/O threads sit in the same low range)
RT_PRIORITY = 10
NICE = -10


@dataclass
class Link:
    """One vehicle link: its socket, where to send, what to send and when."""

    sock: socket.socket
    framer: Framer
    target: tuple[int, int]
    frame: int
    period_s: float
    dests: list[tuple[str, int]] = field(default_factory=list)
    setpoint: tuple[int, tuple[float, ...], int] | None = None  # due ms, ned, type mask
    hb: tuple[int, int, int] = (18, 8, 4)  # ONBOARD_CONTROLLER, AUTOPILOT_INVALID, ACTIVE
    hb_period_s: float = 0.2
    next_sp: float = 0.0
    next_hb: float = 0.0
    frames: int = 0       # setpoint frames sent
    send_errors: int = 0
    last_sp: float = 0.0
    max_gap_ms: float = 0.0
    over_150_ms: int = 0  # gaps between setpoint frames longer than 150 ms

    def send(self, data: bytes) -> None:
        for addr in self.dests:
            try:
                self.sock.sendto(data, addr)
            except OSError:  # an ICMP "port unreachable" from a vehicle not up yet
                self.send_errors += 1

    def send_setpoint(self, now: float) -> None:
        assert self.setpoint is not None
        due_ms, ned, mask = self.setpoint
        self.send(self.framer.set_position_target_local_ned(due_ms, *self.target, self.frame,
                                                            mask, ned))
        if self.last_sp:
            gap = (now - self.last_sp) * 1000.0
            self.max_gap_ms = max(self.max_gap_ms, gap)
            self.over_150_ms += gap > 150.0
        self.last_sp = now
        self.frames += 1
        self.next_sp = now + self.period_s

    def tick(self, now: float) -> None:
        if now >= self.next_hb:
            self.send(self.framer.heartbeat(*self.hb[:2], 0, 0, self.hb[2]))
            self.next_hb = now + self.hb_period_s
        if self.setpoint is not None and now >= self.next_sp:
            self.send_setpoint(now)

    def due(self) -> float:
        nxt = self.next_hb
        if self.setpoint is not None:
            nxt = min(nxt, self.next_sp)
        return nxt

    def stats(self) -> dict[str, Any]:
        return {"frames": self.frames, "max_gap_ms": round(self.max_gap_ms, 3),
                "over_150_ms": self.over_150_ms, "send_errors": self.send_errors}


def raise_priority() -> str:
    """SCHED_RR, else nice −10, else nothing; what it got."""
    try:
        os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(RT_PRIORITY))
        return f"SCHED_RR {RT_PRIORITY}"
    except (AttributeError, PermissionError, OSError):
        pass
    try:
        os.setpriority(os.PRIO_PROCESS, 0, NICE)
        return f"nice {NICE}"
    except (PermissionError, OSError):
        return "unchanged"


class Streamer:
    def __init__(self, ctl: socket.socket):
        self.ctl = ctl
        self.links: dict[int, Link] = {}
        self.lease_until = time.monotonic() + protocol.LEASE_S
        self.lapsed = False

    def say(self, msg: dict[str, Any]) -> None:
        with contextlib.suppress(OSError, ValueError):  # the parent is gone: the read ends us
            protocol.send(self.ctl, msg)

    def log(self, level: str, text: str, **kw: Any) -> None:
        self.say({"op": "log", "level": level, "msg": text, **kw})

    def handle(self, msg: dict[str, Any], fds: list[int], now: float) -> None:
        op, lid = msg["op"], int(msg.get("id", -1))
        if op == "link":
            sock = socket.socket(fileno=fds[0])
            key = bytes.fromhex(msg["key"]) if msg.get("key") else None
            framer = Framer(int(msg["sysid"]), int(msg["compid"]), key, int(msg["link_id"]))
            old = self.links.pop(lid, None)
            if old is not None:
                old.sock.close()
            self.links[lid] = Link(sock, framer, (int(msg["target"][0]), int(msg["target"][1])),
                                   int(msg["frame"]), 1.0 / float(msg["rate_hz"]),
                                   [(str(a), int(p)) for a, p in msg["dests"]])
            return
        for fd in fds:  # only a link message carries a socket
            os.close(fd)
        link = self.links.get(lid)
        if op == "lease":
            return
        if op == "stats":
            self.say({"op": "stats", "id": lid, "stats": link.stats() if link else {}})
        elif link is None:
            self.log("warning", "control message for an unknown link", op=op, id=lid)
        elif op == "dests":
            link.dests = [(str(a), int(p)) for a, p in msg["dests"]]
        elif op == "setpoint":
            link.setpoint = (int(msg["due_ms"]), tuple(float(v) for v in msg["ned"]),
                             int(msg["mask"]))
            if not self.lapsed:
                link.send_setpoint(now)
            if msg.get("ack"):
                self.say({"op": "sent", "id": lid, "seq": msg["seq"], "t": time.perf_counter(),
                          "frames": link.frames})
        elif op == "heartbeat":
            link.hb_period_s = float(msg["period_s"])
            link.hb = (int(msg.get("type", link.hb[0])), int(msg.get("autopilot", link.hb[1])),
                       int(msg.get("status", link.hb[2])))
            link.next_hb = min(link.next_hb, now + link.hb_period_s)
        elif op == "close":
            self.say({"op": "stats", "id": lid, "stats": link.stats(), "closed": True})
            link.sock.close()
            del self.links[lid]

    def run(self) -> int:
        self.say({"op": "hello", "pid": os.getpid(), "priority": raise_priority()})
        while True:
            now = time.monotonic()
            wake = min([link.due() for link in self.links.values()] + [self.lease_until])
            ready, _, _ = select.select([self.ctl], [], [], max(0.0, wake - now))
            now = time.monotonic()
            if ready:
                try:
                    msg, fds = protocol.recv(self.ctl)
                except (OSError, ValueError) as err:
                    self.log("error", "unreadable control message", error=str(err))
                    continue
                if msg is None:
                    return 0  # the supervisor is gone: so is its stream
                self.lease_until = now + protocol.LEASE_S
                if self.lapsed:
                    self.lapsed = False
                    self.log("info", "supervisor back: streaming again")
                try:
                    self.handle(msg, fds, now)
                except (KeyError, TypeError, ValueError, OSError) as err:
                    self.log("error", "bad control message", op=str(msg.get("op")),
                             error=str(err))
            if now > self.lease_until:
                if not self.lapsed:
                    self.lapsed = True
                    self.log("error", "supervisor silent: stream stopped",
                             silent_s=protocol.LEASE_S)
                self.lease_until = now + protocol.LEASE_S
                continue
            if not self.lapsed:
                for link in self.links.values():
                    link.tick(now)

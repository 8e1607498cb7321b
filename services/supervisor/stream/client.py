"""The supervisor's side of its stream process: start it, hand it links, feed it setpoints.

:func:`stream_process` gives the process's one :class:`StreamProcess`
(started on first use; a fleet's supervisor shares it between its vehicles).
:meth:`StreamProcess.add` hands it a vehicle link's UDP socket and returns a
:class:`StreamLink`, whose :meth:`~StreamLink.setpoint` makes a setpoint
current and returns when it has left the socket. A thread renews the lease
and reads the process's answers (its log lines are logged here); if the
process dies it is started again and given every link back, with its
current setpoint, and the restart is counted and logged.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from services.common.log import fields
from services.supervisor.stream import protocol

log = logging.getLogger(__name__)

REPO = Path(__file__).resolve().parents[3]
#: how long a caller waits for the stream process to confirm a setpoint left (s)
ACK_TIMEOUT_S = 0.5


@dataclass
class _LinkState:
    """What the parent remembers of a link, to give it back to a restarted process."""

    sock: socket.socket
    spec: dict[str, Any]
    setpoint: dict[str, Any] | None = None
    heartbeat: dict[str, Any] | None = None
    frames: int = 0       # setpoint frames sent by the current process ...
    frames_before: int = 0  # ... and by the ones before it
    stats: dict[str, Any] = field(default_factory=dict)


class StreamProcess:
    """The supervisor process's stream process (services/supervisor/stream/__main__.py)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.cond = threading.Condition(self.lock)
        self.links: dict[int, _LinkState] = {}
        self.acks: dict[tuple[int, int], float] = {}
        self.ids = itertools.count(1)
        self.seqs = itertools.count(1)
        self.restarts = 0
        self.priority = ""
        self.pid = 0
        self.closing = False
        self.ctl: socket.socket | None = None
        self.proc: subprocess.Popen[bytes] | None = None
        self._start()
        threading.Thread(target=self._lease, name="stream-lease", daemon=True).start()

    # -- the process --------------------------------------------------------------------------
    def _start(self) -> None:
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        env = dict(os.environ, PYTHONPATH=str(REPO))
        self.proc = subprocess.Popen(
            [sys.executable, "-S", "-m", "services.supervisor.stream", "--ctl",
             str(theirs.fileno())], pass_fds=[theirs.fileno()], env=env, cwd=str(REPO))
        theirs.close()
        self.ctl = ours
        threading.Thread(target=self._read, args=(ours,), name="stream-reader",
                         daemon=True).start()

    def _restart(self, why: str) -> None:
        with self.lock:
            if self.closing:
                return
            self.restarts += 1
            log.error("stream process ended: starting it again", extra=fields(
                why=why, restarts=self.restarts))
            old = self.proc
            self._start()
            links = list(self.links.items())
        if old is not None:
            old.wait()
        for lid, st in links:  # every link back, as it was
            st.frames_before, st.frames = st.frames_before + st.frames, 0
            self._send({"op": "link", "id": lid, **st.spec}, [st.sock.fileno()])
            for msg in (st.heartbeat, st.setpoint):
                if msg is not None:
                    self._send({**msg, "ack": False})

    def _send(self, msg: dict[str, Any], fds: list[int] | None = None) -> bool:
        ctl = self.ctl
        if ctl is None:
            return False
        try:
            protocol.send(ctl, msg, fds)
            return True
        except OSError:
            return False  # the reader sees the end and restarts the process

    def _read(self, ctl: socket.socket) -> None:
        while True:
            try:
                msg, _fds = protocol.recv(ctl)
            except (OSError, ValueError) as err:
                msg = None
                log.debug("stream control socket", extra=fields(error=str(err)))
            if msg is None:
                ctl.close()
                if ctl is self.ctl:
                    self._restart("end of its control socket")
                return
            self._on(msg)

    def _on(self, msg: dict[str, Any]) -> None:
        op = msg["op"]
        if op == "hello":
            self.pid, self.priority = int(msg["pid"]), str(msg["priority"])
            log.info("setpoint stream process started", extra=fields(
                pid=self.pid, scheduling=self.priority))
        elif op == "sent":
            with self.cond:
                self.acks[(int(msg["id"]), int(msg["seq"]))] = float(msg["t"])
                st = self.links.get(int(msg["id"]))
                if st is not None:
                    st.frames = int(msg["frames"])
                self.cond.notify_all()
        elif op == "stats":
            with self.cond:
                st = self.links.get(int(msg["id"]))
                if st is not None:
                    st.stats = dict(msg["stats"])
                    st.frames = int(st.stats.get("frames", st.frames))
                self.cond.notify_all()
        elif op == "log":
            level = {"error": logging.ERROR, "warning": logging.WARNING}.get(
                str(msg.pop("level", "")), logging.INFO)
            text = str(msg.pop("msg", ""))
            msg.pop("op", None)
            log.log(level, f"stream process: {text}", extra=fields(**msg))

    def _lease(self) -> None:
        while not self.closing:
            self._send({"op": "lease"})
            time.sleep(protocol.LEASE_EVERY_S)

    # -- links --------------------------------------------------------------------------------
    def add(self, sock: socket.socket, dests: list[tuple[str, int]], sysid: int, compid: int,
            target: tuple[int, int], frame: int, rate_hz: float, key: bytes | None = None,
            link_id: int = 1) -> StreamLink:
        """Stream on ``sock`` (a UDP socket the caller keeps) to ``dests``; framed as system
        ``sysid`` component ``compid``, signed with ``key`` on ``link_id`` if given."""
        lid = next(self.ids)
        spec = {"dests": [list(d) for d in dests], "sysid": sysid, "compid": compid,
                "target": list(target), "frame": frame, "rate_hz": rate_hz,
                "key": key.hex() if key else "", "link_id": link_id}
        with self.lock:
            self.links[lid] = _LinkState(sock, spec)
        self._send({"op": "link", "id": lid, **spec}, [sock.fileno()])
        return StreamLink(self, lid)

    def close(self) -> None:
        """Stop the process (its links go with it)."""
        self.closing = True
        if self.ctl is not None:
            with contextlib.suppress(OSError):  # wakes the reader blocked on it; the child
                self.ctl.shutdown(socket.SHUT_RDWR)  # sees end of file at once
            self.ctl.close()
        if self.proc is not None:
            try:
                self.proc.wait(2.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


class StreamLink:
    """One vehicle link in the stream process."""

    def __init__(self, owner: StreamProcess, lid: int):
        self.owner = owner
        self.id = lid

    def setpoint(self, due_ms: int, ned: tuple[float, ...], mask: int, wait: bool = True) -> float:
        """Make this the link's setpoint and send it now; with ``wait``, return the
        ``time.perf_counter()`` at which it left (the caller's own clock if no answer came)."""
        o = self.owner
        seq = next(o.seqs)
        msg = {"op": "setpoint", "id": self.id, "seq": seq, "due_ms": int(due_ms),
               "ned": [float(v) for v in ned], "mask": int(mask), "ack": wait}
        with o.lock:
            st = o.links[self.id]
            st.setpoint = msg
        o._send(msg)
        if not wait:
            return time.perf_counter()
        deadline = time.monotonic() + ACK_TIMEOUT_S
        with o.cond:
            while (self.id, seq) not in o.acks:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    log.warning("stream process did not confirm a setpoint", extra=fields(
                        due_ms=due_ms, waited_s=ACK_TIMEOUT_S))
                    return time.perf_counter()
                o.cond.wait(remaining)
            return o.acks.pop((self.id, seq))

    def dests(self, dests: list[tuple[str, int]]) -> None:
        with self.owner.lock:
            self.owner.links[self.id].spec["dests"] = [list(d) for d in dests]
        self.owner._send({"op": "dests", "id": self.id, "dests": [list(d) for d in dests]})

    def heartbeat(self, period_s: float, mav_type: int, autopilot: int, status: int) -> None:
        msg = {"op": "heartbeat", "id": self.id, "period_s": period_s, "type": mav_type,
               "autopilot": autopilot, "status": status}
        with self.owner.lock:
            self.owner.links[self.id].heartbeat = msg
        self.owner._send(msg)

    @property
    def frames(self) -> int:
        """Setpoint frames sent so far (as of the process's last answer)."""
        st = self.owner.links[self.id]
        return st.frames_before + st.frames

    def stats(self, timeout_s: float = 1.0) -> dict[str, Any]:
        """The process's count of this link's frames and the longest gap it kept between them."""
        o = self.owner
        with o.cond:
            st = o.links[self.id]
            st.stats = {}
        o._send({"op": "stats", "id": self.id})
        deadline = time.monotonic() + timeout_s
        with o.cond:
            while not st.stats and time.monotonic() < deadline:
                o.cond.wait(0.05)
            return dict(st.stats)

    def close(self) -> dict[str, Any]:
        """Stop streaming this link; its final statistics."""
        stats = self.stats()
        self.owner._send({"op": "close", "id": self.id})
        with self.owner.lock:
            self.owner.links.pop(self.id, None)
        return stats


_PROCESS: StreamProcess | None = None
_PROCESS_LOCK = threading.Lock()


def stream_process() -> StreamProcess:
    """This process's stream process, started on first use."""
    global _PROCESS
    with _PROCESS_LOCK:
        if _PROCESS is None:
            _PROCESS = StreamProcess()
        return _PROCESS


def close_stream_process() -> None:
    """Stop this process's stream process, if it was started, and wait for it to end (so no
    exited child is left for init to collect)."""
    global _PROCESS
    with _PROCESS_LOCK:
        if _PROCESS is not None:
            _PROCESS.close()
            _PROCESS = None

"""The impairer's control socket: one JSON object a line each way, over a Unix stream socket.

=============================================================  ==========================
request                                                        effect
=============================================================  ==========================
``{"cmd": "ping"}``                                            nothing (ready check)
``{"cmd": "set", "source": "air", "delay_ms": 150,             the direction leaving host
"jitter_ms": 20, "loss": 0.05}``                               ``source`` (null: both)
``{"cmd": "outage", "seconds": 10}``                           the link down for 10 s
``{"cmd": "outage", "seconds": null}``                         down until ``up``
``{"cmd": "up"}``                                              the link up again now
``{"cmd": "stats"}``                                           counters and settings
=============================================================  ==========================

Every reply has ``"ok"``; a request that does not parse or is out of range is answered
``{"ok": false, "error": "..."}`` and changes nothing. A Unix socket is a file, so a test in
the root namespace reaches the impairer inside the test bed's wire namespace.
"""

from __future__ import annotations

import json
import logging
import math
import os
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from services.testbed.impairment import Impairment

log = logging.getLogger(__name__)

MAX_LINE = 65536
COMMANDS = ("ping", "set", "outage", "up", "stats")


class ImpairerError(RuntimeError):
    """The impairer refused a request or could not be reached."""


@dataclass(frozen=True)
class Request:
    cmd: str
    source: str | None = None             # set: the sending host (None: both directions)
    impairment: Impairment | None = None  # set: delay, jitter, loss
    seconds: float | None = None          # outage: its length (None: until "up")


def parse(line: bytes | str, sources: tuple[str, ...]) -> Request:
    """A checked request (ValueError saying what is wrong)."""
    try:
        doc = json.loads(line)
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ValueError(f"not JSON: {err}") from None
    if not isinstance(doc, dict):
        raise ValueError(f"a request is a JSON object, got {type(doc).__name__}")
    cmd = doc.pop("cmd", None)
    if cmd not in COMMANDS:
        raise ValueError(f"cmd must be one of {list(COMMANDS)}, got {cmd!r}")
    if cmd == "set":
        source = doc.pop("source", None)
        if source is not None and source not in sources:
            raise ValueError(f"source must be one of {list(sources)} or null, got {source!r}")
        extra = sorted(set(doc) - {"delay_ms", "jitter_ms", "loss"})
        if extra:
            raise ValueError(f"set takes delay_ms, jitter_ms, loss; not {extra}")
        return Request(cmd, source=source, impairment=Impairment(**doc))
    if cmd == "outage":
        seconds = doc.pop("seconds", None)
        if seconds is not None and (isinstance(seconds, bool)
                                    or not isinstance(seconds, (int, float))
                                    or not (math.isfinite(seconds) and seconds > 0)):
            raise ValueError(f"seconds must be a finite number > 0 or null, got {seconds!r}")
        if doc:
            raise ValueError(f"outage takes seconds only; not {sorted(doc)}")
        return Request(cmd, seconds=None if seconds is None else float(seconds))
    if doc:
        raise ValueError(f"{cmd} takes no fields; not {sorted(doc)}")
    return Request(cmd)


Handler = Callable[[Request], dict[str, Any]]


class ControlServer:
    """Answers requests on ``path`` in a thread of its own; ``handle`` applies one request."""

    def __init__(self, path: str, sources: tuple[str, ...], handle: Handler):
        self.path, self.sources, self.handle = path, sources, handle
        if os.path.exists(path):
            os.unlink(path)
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._sock.bind(path)
        self._sock.listen(8)
        self._thread = threading.Thread(target=self._serve, name="control", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        self._sock.close()
        if os.path.exists(self.path):
            os.unlink(self.path)

    def answer(self, line: bytes) -> dict[str, Any]:
        try:
            request = parse(line, self.sources)
        except ValueError as err:
            log.warning("control request refused: %s", err)
            return {"ok": False, "error": str(err)}
        return {"ok": True, **self.handle(request)}

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self._sock.accept()
            except OSError:
                return  # closed
            threading.Thread(target=self._client, args=(conn,), daemon=True).start()

    def _client(self, conn: socket.socket) -> None:
        with conn, conn.makefile("rwb") as f:
            while True:
                line = f.readline(MAX_LINE + 1)
                if not line:
                    return
                reply = (self.answer(line) if len(line) <= MAX_LINE
                         else {"ok": False, "error": f"request longer than {MAX_LINE} bytes"})
                f.write(json.dumps(reply).encode() + b"\n")
                f.flush()


class ControlClient:
    """Sends requests to an impairer's control socket (a connection per request)."""

    def __init__(self, path: str, timeout_s: float = 5.0):
        self.path, self.timeout_s = path, timeout_s

    def call(self, **request: Any) -> dict[str, Any]:
        """Send ``request``; returns the reply (ImpairerError if refused or unreachable)."""
        try:
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
                s.settimeout(self.timeout_s)
                s.connect(self.path)
                s.sendall(json.dumps(request).encode() + b"\n")
                with s.makefile("rb") as f:
                    line = f.readline(MAX_LINE + 1)
        except OSError as err:
            raise ImpairerError(f"impairer at {self.path}: {err}") from err
        try:
            reply = json.loads(line)
        except json.JSONDecodeError:
            raise ImpairerError(f"impairer at {self.path}: no reply ({line[:80]!r})") from None
        if not isinstance(reply, dict) or reply.get("ok") is not True:
            raise ImpairerError(f"impairer at {self.path} refused {request}: "
                                f"{reply.get('error') if isinstance(reply, dict) else reply}")
        return reply

"""What this process sent and received over Zenoh: payload bytes per key expression.

Every put, query, reply and received sample, query or reply that goes through
``services.common.bus`` is counted in :data:`TRAFFIC`: messages and payload bytes
per (key pattern, kind, direction). The key pattern is the key with the vehicle
id and a planner replica's session id replaced by ``*`` (``dualpilot/*/plan/system2/*``),
so a fleet's vehicles and a pool's replicas add up under one row. Liveliness tokens and
Zenoh's own framing are not payload and are not counted here; a link's interface counters
have them (services/testbed/linkbytes.py puts both side by side).

A service writes its table at exit to ``TRAFFIC_PATH`` when that is set (``{service}`` and
``{pid}`` in it are filled in; services/common/bus/service.py), and serves it in its
status (``traffic``).
"""

from __future__ import annotations

import json
import os
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from services.common import keys

#: the kinds of message counted
KINDS = ("put", "query", "reply")
SENT, RECEIVED = "sent", "received"
#: at most this many rows are kept; the rest count under :data:`OTHER`
MAX_ROWS = 512
OTHER = "(other)"


def pattern(key: str) -> str:
    """``key`` with its vehicle id and a replica's session id as ``*``: the row it counts
    under (``dualpilot/uav1/plan/system2/0a1b…`` → ``dualpilot/*/plan/system2/*``)."""
    parts = str(key).split("/")
    if len(parts) < 3 or parts[0] != keys.ROOT:
        return str(key)[:200]
    parts[1] = "*"
    if len(parts) == 5 and parts[2] == "plan":
        parts[4] = "*"
    return "/".join(parts)


@dataclass
class Row:
    messages: int = 0
    bytes: int = 0


class Traffic:
    """Messages and payload bytes per (key pattern, kind, direction); thread-safe."""

    def __init__(self, max_rows: int = MAX_ROWS):
        self.max_rows = max_rows
        self._lock = threading.Lock()
        self._rows: dict[tuple[str, str, str], Row] = {}

    def count(self, key: str, kind: str, direction: str, nbytes: int) -> None:
        """One message of ``nbytes`` payload bytes on ``key``."""
        if kind not in KINDS or direction not in (SENT, RECEIVED):
            raise ValueError(f"kind {kind!r} / direction {direction!r} not counted")
        name = pattern(key)
        with self._lock:
            row = self._rows.get((name, kind, direction))
            if row is None:
                if len(self._rows) >= self.max_rows:
                    name = OTHER
                row = self._rows.setdefault((name, kind, direction), Row())
            row.messages += 1
            row.bytes += int(nbytes)

    def sent(self, key: str, kind: str, nbytes: int) -> None:
        self.count(key, kind, SENT, nbytes)

    def received(self, key: str, kind: str, nbytes: int) -> None:
        self.count(key, kind, RECEIVED, nbytes)

    def snapshot(self) -> list[dict[str, Any]]:
        """Every row: ``{"key", "kind", "direction", "messages", "bytes"}``, sorted."""
        with self._lock:
            rows = [{"key": k, "kind": kind, "direction": d, "messages": r.messages,
                     "bytes": r.bytes} for (k, kind, d), r in self._rows.items()]
        return sorted(rows, key=lambda r: (r["key"], r["kind"], r["direction"]))

    def reset(self) -> None:
        with self._lock:
            self._rows.clear()


#: this process's traffic
TRAFFIC = Traffic()


def path_for(template: str, service: str, pid: int | None = None) -> Path:
    """``TRAFFIC_PATH``'s file for ``service`` (``{service}``, ``{pid}`` filled in)."""
    return Path(template.replace("{service}", service).replace(
        "{pid}", str(os.getpid() if pid is None else pid)))


def write(path: Path, service: str, host: str = "", table: Traffic = TRAFFIC) -> None:
    """Write ``table`` as JSON: ``{"service", "pid", "host", "rows"}`` (atomically)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps({"service": service, "pid": os.getpid(), "host": host,
                               "rows": table.snapshot()}, indent=1) + "\n")
    tmp.replace(path)


def write_from_env(service: str) -> Path | None:
    """At a service's exit: its table to ``TRAFFIC_PATH`` (with ``PLACEMENT`` as its host),
    if set; the path written (None: not asked, or not writable)."""
    template = os.environ.get("TRAFFIC_PATH", "")
    if not template:
        return None
    path = path_for(template, service)
    try:
        write(path, service, os.environ.get("PLACEMENT", ""))
    except OSError:
        return None
    return path

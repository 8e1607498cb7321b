"""Every service's status queryable ``<ns>/status/<service>``: who it is, what it rejected and
the missions it runs (services/common/effective.py)."""

from __future__ import annotations

import json
import logging
import os
import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh

from services.common import keys, rejections, wire
from services.common.bus.inbox import Inbox
from services.common.bus.query import Trusted, first_reply
from services.common.cli import Settings
from services.common.effective import EFFECTIVE
from services.common.traffic import TRAFFIC

log = logging.getLogger("services.common.bus")

STATUS_ENCODING = "application/json"


def status(settings: Settings, started: float) -> dict[str, Any]:
    """The service's status: who it is, what it rejected (per key and reason) and each
    mission's effective configuration (mission id → uav, config, what it made of it)."""
    rejected = rejections.REJECTED.snapshot()
    return {
        "service": settings.service, "uav": settings.uav_id, "pid": os.getpid(),
        "uptime_s": round(time.monotonic() - started, 3),
        "schema_version": wire.SCHEMA_VERSION,
        "rejected_total": sum(sum(c.values()) for c in rejected.values()),
        "rejected": rejected,
        "reasons": [r.value for r in rejections.Reason],
        "log_lines_suppressed": rejections.REJECTED.suppressed_total,
        "missions": EFFECTIVE.snapshot(),
        "traffic": TRAFFIC.snapshot(),
    }


def serve_status(session: zenoh.Session, settings: Settings, stop: threading.Event,
                 started: float) -> Callable[[], None]:
    """Answer ``keys.status(uav, service)`` from a thread of its own; returns the closer.

    The query's payload is ignored (whatever it is). The callback only
    enqueues; the thread replies.
    """
    key = keys.status(settings.uav_id, settings.service)
    inbox = Inbox(key, max_items=64, max_bytes=1024 * 1024)
    queryable = session.declare_queryable(key, inbox.on_query)
    done = threading.Event()

    def loop() -> None:
        while not (stop.is_set() or done.is_set()):
            item = inbox.get(timeout=0.2)
            if item is None or item.query is None:
                continue
            try:
                body = json.dumps(status(settings, started)).encode()
                item.query.reply(key, body, encoding=zenoh.Encoding(STATUS_ENCODING))
                TRAFFIC.sent(key, "reply", len(body))
            except Exception:  # a status reply must never take the service down
                log.exception("status reply failed")
            finally:
                item.query.drop()

    thread = threading.Thread(target=loop, name=f"{settings.service}-status", daemon=True)
    thread.start()

    def close() -> None:
        done.set()
        thread.join(1.0)
        queryable.undeclare()

    return close


def query_status(session: zenoh.Session, uav: str, service: str,
                 timeout_s: float = 5.0, trusted: Trusted = None,
                 stop: threading.Event | None = None) -> dict[str, Any]:
    """Ask a service for its status (raises TimeoutError if it (``trusted``) does not answer)."""
    reply = first_reply(session, keys.status(uav, service), timeout_s, stop, trusted)
    if reply.ok is None:
        raise TimeoutError(f"no status from {service} within {timeout_s:.3g} s")
    doc: dict[str, Any] = json.loads(reply.ok.payload.to_bytes())
    return doc
